"""The ball model: where the ball is relative to the torso, filtered and predicted.

A detection gives the ball's direction relative to the camera; turning that ray by the neck
angles at the moment the image was taken gives it relative to the torso, which does not move
when the head does. An alpha-beta filter per axis smooths the bearing and estimates its
rate, so the estimate is predicted to the present (the image is a few milliseconds old by
now) and carries the head over single missed detections.

Where the ball lies on the ground follows from the same bearing: the camera's ray, turned
level by the IMU's orientation (a walking torso leans and sways) and started at the camera
(moved by the neck angles), meets the plane of the ball's centre at the torso's known
height. That is ``ball/position``: the ball on the ground relative to the robot, in the
level frame under the torso (``base_footprint``: x forward, y left, z up), which is what
a behaviour that walks to the ball needs; the distance from the ball's apparent size
(``ball/estimate``'s z) is too coarse for that beyond a metre.
"""

from __future__ import annotations

import math

from geometry_msgs.msg import PointStamped, Quaternion
from sensor_msgs.msg import Imu, JointState

from efficient_comm import from_msg
from efficient_comm.handle import NodeHandle
from throttle_publisher import ThrottledPublisher

from ..errors import SimConfigError

BALL_RADIUS_M = 0.07
NECK = ("neck_yaw", "neck_pitch")
#: Joint states further from the image than this are not extrapolated to it.
MAX_EXTRAPOLATION_S = 0.05
#: The head's kinematics (``models/robot.xml``): neck yaw joint above the torso origin,
#: neck pitch joint above that, the camera ahead of and above the pitch joint (m).
NECK_YAW_ABOVE_TORSO = 0.1
NECK_PITCH_ABOVE_YAW = 0.03
CAMERA_FROM_PITCH = (0.05, 0.05)
#: The torso origin's height above the ground, standing or walking in the walk engine's
#: crouch (``walk.standing_height`` of its defaults).
TORSO_HEIGHT_M = 0.361
#: Rays flatter than this below the horizon meet the ground too far away to trust (rad).
MIN_DEPRESSION_RAD = math.radians(3.0)


def torso_bearing(yaw: float, pitch: float, *, neck_yaw: float, neck_pitch: float
                  ) -> tuple[float, float]:
    """(yaw left, pitch down) from the torso of what the camera sees at (yaw, pitch).

    Image angles do not simply add to the neck angles: with the head tilted down, a ball at
    the side of the image lies further to the side of the torso. The pinhole ray through
    the detection is turned by the head's pitch, then by the neck's yaw (the order of the
    joints from the head down); x forward, y left, z up.
    """
    x, y, z = 1.0, math.tan(yaw), -math.tan(pitch)
    c, s = math.cos(neck_pitch), math.sin(neck_pitch)
    x, z = c * x + s * z, c * z - s * x
    c, s = math.cos(neck_yaw), math.sin(neck_yaw)
    x, y = c * x - s * y, s * x + c * y
    return math.atan2(y, x), math.atan2(-z, math.hypot(x, y))


def _rotate(q: Quaternion, v: tuple[float, float, float]) -> tuple[float, float, float]:
    """``v`` turned by the unit quaternion ``q`` (body to world)."""
    w, x, y, z = q.w, q.x, q.y, q.z
    vx, vy, vz = v
    return (
        (1 - 2 * (y * y + z * z)) * vx + 2 * (x * y - w * z) * vy + 2 * (x * z + w * y) * vz,
        2 * (x * y + w * z) * vx + (1 - 2 * (x * x + z * z)) * vy + 2 * (y * z - w * x) * vz,
        2 * (x * z - w * y) * vx + 2 * (y * z + w * x) * vy + (1 - 2 * (x * x + y * y)) * vz,
    )


def ground_position(yaw: float, pitch: float, *, neck_yaw: float, neck_pitch: float,
                    orientation: Quaternion | None = None,
                    torso_height: float = TORSO_HEIGHT_M) -> tuple[float, float] | None:
    """Where the ball seen at torso bearing (yaw, pitch) lies: (x forward, y left) in m.

    The frame is level, under the torso origin, turned to the torso's heading; the
    torso's roll and pitch come from ``orientation`` (the IMU's; None: upright). None if
    the ray does not meet the ground in front of the camera (at or above the horizon).
    """
    ray = (math.cos(pitch) * math.cos(yaw), math.cos(pitch) * math.sin(yaw), -math.sin(pitch))
    cx, cz = CAMERA_FROM_PITCH
    c, s = math.cos(neck_pitch), math.sin(neck_pitch)
    hx, hz = c * cx + s * cz, c * cz - s * cx  # the camera, turned by the head's pitch
    c, s = math.cos(neck_yaw), math.sin(neck_yaw)
    camera = (c * hx, s * hx, NECK_YAW_ABOVE_TORSO + NECK_PITCH_ABOVE_YAW + hz)
    if orientation is not None and math.isfinite(
            norm := math.sqrt(orientation.w ** 2 + orientation.x ** 2 + orientation.y ** 2
                              + orientation.z ** 2)) and norm > 0:
        q = Quaternion(w=orientation.w / norm, x=orientation.x / norm,
                       y=orientation.y / norm, z=orientation.z / norm)
        ray, camera = _rotate(q, ray), _rotate(q, camera)
        forward = _rotate(q, (1.0, 0.0, 0.0))
        heading = math.atan2(forward[1], forward[0])
        c, s = math.cos(-heading), math.sin(-heading)
        ray = (c * ray[0] - s * ray[1], s * ray[0] + c * ray[1], ray[2])
        camera = (c * camera[0] - s * camera[1], s * camera[0] + c * camera[1], camera[2])
    if ray[2] > -math.sin(MIN_DEPRESSION_RAD):
        return None
    t = (BALL_RADIUS_M - torso_height - camera[2]) / ray[2]
    return camera[0] + t * ray[0], camera[1] + t * ray[1]


