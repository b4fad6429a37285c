"""What the soccer pipeline achieves, measured against the simulator's ground truth.

Tracking error is the angle between the camera's optical axis and the true direction to the
ball at each camera frame: what "the head keeps the ball centred" means, independent of what
the pipeline believes. Latency runs from an image's capture stamp to the joint command it
caused. Rates count what each stage produced. Frames taken while the fall detector says the
robot is down (``fall/state``) are counted but not scored: a head on the ground tracks
nothing; neither are frames in which the ball lies outside the image (the head is looking
for it, or it was just put back behind the robot): that is searching, not tracking, and
is counted on its own (``frames_out_of_view``). What the robot did as a player is
counted over the run: kicks and get-ups (the motion arbiter's ``motion/state`` entering
``kick``, and leaving ``getup`` for a standing motion), the time to the first kick, and
the distance walked (ground truth: the torso's path on the ground, sampled once a gait
cycle, :data:`PATH_SAMPLE_S`, so the sway from foot to foot does not count, and only
while standing). :meth:`SoccerMonitor.window` returns the figures since its last call
(live statistics); :meth:`SoccerMonitor.totals` those of the run.
"""

from __future__ import annotations

import math
import statistics
from collections import deque
from dataclasses import dataclass, field

import numpy as np
from geometry_msgs.msg import PointStamped, PoseStamped
from sensor_msgs.msg import CameraInfo, Image, JointState
from std_msgs.msg import String

from efficient_comm import from_msg
from efficient_comm.handle import NodeHandle

from .fall import LATCHED, STANDING
from .vision import FALLBACK_FOVY_DEG

#: The walked path is sampled this often (s): one cycle of the walk engine's gait.
PATH_SAMPLE_S = 0.5
#: Moves shorter than this (m) are the body swaying on the spot, not walking.
PATH_MIN_STEP_M = 0.02
#: ``motion/state`` values in which the robot is on its feet.
STANDING_MOTIONS = ("stand", "walk", "kick")


def _rotation(pose: PoseStamped) -> np.ndarray:
    q = pose.pose.orientation
    w, x, y, z = q.w, q.x, q.y, q.z
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])


def ball_in_camera(camera: PoseStamped, ball: PoseStamped) -> tuple[float, float, float]:
    """(yaw, pitch, off-axis angle) of the ball seen from the camera, in radians.

    Yaw is positive to the left of the image centre, pitch positive below it, like the
    detector's output; the camera frame is MuJoCo's (x right, y up, looking along -z).
    """
    c, b = camera.pose.position, ball.pose.position
    d = _rotation(camera).T @ np.array([b.x - c.x, b.y - c.y, b.z - c.z])
    forward = -d[2]
    off_axis = math.acos(max(-1.0, min(1.0, forward / float(np.linalg.norm(d)))))
    return math.atan2(-d[0], forward), math.atan2(-d[1], forward), off_axis


@dataclass
class Figures:
    """What one stretch of the run achieved."""

    seconds: float = 0.0
    frames: int = 0
    frames_down: int = 0  # taken while the robot was falling or fallen: not scored
    frames_out_of_view: int = 0  # the ball outside the image: searching, not scored
    detections: int = 0
    joint_states: int = 0
    commands: int = 0
    tracking_error_deg: list[float] = field(default_factory=list)
    detection_error_deg: list[float] = field(default_factory=list)
    latency_ms: list[float] = field(default_factory=list)

    def rate(self, count: int) -> float:
        return count / self.seconds if self.seconds > 0 else 0.0

    @staticmethod
    def percentile(values: list[float], q: float) -> float:
        if not values:
            return math.nan
        ordered = sorted(values)
        return ordered[min(len(ordered) - 1, round(q * (len(ordered) - 1)))]

    def summary(self) -> dict[str, float]:
        return {
            "camera_fps": self.rate(self.frames),
            "detection_rate_hz": self.rate(self.detections),
            "joint_state_rate_hz": self.rate(self.joint_states),
            "tracking_error_mean_deg": (statistics.fmean(self.tracking_error_deg)
                                        if self.tracking_error_deg else math.nan),
            "tracking_error_p95_deg": self.percentile(self.tracking_error_deg, 0.95),
            "tracking_error_max_deg": max(self.tracking_error_deg, default=math.nan),
            "detection_error_p95_deg": self.percentile(self.detection_error_deg, 0.95),
            "latency_median_ms": self.percentile(self.latency_ms, 0.5),
            "latency_p99_ms": self.percentile(self.latency_ms, 0.99),
        }


