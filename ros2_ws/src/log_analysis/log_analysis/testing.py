"""Test doubles: a team log written from plain messages (for testing event generators,
ours and users'); a filmed ball: a log of a ball's track with a video of it on a camera
clock of known offset and drift (for testing what puts a video on a log's time); and a
seen ball: a robot's camera images of a ball at known bearings with the ground truth (for
comparing detectors); and a robot's own bag on its own clock, with its clock estimates (for
reading several robots' bags on the team's time).

    with LogBuilder(tmp_path / "log") as log:
        log.add("blue1", "fall/state", String(data="fallen"), t=3.0)
        log.add("world", "game_state", state, t=3.5)
    found = detect(TeamLog(tmp_path / "log"), [Falls()])

Topics land as a match's merged log has them (``/blue1/fall/state``); times are seconds
from ``epoch_s``. The log is a real rosbag2 bag (rosbag2_layout writes it), so a
generator tested on it reads a recorded match the same way.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict
from fractions import Fraction
from pathlib import Path
from types import TracebackType
from typing import Any

import av
import cv2
import numpy as np
from geometry_msgs.msg import PointStamped, PoseStamped, PoseWithCovarianceStamped
from rclpy.serialization import serialize_message
from sensor_msgs.msg import CompressedImage, JointState
from std_msgs.msg import String

from rosbag2_layout import BagWriter, type_name
from team_clock_interfaces.msg import ClockOffset

from .video import SIDECAR_FORMAT, Calibration, video_sidecar_path

__all__ = ["OVERHEAD", "LogBuilder", "RobotBag", "film_ball", "seen_ball"]

#: A camera above a KidSize field's long side, as humanoid_sim's match films (480 x 270).
OVERHEAD = Calibration(width=480, height=270, fx=325.9, fy=325.9, cx=240.0, cy=135.0,
                       position=(0.0, -4.0685, 8.725), forward=(0.0, 0.4226, -0.9063),
                       up=(0.0, 0.9063, 0.4226))
_TURF, _BALL, _RED = (70, 228, 70), (232, 150, 45), (200, 30, 30)


class LogBuilder:
    """Writes a merged-log-shaped bag at ``path``; messages may come in any order (the
    reader orders them by time). A context manager (closes on exit)."""

    def __init__(self, path: str | os.PathLike[str], *, epoch_s: float = 1000.0) -> None:
        self._epoch_ns = int(epoch_s * 1e9)
        self._writer = BagWriter(Path(path), min_free_bytes=0, chunk_bytes=4096)

    def add(self, robot: str, topic: str, msg: Any, *, t: float) -> None:
        """``msg`` on ``/<robot>/<topic>`` (``robot=""``: at the root) at ``t`` seconds."""
        name = f"/{robot}/{topic}" if robot else f"/{topic.lstrip('/')}"
        self._writer.write(name, type_name(type(msg)), bytes(serialize_message(msg)),
                           self.ns(t))

    def ns(self, t: float) -> int:
        """The log time of ``t`` seconds."""
        return self._epoch_ns + round(t * 1e9)

    def close(self) -> None:
        self._writer.close()

    def __enter__(self) -> LogBuilder:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()


class RobotBag:
    """One robot's own bag as its recorder writes it: topics without the robot's namespace,
    log times on the robot's clock, and the clock estimates team_clock's ``ClockSync``
    publishes (``/team_clock/offset``, once a second over the bag's span), so that
    ``TeamLog.from_robot_logs`` and team_clock's ``merge`` put it on the team's time.

    The robot's clock reads ``ahead_s`` seconds ahead of the team's reference at
    ``epoch_s`` and runs ``drift_ppm`` fast. :meth:`add` takes reference seconds from
    ``epoch_s`` (where the message belongs on the team's time) and writes the robot's
    clock reading of that instant. A context manager (closes on exit).
    """

    def __init__(self, path: str | os.PathLike[str], *, robot: str, ahead_s: float,
                 drift_ppm: float = 0.0, reference: str = "world", epoch_s: float = 1000.0
                 ) -> None:
        self.robot, self.reference = robot, reference
        self._ahead_ns, self._rate = round(ahead_s * 1e9), drift_ppm * 1e-6
        self._epoch_ns = int(epoch_s * 1e9)
        self._writer = BagWriter(Path(path), min_free_bytes=0, chunk_bytes=4096)
        self._span: list[float] = []

    def local_ns(self, t: float) -> int:
        """The robot's clock at ``t`` reference seconds from the epoch."""
        return self._epoch_ns + self._ahead_ns + round(t * 1e9 * (1 + self._rate))

    def ns(self, t: float) -> int:
        """The reference time (ns) of ``t`` seconds from the epoch."""
        return self._epoch_ns + round(t * 1e9)

    def add(self, topic: str, msg: Any, *, t: float) -> None:
        """``msg`` on ``/<topic>`` of the robot's bag, logged at ``t`` reference seconds."""
        self._write(topic, msg, self.local_ns(t))
        self._span.append(t)

    def _write(self, topic: str, msg: Any, local_ns: int) -> None:
        self._writer.write(f"/{topic}", type_name(type(msg)), bytes(serialize_message(msg)),
                           local_ns)

    def close(self) -> None:
        """Write the clock estimates (every second over the bag's span) and close."""
        if self._span:
            for k in range(math.floor(min(self._span)), math.ceil(max(self._span)) + 1):
                local = self.local_ns(k)
                estimate = ClockOffset(robot=self.robot, reference=self.reference,
                                       source=self.reference, offset_ns=self.ns(k) - local,
                                       drift_ppm=(1 / (1 + self._rate) - 1) * 1e6,
                                       uncertainty_ns=100_000, samples=8, valid=True)
                estimate.stamp.sec, estimate.stamp.nanosec = divmod(local, 1_000_000_000)
                self._write("team_clock/offset", estimate, local)
        self._writer.close()

    def __enter__(self) -> RobotBag:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()


def film_ball(
    folder: str | os.PathLike[str],
    track: Callable[[float], tuple[float, float]],
    *,
    seconds: float,
    offset_s: float,
    drift_ppm: float,
    fps: int = 5,
    camera: Calibration = OVERHEAD,
    robots: Mapping[str, Callable[[float], tuple[float, float, float]]] | None = None,
) -> tuple[Path, Path]:
    """``folder/log`` with the ball's ground truth at 100 Hz on ``/world/ground_truth/ball``
    (log time = world time, from 0) and ``folder/match.mp4`` (H.264, with its sidecar)
    filming it on a camera clock ``offset_s`` ahead of the world's and ``drift_ppm`` fast:
    the ball (``track(t)`` -> field x, y) as a few orange pixels on turf, and beside it a
    red robot whose edge against the turf comes close to the ball's colour.

    ``robots`` (name -> ``t`` -> field x, y, yaw) adds what each believes at 10 Hz: its
    ``localization/pose`` (that pose), ``ball/position`` (the true ball, as seen from that
    pose, in ``base_footprint``) and ``team_ball`` (the true ball in the field frame), and
    its ``role`` (``striker``) once."""
    out_dir = Path(folder)
    log_path = out_dir / "log"
    with LogBuilder(log_path, epoch_s=0.0) as log:
        for i in range(int(seconds * 100) + 1):
            msg = PoseStamped()
            msg.pose.position.x, msg.pose.position.y = map(float, track(i / 100))
            msg.pose.position.z = 0.07
            msg.header.frame_id = "field"
            log.add("world", "ground_truth/ball", msg, t=i / 100)
            if i % 10 == 0:
                for name, where in (robots or {}).items():
                    _believe(log, name, where(i / 100), track(i / 100), t=i / 100)
        for name in robots or {}:
            log.add(name, "role", String(data="striker"), t=0.0)
    video = out_dir / "match.mp4"
    time_base = Fraction(1, 90_000)
    frames = int(seconds * fps)
    with av.open(str(video), "w") as container:
        stream: Any = container.add_stream("libx264", rate=fps)
        stream.width, stream.height, stream.pix_fmt = camera.width, camera.height, "yuv420p"
        stream.codec_context.time_base = stream.time_base = time_base
        for k in range(frames):
            world = k / fps
            img = np.empty((camera.height, camera.width, 3), np.uint8)
            img[:] = _TURF
            u, v = camera.project([(*track(world), 0.07)])[0]
            # The pixel that holds (u, v) (pixel k spans [k, k + 1]) and its neighbours.
            img[int(v) - 1:int(v) + 2, int(u) - 1:int(u) + 2] = _BALL
            img[60:80, 300:306] = _RED
            img[60:80, 306:307] = (150, 140, 55)
            camera_s = world + offset_s + drift_ppm * 1e-6 * world
            frame = av.VideoFrame.from_ndarray(img, format="rgb24")
            frame.pts = round((camera_s - offset_s) / time_base)
            frame.time_base = time_base
            container.mux(stream.encode(frame))
        container.mux(stream.encode())
    sidecar = {"format": SIDECAR_FORMAT, "video": video.name, "start_ns": round(offset_s * 1e9),
               "time_base": [1, 90_000], "fps": fps, "frames": frames, "width": camera.width,
               "height": camera.height, "view": {}, "calibration": asdict(camera)}
    video_sidecar_path(video).write_text(json.dumps(sidecar))
    return log_path, video


def _believe(log: LogBuilder, robot: str, pose: tuple[float, float, float],
             ball: tuple[float, float], *, t: float) -> None:
    x, y, yaw = map(float, pose)
    estimate = PoseWithCovarianceStamped()
    estimate.pose.pose.position.x, estimate.pose.pose.position.y = x, y
    estimate.pose.pose.orientation.z = math.sin(yaw / 2)
    estimate.pose.pose.orientation.w = math.cos(yaw / 2)
    log.add(robot, "localization/pose", estimate, t=t)
    dx, dy = ball[0] - x, ball[1] - y
    seen = PointStamped()
    seen.point.x = math.cos(yaw) * dx + math.sin(yaw) * dy
    seen.point.y = -math.sin(yaw) * dx + math.cos(yaw) * dy
    seen.header.frame_id = "base_footprint"  # as the robot's world model has it
    log.add(robot, "ball/position", seen, t=t)
    shared = PoseWithCovarianceStamped()  # the team's ball, in the field frame
    shared.header.frame_id = "field"
    shared.pose.pose.position.x, shared.pose.pose.position.y = map(float, ball)
    log.add(robot, "team_ball", shared, t=t)


def seen_ball(path: str | os.PathLike[str], *, robot: str,
              frames: Sequence[tuple[float, float | None, bool]], width: int = 320,
              height: int = 240, vfov_deg: float = 70.0, distance_m: float = 2.0) -> Path:
    """A log of ``robot``'s camera (JPEG on ``camera/image_raw/compressed``) and its ground
    truth: per frame ``(t, yaw_deg, bar)``, the ball ``distance_m`` ahead at ``yaw_deg``
    from the camera's axis (left positive; ``None``: behind the robot, not in the image),
    drawn as an orange disc on turf, and with ``bar`` an orange bar bigger than the ball
    elsewhere in the image (what the largest-blob rule mistakes for it). The robot stands
    at the origin facing +x, its neck straight (``joint_states``)."""
    f = (height / 2) / math.tan(math.radians(vfov_deg) / 2)
    with LogBuilder(path, epoch_s=0.0) as log:
        truth = PoseStamped()
        truth.pose.orientation.w = 1.0
        for t, yaw_deg, bar in frames:
            img = np.empty((height, width, 3), np.uint8)
            img[:] = (70, 160, 70)
            ball = PoseStamped()
            if yaw_deg is None:
                ball.pose.position.x = -distance_m
            else:
                yaw = math.radians(yaw_deg)
                ball.pose.position.x = distance_m * math.cos(yaw)
                ball.pose.position.y = distance_m * math.sin(yaw)
                u = width / 2 - f * math.tan(yaw)
                cv2.circle(img, (round(u), round(height * 0.7)), 6, (230, 110, 20), -1)
            if bar:
                cv2.rectangle(img, (20, 30), (90, 38), (230, 110, 20), -1)
            ok, jpeg = cv2.imencode(".jpg", cv2.cvtColor(img, cv2.COLOR_RGB2BGR),
                                    [cv2.IMWRITE_JPEG_QUALITY, 90])
            assert ok
            image = CompressedImage(format="jpeg", data=jpeg.tobytes())
            image.header.stamp.sec, image.header.stamp.nanosec = int(t), int(t % 1 * 1e9)
            log.add(robot, "camera/image_raw/compressed", image, t=t)
            log.add(robot, "ground_truth/pose", truth, t=t - 0.01)
            log.add(robot, "ground_truth/ball", ball, t=t - 0.01)
            log.add(robot, "joint_states", JointState(name=["neck_yaw", "neck_pitch"],
                                                      position=[0.0, 0.6]), t=t - 0.01)
    return Path(path)
