"""One robot of the team match, in a process of its own on its own DDS domain.

Started by :mod:`.match` with one JSON argument, the robot's plan (:func:`.match.robot_plan`),
and ``ROS_DOMAIN_ID`` set to the robot's domain. One container, namespace ``/<robot>``,
holds what runs on the robot: the servo driver on the world's pty for this robot, ball
detection and model, fall detector, head behaviour, walk, kick, get-up, motion arbiter, the
striker (``robot`` parameter: it obeys ``game_state`` and plays its ``role``), the team
layer (:class:`~.soccer.team_comm.TeamComm`) and its link, rf_bridge's ``BridgeNode``
(loaded by its component name, with the plan's bridge file: Zenoh on localhost, the team's
key space, a byte budget), the JPEG compressor and the recorder (idle until its ``~/start``
service is called, as in the one-robot demo).

The camera, the IMU, ``game_state`` and ground truth arrive on this robot's domain from the
world process (:mod:`.match_world`). ``localization/pose`` comes from
:class:`TruthPose`, a stand-in: ground truth with the sigma it claims, until a localization
takes its place behind the same topic.

Every ``status_period_s`` it prints ``status {json}`` on stdout: role, role switches, the
striker's state, game state, falls, the distance to the ball it believes in, camera frames
and IMU messages received, and the team link's usage as rf_bridge reports it on
``/diagnostics``.
"""

from __future__ import annotations

import contextlib
import json
import math
import sys
import time
from pathlib import Path
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PointStamped, PoseStamped, PoseWithCovarianceStamped
from sensor_msgs.msg import CameraInfo, Image, Imu
from std_msgs.msg import String

from debug_probes import JpegCompressor
from efficient_comm import ComponentSpec, Container, latched_qos, stop_on_sigterm
from efficient_comm.handle import NodeHandle
from soccer_interfaces.msg import GameState

from .demo import add_recorder
from .driver import ServoDriver
from .match_world import DEVICE, IMU_DEPTH
from .mujoco_plant import JOINTS
from .soccer.arbiter import MotionArbiter
from .soccer.behaviour import HeadBehaviour
from .soccer.fall import LATCHED, FallDetector
from .soccer.getup import GetUp
from .soccer.kick import Kick
from .soccer.striker import Striker
from .soccer.team_comm import TeamComm
from .soccer.team_referee import STATE_NAMES
from .soccer.vision import BallDetector
from .soccer.walk import WalkEngine
from .soccer.world_model import BallModel

#: rf_bridge's status name for the team link on ``/diagnostics``.
TEAM_LINK_STATUS = "rf_bridge: team link"


