"""The ball model: where the ball is relative to the torso, filtered and predicted.

A detection gives the ball's direction relative to the camera; adding the neck angles at
that moment gives it relative to the torso, which does not move when the head does. An
alpha-beta filter per axis smooths the bearing and estimates its rate, so the estimate is
predicted to the present (the image is a few milliseconds old by now) and carries the head
over single missed detections.
"""

from __future__ import annotations

import math

from geometry_msgs.msg import PointStamped
from sensor_msgs.msg import JointState

from efficient_comm import from_msg
from efficient_comm.handle import NodeHandle

from ..errors import SimConfigError

BALL_RADIUS_M = 0.07


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
        self.neck: dict[str, float] = {"neck_yaw": 0.0, "neck_pitch": 0.0}
        self._last_ns: int | None = None
        self.pub = node.create_publisher(PointStamped, "ball/estimate", qos=10)
        node.create_subscription(JointState, "joint_states", self._on_joints, qos=10)
        node.create_subscription(PointStamped, "ball/detection", self._on_detection, qos=10)

    def _on_joints(self, state: JointState) -> None:
        for name, position in zip(state.name, state.position, strict=False):
            if name in self.neck:
                self.neck[name] = position

    def _on_detection(self, detection: PointStamped) -> None:
        stamp = from_msg(detection.header.stamp)
        dt = (stamp - self._last_ns) / 1e9 if self._last_ns is not None else 0.0
        self._last_ns = stamp
        self.yaw.update(self.neck["neck_yaw"] + detection.point.x, dt)
        self.pitch.update(self.neck["neck_pitch"] + detection.point.y, dt)
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