class SoccerMonitor:
    def __init__(self, node: NodeHandle) -> None:
        self.node = node
        self.camera: PoseStamped | None = None
        self.ball: PoseStamped | None = None
        self.posture = STANDING
        # Commands caused by an image reach us before the image itself when composed
        # depth-first (the detector subscribed first), so either side may come first.
        self._image_stamps: deque[int] = deque(maxlen=64)
        self._command_times: dict[int, int] = {}
        self._window = Figures()
        self._total = Figures()
        #: When the monitor started (the clock's ns): times in the report count from here.
        self.started_ns = node.clock.now_ns()
        self._window_start = self._total_start = self.started_ns
        self.motion = ""
        self.kicks = 0
        self.getups = 0
        self._getting_up = False
        #: Simulated time (ns since the monitor started) of the first kick.
        self.first_kick_ns: int | None = None
        self.walked_m = 0.0
        self._path_point: tuple[float, float] | None = None
        self._path_next_ns = 0
        node.create_subscription(PoseStamped, "ground_truth/camera", self._on_camera, qos=10)
        node.create_subscription(PoseStamped, "ground_truth/ball", self._on_ball, qos=10)
        node.create_subscription(Image, "camera/image_raw", self._on_image, qos=10)
        #: Half the image's width and height over the focal length (tangents of the half
        #: fields of view), from ``camera_info``; until then the head camera's.
        fovy = math.radians(FALLBACK_FOVY_DEG)
        self._half_view = (math.tan(fovy / 2) * 4 / 3, math.tan(fovy / 2))
        node.create_subscription(CameraInfo, "camera/camera_info", self._on_info,
                                 qos=LATCHED)
        node.create_subscription(PointStamped, "ball/detection", self._on_detection, qos=10)
        node.create_subscription(JointState, "joint_states", self._on_state, qos=10)
        node.create_subscription(JointState, "joint_commands", self._on_command, qos=10)
        node.create_subscription(String, "fall/state", self._on_posture, qos=LATCHED)
        node.create_subscription(String, "motion/state", self._on_motion, qos=LATCHED)
        node.create_subscription(PoseStamped, "ground_truth/robot", self._on_robot, qos=10)

    def _on_motion(self, state: String) -> None:
        previous, self.motion = self.motion, state.data
        if state.data == "kick" and previous != "kick":
            self.kicks += 1
            if self.first_kick_ns is None:
                self.first_kick_ns = self.node.clock.now_ns() - self._total_start
        # A get-up ends in a standing motion, directly or through ``fallen`` (the motion
        # over, the fall detector not yet sure the robot stands): count it once either way.
        if state.data == "getup":
            self._getting_up = True
        elif self._getting_up and state.data in STANDING_MOTIONS:
            self._getting_up = False
            self.getups += 1

    def _on_robot(self, pose: PoseStamped) -> None:
        now = self.node.clock.now_ns()
        if now < self._path_next_ns:
            return
        self._path_next_ns = now + round(PATH_SAMPLE_S * 1e9)
        point = (pose.pose.position.x, pose.pose.position.y)
        if self.posture != STANDING:
            self._path_point = None  # a fall and a get-up are not walking
            return
        if self._path_point is None:
            self._path_point = point
        elif (step := math.dist(point, self._path_point)) >= PATH_MIN_STEP_M:
            self.walked_m += step  # smaller steps add up until they are one: no jitter
            self._path_point = point

    def _both(self) -> tuple[Figures, Figures]:
        return self._window, self._total

    def _on_posture(self, posture: String) -> None:
        self.posture = posture.data

    def _truth(self) -> tuple[PoseStamped, PoseStamped] | None:
        """Camera and ball poses to score against; none while the robot is down."""
        if self.posture != STANDING or self.camera is None or self.ball is None:
            return None
        return self.camera, self.ball

    def _on_camera(self, pose: PoseStamped) -> None:
        self.camera = pose

    def _on_ball(self, pose: PoseStamped) -> None:
        self.ball = pose

    def _on_info(self, info: CameraInfo) -> None:
        fx, fy = info.k[0], info.k[4]
        if fx > 0 and fy > 0 and info.width and info.height:
            self._half_view = (info.width / 2 / fx, info.height / 2 / fy)

    def _in_view(self, yaw: float, pitch: float, off_axis: float) -> bool:
        return (off_axis < math.pi / 2 and abs(math.tan(yaw)) <= self._half_view[0]
                and abs(math.tan(pitch)) <= self._half_view[1])

    def _on_image(self, image: Image) -> None:
        stamp = from_msg(image.header.stamp)
        self._image_stamps.append(stamp)
        if (sent := self._command_times.pop(stamp, None)) is not None:
            self._latency((sent - stamp) / 1e6)
        error = None
        out_of_view = False
        if (truth := self._truth()) is not None:
            seen = ball_in_camera(*truth)
            out_of_view = not self._in_view(*seen)
            error = None if out_of_view else math.degrees(seen[2])
        for figures in self._both():
            figures.frames += 1
            figures.frames_down += self.posture != STANDING
            figures.frames_out_of_view += out_of_view
            if error is not None:
                figures.tracking_error_deg.append(error)

    def _on_detection(self, detection: PointStamped) -> None:
        error = None
        if (truth := self._truth()) is not None:
            yaw, pitch, _ = ball_in_camera(*truth)
            error = math.degrees(math.hypot(detection.point.x - yaw, detection.point.y - pitch))
        for figures in self._both():
            figures.detections += 1
            if error is not None:
                figures.detection_error_deg.append(error)

    def _on_state(self, _: JointState) -> None:
        for figures in self._both():
            figures.joint_states += 1

    def _on_command(self, command: JointState) -> None:
        stamp, now = from_msg(command.header.stamp), self.node.clock.now_ns()
        if stamp in self._image_stamps:
            self._latency((now - stamp) / 1e6)
        else:
            self._command_times.setdefault(stamp, now)
            while len(self._command_times) > 64:  # stance commands never meet an image
                del self._command_times[next(iter(self._command_times))]
        for figures in self._both():
            figures.commands += 1

    def _latency(self, milliseconds: float) -> None:
        for figures in self._both():
            figures.latency_ms.append(milliseconds)

    def window(self) -> Figures:
        """The figures since the previous call, and start a new window."""
        now = self.node.clock.now_ns()
        window, self._window = self._window, Figures()
        window.seconds = (now - self._window_start) / 1e9
        self._window_start = now
        return window

    def totals(self) -> Figures:
        self._total.seconds = (self.node.clock.now_ns() - self._total_start) / 1e9
        return self._total
