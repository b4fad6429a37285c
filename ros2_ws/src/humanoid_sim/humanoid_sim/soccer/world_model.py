"""The ball model: where the ball is relative to the torso, filtered and predicted.

A detection gives the ball's direction relative to the camera; turning that ray by the neck
angles at the moment the image was taken gives it relative to the torso, which does not move
when the head does. An alpha-beta filter per axis smooths the bearing and estimates its
rate, so the estimate is predicted to the present (the image is a few milliseconds old by
now) and carries the head over single missed detections.
"""

from __future__ import annotations

import math

from geometry_msgs.msg import PointStamped
from sensor_msgs.msg import JointState

from efficient_comm import from_msg
from efficient_comm.handle import NodeHandle
from throttle_publisher import ThrottledPublisher

from ..errors import SimConfigError

BALL_RADIUS_M = 0.07
NECK = ("neck_yaw", "neck_pitch")
#: Joint states further from the image than this are not extrapolated to it.
MAX_EXTRAPOLATION_S = 0.05


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
        #: Neck joints as last reported: stamp (ns), position (rad), velocity (rad/s).
        self.neck: dict[str, tuple[int, float, float]] = {name: (0, 0.0, 0.0) for name in NECK}
        self._last_ns: int | None = None
        # Throttled, so a viewer's rate (the debug GUI's world view) reaches it.
        self.pub = ThrottledPublisher(node, PointStamped, "ball/estimate", qos=10)
        node.create_subscription(JointState, "joint_states", self._on_joints, qos=10)
        node.create_subscription(PointStamped, "ball/detection", self._on_detection, qos=10)

    def _on_joints(self, state: JointState) -> None:
        stamp = from_msg(state.header.stamp)
        velocities = list(state.velocity) or [0.0] * len(state.name)
        for name, position, velocity in zip(state.name, state.position, velocities,
                                            strict=False):
            if name in self.neck:
                self.neck[name] = (stamp, position, velocity)

    def neck_at(self, name: str, stamp_ns: int) -> float:
        """The joint's angle when the image was taken: the servo's last report, moved on
        by its velocity (the driver reads the servos after the camera in the same cycle)."""
        reported, position, velocity = self.neck[name]
        dt = max(-MAX_EXTRAPOLATION_S, min(MAX_EXTRAPOLATION_S, (stamp_ns - reported) / 1e9))
        return position + velocity * dt

    def _on_detection(self, detection: PointStamped) -> None:
        stamp = from_msg(detection.header.stamp)
        dt = (stamp - self._last_ns) / 1e9 if self._last_ns is not None else 0.0
        self._last_ns = stamp
        yaw, pitch = torso_bearing(detection.point.x, detection.point.y,
                                   neck_yaw=self.neck_at("neck_yaw", stamp),
                                   neck_pitch=self.neck_at("neck_pitch", stamp))
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
