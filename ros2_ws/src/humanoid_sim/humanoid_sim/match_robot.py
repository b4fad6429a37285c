"""One robot of the team match, in a process of its own on its own DDS domain.

Started by :mod:`.match` with one JSON argument, the robot's plan (:func:`.match.robot_plan`),
and ``ROS_DOMAIN_ID`` set to the robot's domain. One container, namespace ``/<robot>``,
holds what runs on the robot: the servo driver on the world's pty for this robot, ball
detection and model, fall detector, head behaviour, walk, kick, get-up, motion arbiter, the
striker (``robot`` parameter: it obeys ``game_state`` and plays its ``role``), the team
layer (:class:`~.soccer.team_comm.TeamComm`) and its link, rf_bridge's ``BridgeNode``
(loaded by its component name, with the plan's bridge file: Zenoh on localhost, the team's
key space, a byte budget), the JPEG compressor, team_clock's ``ClockSync`` against the
world and the recorder, recording from the start (:mod:`.match_recording`). The container
runs on this robot's own clock, off the world's by the plan's ``clock`` (``offset_s``,
``drift_ppm``), as a separate computer's would be.

The camera, the IMU, ``game_state`` and ground truth arrive on this robot's domain from the
world process (:mod:`.match_world`). ``localization/pose`` comes from the source the plan
names (:func:`.soccer.localization.add_localization`: the particle filter, noisy ground
truth or ground truth), and a :class:`~.soccer.pose_error.PoseErrorMonitor` measures it
against ground truth for the status line and the report.

Every ``status_period_s`` it prints ``status {json}`` on stdout: role, role switches, the
striker's state, game state, falls, the distance to the ball it believes in, camera frames
and IMU messages received, and the team link's usage as rf_bridge reports it on
``/diagnostics`` (``link_cut`` once the link failed).

In lockstep the team link delivers each teammate's message at a simulated time fixed by
the step it was sent in (``team_latency_s`` later; rf_bridge's ``lockstep_team_link``),
waiting for the plan's ``team_peers``: a seed's game repeats with teammates too.

SIGUSR1 (what the match sends at ``--team-link-cut-at`` in real time; in lockstep the plan's
``team_link_cut_at_s`` does it at that simulated time): the team link fails. The robot
unloads its rf_bridge, whose Zenoh session closes, so nothing more is sent to or heard from
its teammates; its team layer then finds them gone after its timeout and the robot plays
alone (:class:`TeamLinkCut`).
"""

from __future__ import annotations

import contextlib
import functools
import json
import math
import signal
import sys
import threading
import time
from pathlib import Path
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PointStamped, PoseStamped
from sensor_msgs.msg import CameraInfo, Image, Imu
from std_msgs.msg import String

from debug_probes import JpegCompressor
from efficient_comm import (
    ComponentSpec,
    Container,
    SkewedClock,
    from_msg,
    latched_qos,
    stop_on_sigterm,
    to_msg,
)
from efficient_comm.handle import NodeHandle
from soccer_interfaces.msg import GameState

from .driver import ServoDriver, WaitingPortHandler
from .joints import JOINTS
from .match_devices import DEVICE, IMU_DEPTH
from .match_recording import add_robot_recording
from .soccer.arbiter import MotionArbiter
from .soccer.behaviour import HeadBehaviour
from .soccer.fall import LATCHED, FallDetector
from .soccer.getup import GetUp
from .soccer.kick import Kick
from .soccer.localization import add_localization
from .soccer.pose_error import PoseErrorMonitor
from .soccer.striker import Striker
from .soccer.team_comm import TeamComm
from .soccer.team_referee import STATE_NAMES
from .soccer.vision import BallDetector
from .soccer.walk import WalkEngine
from .soccer.world_model import BallModel

#: rf_bridge's status name for the team link on ``/diagnostics``.
TEAM_LINK_STATUS = "rf_bridge: team link"
#: Lockstep: how long (wall ms) the driver waits for a servo's reply (:class:`LockstepPort`).
LOCKSTEP_REPLY_MS = 2000.0
#: What the world delivers under ``device/`` on the robot's domain: (type, topic, QoS).
DEVICE_TOPICS: tuple[tuple[type, str, Any], ...] = (
    (Image, "camera/image_raw", 2), (CameraInfo, "camera/camera_info", latched_qos()),
    (Imu, "imu/data", IMU_DEPTH), (GameState, "game_state", latched_qos()),
    (PoseStamped, "ground_truth/pose", 10), (PoseStamped, "ground_truth/ball", 10))


