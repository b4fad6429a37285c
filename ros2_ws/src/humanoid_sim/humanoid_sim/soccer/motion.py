"""Motion: the whole body's joint commands, from the stance and the head goal.

The robot stands in a slight crouch (knees bent, so it can balance and react); the head goal
is clamped to the neck's range. A command goes out at once for every head goal (the chain
from image to servo goal stays one pass) and at ``rate_hz`` otherwise, so the robot stands
even before anything is seen.
"""

from __future__ import annotations

from builtin_interfaces.msg import Time
from sensor_msgs.msg import JointState

from efficient_comm import to_msg
from efficient_comm.handle import NodeHandle

from ..mujoco_plant import JOINTS

STANCE: dict[str, float] = {name: 0.0 for name in JOINTS.values()} | {
    "l_hip_pitch": -0.35, "l_knee": 0.7, "l_ankle_pitch": -0.35,
    "r_hip_pitch": -0.35, "r_knee": 0.7, "r_ankle_pitch": -0.35,
    "l_shoulder_roll": 0.15, "r_shoulder_roll": -0.15, "l_elbow": -0.5, "r_elbow": -0.5,
    "neck_pitch": 0.45,
}
NECK_LIMITS = {"neck_yaw": (-2.0, 2.0), "neck_pitch": (-1.0, 1.3)}


class Motion:
    def __init__(self, node: NodeHandle) -> None:
        self.node = node
        rate = node.declare_parameter("rate_hz", 20.0)
        self.goal = dict(STANCE)
        self.pub = node.create_publisher(JointState, "joint_commands", qos=10)
        node.create_subscription(JointState, "head/goal", self._on_head, qos=10)
        node.create_timer(1.0 / rate, self._send)

    def _on_head(self, goal: JointState) -> None:
        for name, position in zip(goal.name, goal.position, strict=False):
            if name in NECK_LIMITS:
                low, high = NECK_LIMITS[name]
                self.goal[name] = min(high, max(low, position))
        self._send(goal.header.stamp)

    def _send(self, stamp: Time | None = None) -> None:
        command = JointState(name=list(self.goal), position=list(self.goal.values()))
        command.header.stamp = stamp if stamp is not None else to_msg(self.node.clock.now_ns())
        self.pub.publish(command)
