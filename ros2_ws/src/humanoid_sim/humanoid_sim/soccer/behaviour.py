"""Behaviour: look at the ball; when it has not been seen for a while, look for it.

Head goals are the estimated bearing itself (the world model already predicts it to the
present). Searching sweeps the head from side to side, looking down at the field in front.
While the fall detector says the robot is falling or has fallen (``fall/state``), the
behaviour is ``fallen``: it neither tracks nor searches, and claims neither; once the robot
stands again it starts by searching.
"""

from __future__ import annotations

import math

from geometry_msgs.msg import PointStamped
from sensor_msgs.msg import JointState
from std_msgs.msg import String

from efficient_comm import from_msg, to_msg
from efficient_comm.handle import NodeHandle

from .fall import LATCHED, STANDING

SEARCH_PERIOD_S = 6.0
SEARCH_YAW_RAD = 1.4
SEARCH_PITCH_RAD = 0.45


class HeadBehaviour:
    def __init__(self, node: NodeHandle) -> None:
        self.node = node
        self.lost_after_ns = round(node.declare_parameter("lost_after", 0.5) * 1e9)
        self.pub = node.create_publisher(JointState, "head/goal", qos=10)
        node.create_subscription(PointStamped, "ball/estimate", self._on_ball, qos=10)
        node.create_subscription(String, "fall/state", self._on_posture, qos=LATCHED)
        self.last_seen_ns: int | None = None
        self.state = "searching"
        self.switches = 0
        self._search_start_ns = node.clock.now_ns()
        node.create_timer(0.1, self._search)

    def _on_posture(self, posture: String) -> None:
        if posture.data != STANDING:
            self._set_state("fallen")
        elif self.state == "fallen":  # up again: where the ball is, is not known
            self.last_seen_ns = None
            self._set_state("searching")
            self._search_start_ns = self.node.clock.now_ns()

    def _look(self, yaw: float, pitch: float, stamp_ns: int | None = None) -> None:
        goal = JointState(name=["neck_yaw", "neck_pitch"], position=[yaw, pitch])
        goal.header.stamp = to_msg(self.node.clock.now_ns() if stamp_ns is None else stamp_ns)
        self.pub.publish(goal)

    def _set_state(self, state: str) -> None:
        if state != self.state:
            self.state = state
            self.switches += 1
            self.node.logger.info(f"head: {state}")

    def _on_ball(self, estimate: PointStamped) -> None:
        if self.state == "fallen":
            return
        self.last_seen_ns = self.node.clock.now_ns()
        self._set_state("tracking")
        self._look(estimate.point.x, estimate.point.y, from_msg(estimate.header.stamp))

    def _search(self) -> None:
        now = self.node.clock.now_ns()
        if self.state == "fallen" or (
                self.last_seen_ns is not None and now - self.last_seen_ns < self.lost_after_ns):
            return
        if self.state != "searching":
            self._search_start_ns = now
        self._set_state("searching")
        phase = 2 * math.pi * ((now - self._search_start_ns) / 1e9) / SEARCH_PERIOD_S
        self._look(SEARCH_YAW_RAD * math.sin(phase), SEARCH_PITCH_RAD)