def main(argv: list[str] | None = None) -> int:
    plan: dict[str, Any] = json.loads((argv or sys.argv[1:])[0])
    name: str = plan["robot"]
    ns = f"/{name}"

    class DeviceInput:
        """The world's sensor topics (``device/<topic>`` on this robot's domain), taken
        from DDS once and published in-process as ``<topic>``.

        One composed subscription, so one DDS reader, per device topic: every subscriber of
        ``<topic>`` in the robot gets the sample by reference, and it is deserialized once
        (six subscribers of the IMU, each with its own reader, made six readers). It used to
        take them on a participant and thread of its own, because the container's executor
        took one DDS sample per wait and the robot heard its IMU at a fraction of its rate;
        the executor now takes every ready sample per wait (``efficient_comm``), so the
        thread, its GIL hand-overs and its second participant are gone.
        """

        def __init__(self, node: NodeHandle) -> None:
            for msg_type, topic, qos in ((Image, "camera/image_raw", 2),
                                         (CameraInfo, "camera/camera_info", latched_qos()),
                                         (Imu, "imu/data", IMU_DEPTH),
                                         (GameState, "game_state", latched_qos()),
                                         (PoseStamped, "ground_truth/pose", 10),
                                         (PoseStamped, "ground_truth/ball", 10)):
                pub = node.create_publisher(msg_type, topic, qos=qos)
                node.create_subscription(msg_type, f"{DEVICE}/{topic}", pub.publish, qos=qos)

    class TruthPose:
        """The stand-in localization: ground truth as ``localization/pose`` with the sigma
        ``pose_sigma_m`` it claims (no noise added)."""

        def __init__(self, node: NodeHandle) -> None:
            sigma = node.declare_parameter("pose_sigma_m", 0.1)
            self.variance = sigma * sigma
            self.pub = node.create_publisher(PoseWithCovarianceStamped, "localization/pose",
                                             qos=10)
            node.create_subscription(PoseStamped, "ground_truth/pose", self._on_truth, qos=10)

        def _on_truth(self, truth: PoseStamped) -> None:
            msg = PoseWithCovarianceStamped()
            msg.header.stamp, msg.header.frame_id = truth.header.stamp, "field"
            msg.pose.pose = truth.pose
            msg.pose.pose.position.z = 0.0
            cov = [0.0] * 36
            cov[0] = cov[7] = self.variance
            msg.pose.covariance = cov
            self.pub.publish(msg)

    class Status:
        """What the match prints about this robot (see the module docstring)."""

        def __init__(self, node: NodeHandle) -> None:
            self.node = node
            self.frames = self.imus = self.role_switches = 0
            self.first_imu = 0.0
            # Made last, as the robot is ready: its CPU from here on is the running cost.
            self.ready = (time.monotonic(), time.process_time())
            self.role = "-"
            self.link: dict[str, float] = {}
            self.ball: tuple[float, float, int] | None = None
            node.create_subscription(Image, "camera/image_raw", self._count_frame, qos=2)
            node.create_subscription(Imu, "imu/data", self._count_imu, qos=10)
            node.create_subscription(String, "role", self._on_role, qos=LATCHED)
            node.create_subscription(PointStamped, "ball/position", self._on_ball, qos=10)
            node.create_subscription(DiagnosticArray, "/diagnostics", self._on_diag, qos=10)
            node.create_timer(plan["status_period_s"], self.emit)

        def _count_frame(self, _: Image) -> None:
            self.frames += 1

        def _count_imu(self, _: Imu) -> None:
            if not self.imus:
                self.first_imu = time.monotonic()
            self.imus += 1

        def imu_hz(self) -> float:
            """IMU messages heard a wall second since the first (the world ticks at most
            100 Hz: a starved robot hears fewer)."""
            wall = time.monotonic() - self.first_imu if self.imus > 1 else 0.0
            return round((self.imus - 1) / wall, 1) if wall > 0 else 0.0

        def _on_role(self, msg: String) -> None:
            if self.role != "-" and msg.data != self.role:
                self.role_switches += 1
            self.role = msg.data

        def _on_ball(self, msg: PointStamped) -> None:
            self.ball = (msg.point.x, msg.point.y, self.node.clock.now_ns())

        def _on_diag(self, msg: DiagnosticArray) -> None:
            for status in msg.status:
                if status.name == TEAM_LINK_STATUS and status.hardware_id == name:
                    self.link = {kv.key: float(kv.value) for kv in status.values}

        def emit(self) -> None:
            now = self.node.clock.now_ns()
            distance = None
            if self.ball is not None and now - self.ball[2] < 2e9:
                distance = round(math.hypot(self.ball[0], self.ball[1]), 2)
            elif striker.ball_known() and striker.ball is not None:
                distance = round(math.dist((striker.pose.x, striker.pose.y), striker.ball), 2)
            game = striker.game.state
            print("status " + json.dumps({
                "role": self.role, "role_switches": self.role_switches,
                "behaviour": striker.state,
                "game_state": (STATE_NAMES.get(game.game_state, "?") if game is not None
                               else "-"),
                "falls": fall.falls, "posture": fall.state, "ball_m": distance,
                "frames": self.frames, "imus": self.imus, "imu_hz": self.imu_hz(),
                "cpu_pct": round(100 * (time.process_time() - self.ready[1])
                                 / max(1e-9, time.monotonic() - self.ready[0]), 1),
                "joint_states": len(driver.present),
                "link": self.link,
            }), flush=True)

    stop_on_sigterm()
    with Container(f"{name}_robot", namespace=ns, dds=True, serve=False,
                   stats_namespace=ns) as container:
        driver: ServoDriver = container.add(
            ServoDriver, name="servo_driver", namespace=ns,
            parameters={"port": plan["port"], "ids": list(JOINTS),
                        "joint_names": list(JOINTS.values())})
        container.add(BallDetector, name="ball_detector", namespace=ns)
        container.add(BallModel, name="ball_model", namespace=ns)
        fall: FallDetector = container.add(FallDetector, name="fall_detector", namespace=ns)
        container.add(HeadBehaviour, name="behaviour", namespace=ns)
        container.add(WalkEngine, name="walk", namespace=ns)
        container.add(Kick, name="kick", namespace=ns)
        container.add(GetUp, name="getup", namespace=ns)
        container.add(MotionArbiter, name="motion", namespace=ns)
        striker: Striker = container.add(Striker, name="striker", namespace=ns,
                                         parameters=plan["striker"])
        container.add(JpegCompressor, name="jpeg_compressor", namespace=ns)
        container.add(TruthPose, name="localization", namespace=ns)
        container.add(TeamComm, name="team_comm", namespace=ns, parameters=plan["team"])
        container.load(ComponentSpec(class_path="BridgeNode", name="rf_bridge", namespace=ns,
                                     parameters={"config": plan["bridge_file"]},
                                     source=f"the match's plan for {name}"))
        add_recorder(container, ns, Path(plan["bag_dir"]))
        # Last but the status: its readers match the world's writers only now, so the
        # samples sent while the robot was still being built do not overflow their history.
        container.add(DeviceInput, name="devices", namespace=ns)
        container.add(Status, name="match_status", namespace=ns)
        print("ready", flush=True)
        with contextlib.suppress(KeyboardInterrupt):
            container.spin()
    return 0


if __name__ == "__main__":
    sys.exit(main())