class LockstepPort(WaitingPortHandler):
    """dynamixel-sdk's PortHandler waiting up to :data:`LOCKSTEP_REPLY_MS` for a reply, on
    the line (``select``, :class:`~.driver.WaitingPortHandler`), not in the SDK's loop of
    empty reads: in lockstep that loop took most of a robot's step, about 150 reads a step
    while the world's bus thread in another process, which it starved, prepared the reply.

    In lockstep every servo of the world answers every request (no line noise in the
    match); a reply takes as long as the world's bus thread needs to get the CPU. The SDK's
    own timeout (about 34 ms with the stock latency timer) would, on a loaded machine,
    count misses an idle one never sees, and the game would change with the load. The
    world's bus is in another process, so the in-process :class:`~.dynamixel.pty.
    DirectPortHandler` cannot serve; a long wall-clock bound only stops a hang when the world
    is gone.
    """

    def setPacketTimeout(self, packet_length: int) -> None:  # noqa: N802 (the SDK's name)
        super().setPacketTimeout(packet_length)
        self.packet_timeout: float = max(float(self.packet_timeout), LOCKSTEP_REPLY_MS)

    def setPacketTimeoutMillis(self, msec: float) -> None:  # noqa: N802
        super().setPacketTimeoutMillis(max(msec, LOCKSTEP_REPLY_MS))


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
        thread, its GIL hand-overs and its second participant are gone. In lockstep the
        container's intake holds every sample until the step after the world published it
        (:mod:`efficient_comm.simtime`), so each robot hears each frame in the same step on
        every run.

        The camera and the IMU are this robot's own devices, so their stamps are on its
        clock: the world stamps them on its own, and the robot's clock is off the world's
        (the plan's ``clock``), so each stamp is moved to what this robot's clock read at
        that moment (exactly: the simulation knows the skew). Compared with the world's
        stamps, the ball model predicted the ball as far ahead as the clocks are apart (up
        to 0.8 s). Ground truth and the game state come from outside the robot and keep the
        world's stamps (the merged log matches them to the world's own records).
        """

        OWN = ("camera/image_raw", "imu/data")

        def __init__(self, node: NodeHandle) -> None:
            clock = node.clock
            local = clock.local_ns if isinstance(clock, SkewedClock) else None
            for msg_type, topic, qos in DEVICE_TOPICS:
                pub = node.create_publisher(msg_type, topic, qos=qos)
                relay = pub.publish
                if local is not None and topic in self.OWN:
                    relay = functools.partial(self._restamped, pub.publish, local)
                node.create_subscription(msg_type, f"{DEVICE}/{topic}", relay, qos=qos)

        @staticmethod
        def _restamped(publish: Any, local: Any, msg: Any) -> None:
            msg.header.stamp = to_msg(local(from_msg(msg.header.stamp)))
            publish(msg)

    class TeamLinkCut:
        """The team link failing on SIGUSR1, or in lockstep at the plan's simulated
        ``team_link_cut_at_s`` (the world's time: this robot's clock is skewed off it). The
        handler only sets a flag (it runs between any two bytecodes of the main thread,
        perhaps inside the executor); a timer, on the executor, unloads rf_bridge (the
        component manager's unload service does the same from a callback), and the status
        says ``link_cut`` from then on."""

        def __init__(self, node: NodeHandle) -> None:
            self.asked = threading.Event()
            self.cut = False
            signal.signal(signal.SIGUSR1, lambda *_: self.asked.set())
            at_s = plan.get("team_link_cut_at_s")
            self.at_ns = None if at_s is None else round(at_s * 1e9)
            self.clock = node.clock
            self.timer = node.create_timer(0.1, self._check)

        def _due(self) -> bool:
            if self.at_ns is None:
                return False
            now: int = self.clock.now_ns()
            world = self.clock.base_of(now) if isinstance(self.clock, SkewedClock) else now
            return bool(world >= self.at_ns)

        def _check(self) -> None:
            if (self.asked.is_set() or self._due()) and not self.cut:
                self.cut = True
                container.unload(bridge.unique_id)
                self.timer.cancel()

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
                "link": self.link, "link_cut": link_cut.cut,
                "localization": {"source": pose_error.errors.source,
                                 "errors": pose_error.errors.summary()},
            }), flush=True)

    stop_on_sigterm()
    clock = plan.get("clock", {})  # this computer's clock, off the world's (match_recording)
    lockstep = bool(plan.get("lockstep"))
    with Container(f"{name}_robot", namespace=ns, dds=True, serve=False, stats_namespace=ns,
                   clock_offset_s=clock.get("offset_s", 0.0),
                   clock_drift_ppm=clock.get("drift_ppm", 0.0),
                   lockstep=name if lockstep else None,
                   shm=plan.get("camera_transport") == "shm") as container:
        driver: ServoDriver = container.add(
            ServoDriver, name="servo_driver", namespace=ns,
            parameters={"port": plan["port"], "ids": list(JOINTS),
                        "joint_names": list(JOINTS.values())})
        if lockstep:
            driver.port_factory = LockstepPort
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
        add_localization(container, namespace=ns, source=plan["localization"]["source"],
                         parameters=plan["localization"]["parameters"])
        pose_error: PoseErrorMonitor = container.add(
            PoseErrorMonitor, name="pose_error", namespace=ns,
            parameters={"truth_topic": "ground_truth/pose"})
        container.add(TeamComm, name="team_comm", namespace=ns, parameters=plan["team"])
        bridge = container.load(ComponentSpec(
            class_path="BridgeNode", name="rf_bridge", namespace=ns,
            parameters={"config": plan["bridge_file"]}, source=f"the match's plan for {name}"))
        if container.lockstep is not None:  # team messages at a step fixed by the sending one
            bridge.instance.lockstep_team_link(container.lockstep, peers=plan["team_peers"],
                                               latency_s=plan["team_latency_s"])
        _, clock_sync = add_robot_recording(container, ns, robot=name,
                                            bag_dir=Path(plan["bag_dir"]),
                                            clock_sync=not lockstep)
        # Last but the status: its readers match the world's writers only now, so the
        # samples sent while the robot was still being built do not overflow their history.
        container.add(DeviceInput, name="devices", namespace=ns)
        link_cut: TeamLinkCut = container.add(TeamLinkCut, name="team_link_cut",
                                              namespace=ns)
        container.add(Status, name="match_status", namespace=ns)
        print("ready", flush=True)
        with contextlib.suppress(KeyboardInterrupt):
            container.spin()
        if clock_sync is not None:
            clock_sync.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