class NeckAngles:
    """The neck's angles when an image was taken: what the servos last reported
    (``joint_states``: stamp, position, velocity), moved on by the velocity to the image's
    stamp, at most :data:`MAX_EXTRAPOLATION_S` (the driver reads the servos after the
    camera in the same cycle, so a report is a few milliseconds off the image).

    The one owner of the camera's neck at image time: the ball model and the landmark
    detector each keep one, fed by their ``joint_states`` subscription.
    """

    def __init__(self) -> None:
        #: Per neck joint: stamp (ns), position (rad), velocity (rad/s) as last reported.
        self.reported: dict[str, tuple[int, float, float]] = {n: (0, 0.0, 0.0) for n in NECK}

    def update(self, state: JointState) -> None:
        """Take the neck joints of a ``joint_states`` message (others are ignored)."""
        stamp = from_msg(state.header.stamp)
        velocities = list(state.velocity) or [0.0] * len(state.name)
        for name, position, velocity in zip(state.name, state.position, velocities,
                                            strict=False):
            if name in self.reported:
                self.reported[name] = (stamp, position, velocity)

    def at(self, name: str, stamp_ns: int) -> float:
        """Joint ``name``'s angle (rad) at ``stamp_ns``."""
        reported, position, velocity = self.reported[name]
        dt = max(-MAX_EXTRAPOLATION_S, min(MAX_EXTRAPOLATION_S, (stamp_ns - reported) / 1e9))
        return position + velocity * dt


class _AlphaBeta:
    def __init__(self, alpha: float, beta: float) -> None:
        self.alpha, self.beta = alpha, beta
        self.value = self.rate = 0.0
        self.started = False

    def update(self, measured: float, dt: float) -> None:
        if not self.started or dt <= 0 or dt > 1.0:  # (re)start after a gap
            self.value, self.rate, self.started = measured, 0.0, True
            return
        predicted = self.value + self.rate * dt
        residual = measured - predicted
        self.value = predicted + self.alpha * residual
        self.rate += self.beta * residual / dt


class BallModel:
    def __init__(self, node: NodeHandle) -> None:
        self.node = node
        alpha = node.declare_parameter("alpha", 0.7)
        beta = node.declare_parameter("beta", 0.2)
        if not (0 < alpha <= 1 and 0 <= beta < 2):
            raise SimConfigError(f"need 0 < alpha <= 1 and 0 <= beta < 2, got {alpha}, {beta}")
        self.yaw, self.pitch = _AlphaBeta(alpha, beta), _AlphaBeta(alpha, beta)
        self.distance_m = 0.0
        self.torso_height = node.declare_parameter("torso_height", TORSO_HEIGHT_M,
                                                   range=(0.1, 2.0))
        self.orientation: Quaternion | None = None
        self.neck = NeckAngles()
        self._last_ns: int | None = None
        # Throttled, so a viewer's rate (the debug GUI's world view) reaches it.
        self.pub = ThrottledPublisher(node, PointStamped, "ball/estimate", qos=10)
        self.position_pub = node.create_publisher(PointStamped, "ball/position", qos=10)
        node.create_subscription(JointState, "joint_states", self.neck.update, qos=10)
        node.create_subscription(Imu, "imu/data", self._on_imu, qos=10)
        node.create_subscription(PointStamped, "ball/detection", self._on_detection, qos=10)

    def _on_imu(self, imu: Imu) -> None:
        self.orientation = imu.orientation  # shared, only read

    def _on_detection(self, detection: PointStamped) -> None:
        stamp = from_msg(detection.header.stamp)
        dt = (stamp - self._last_ns) / 1e9 if self._last_ns is not None else 0.0
        self._last_ns = stamp
        yaw, pitch = torso_bearing(detection.point.x, detection.point.y,
                                   neck_yaw=self.neck.at("neck_yaw", stamp),
                                   neck_pitch=self.neck.at("neck_pitch", stamp))
        self.yaw.update(yaw, dt)
        self.pitch.update(pitch, dt)
        if detection.point.z > 0:
            self.distance_m = BALL_RADIUS_M / math.sin(detection.point.z)
        ahead = max(0.0, (self.node.clock.now_ns() - stamp) / 1e9)
        estimate = PointStamped()
        estimate.header.stamp = detection.header.stamp  # shared, never modified
        estimate.header.frame_id = "torso"
        estimate.point.x = self.yaw.value + self.yaw.rate * ahead
        estimate.point.y = self.pitch.value + self.pitch.rate * ahead
        estimate.point.z = self.distance_m
        self.pub.publish(estimate)
        on_ground = ground_position(estimate.point.x, estimate.point.y,
                                    neck_yaw=self.neck.at("neck_yaw", stamp),
                                    neck_pitch=self.neck.at("neck_pitch", stamp),
                                    orientation=self.orientation,
                                    torso_height=self.torso_height)
        if on_ground is not None:
            position = PointStamped()
            position.header.stamp = detection.header.stamp
            position.header.frame_id = "base_footprint"
            position.point.x, position.point.y = on_ground
            self.position_pub.publish(position)
