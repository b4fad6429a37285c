"""The team match's world process: the world, the team referee, and each robot's sensors
delivered on that robot's own DDS domain.

Started by :mod:`.match` (one per match) with one JSON argument, the plan
(:func:`.match.world_plan`). It hosts, in one container on the world's domain, the
:class:`~.world_simulator.WorldSimulator` (robots' servo buses on ptys linked under
``port_dir``) and the :class:`~.soccer.team_referee.TeamReferee`; per robot a
:class:`SensorLink` holds a DDS participant on that robot's domain and forwards what the
robot's own hardware and radio would give it, under ``/<robot>/device/``: its camera
(``camera/image_raw``, ``camera/camera_info``), its IMU (``imu/data``), the
GameController's broadcast (``game_state``), and ground truth at 10 Hz
(``ground_truth/pose``, ``ground_truth/ball``: for the stand-in localization and the
robot's recording).

Why one participant per robot domain, here: each robot's domain is its own computer's
network, and the camera and IMU are the robot's own devices; the world is the only process
that has them. A bridge process per robot would copy every image twice more; a robot that
joined the world's domain would see every other robot's topics. The links only publish
(the servo buses are ptys), so nothing flows back from a robot's domain into the world.

With the plan's ``recording`` (:func:`add_world_recording`) it also records the ground truth
and the referee on the world's clock, answers every robot's ``ClockSync`` on the robot's
domain as the team's reference clock, and films the external video.

Every ``status_period_s`` it prints one line ``status {json}`` on stdout: simulated time,
real-time factor, game state and its changes so far, score, goals, the distance each robot
walked (ground truth, its torso sampled every half second of simulated time: one gait
cycle, so the sway from foot to foot does not count), the world's physics and render
times, its ticks (one IMU message per robot each), the IMU messages sent to each robot
while its reader was matched, and its CPU split
(:meth:`~.world_simulator.WorldSimulator.cpu_split`).
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import json
import math
import struct
import sys
import threading
import time
from collections.abc import Sequence
from typing import Any

import rclpy
from geometry_msgs.msg import PoseStamped
from rclpy.context import Context
from rclpy.duration import Duration
from sensor_msgs.msg import CameraInfo, Image, Imu

from efficient_comm import (
    Container,
    LockstepError,
    ManualClock,
    StepCoordinator,
    advance_together,
    latched_qos,
    stop_on_sigterm,
)
from efficient_comm.handle import NodeHandle
from robot_recorder import Recorder
from soccer_interfaces.msg import GameState

from .match_devices import DEVICE, IMU_DEPTH
from .match_recording import ClockServers, world_topics
from .match_video import MatchCamera
from .soccer.team_referee import STATE_NAMES, TeamReferee
from .world_simulator import WorldSimulator

#: Lockstep: how long the world waits for a robot's step, and for every robot to join.
STEP_TIMEOUT_S = 60.0
JOIN_TIMEOUT_S = 180.0


class SensorLink:
    """One robot's sensors on its own domain (see the module docstring).

    The camera's frames are observed on the world's bus, not subscribed: the link tells the
    world (:meth:`~.world_simulator.WorldSimulator.add_camera_demand`) that it wants a
    frame only while a reader on the robot's domain matches its image writer, so a robot
    that reads no camera costs no rendering.
    """

    def __init__(self, node: NodeHandle, *, robot: str, domain_id: int, truth_every: int,
                 world: WorldSimulator, camera_shm: bool = False) -> None:
        self.context = Context()
        rclpy.init(context=self.context, domain_id=domain_id)
        self.rnode = rclpy.create_node(f"{robot}_sensors", namespace=f"/{robot}",
                                       context=self.context)
        self._truth_every = max(1, truth_every)
        self._truth_count = 0
        pairs: list[tuple[type, str, str, Any]] = [
            (Image, f"/{robot}/camera/image_raw", "camera/image_raw", 2),
            (CameraInfo, f"/{robot}/camera/camera_info", "camera/camera_info",
             latched_qos()),
            (Imu, f"/{robot}/imu/data", "imu/data", IMU_DEPTH),
            (GameState, "/game_state", "game_state", latched_qos()),
        ]
        self.device_pubs: list[Any] = []  # what a lockstep step flushes
        #: IMU messages sent while the robot's reader was matched: what it should hear.
        self.imu_sent = 0
        self.camera: Container | None = None
        self._camera_thread: threading.Thread | None = None
        self._camera_pub: Any = None
        for msg_type, source, target, qos in pairs:
            if msg_type is Image:
                pub = (self._shm_camera(robot, domain_id, f"{DEVICE}/{target}", qos)
                       if camera_shm else
                       self.rnode.create_publisher(msg_type, f"{DEVICE}/{target}", qos))
                node.observe_in_process(Image, source, pub.publish)
                world.add_camera_demand(robot, functools.partial(_has_reader, pub))
            else:
                pub = self.rnode.create_publisher(msg_type, f"{DEVICE}/{target}", qos)
                relay = self._imu(pub) if msg_type is Imu else pub.publish
                node.create_subscription(msg_type, source, relay, qos=qos)
            self.device_pubs.append(pub)
        pose_pub = self.rnode.create_publisher(PoseStamped, f"{DEVICE}/ground_truth/pose", 10)
        ball_pub = self.rnode.create_publisher(PoseStamped, f"{DEVICE}/ground_truth/ball", 10)
        self.device_pubs += [pose_pub, ball_pub]
        node.create_subscription(PoseStamped, f"/ground_truth/{robot}/pose",
                                 lambda m: self._truth(pose_pub, m), qos=10)
        node.create_subscription(PoseStamped, "/ground_truth/ball",
                                 lambda m: self._truth(ball_pub, m, count=False), qos=10)

    def _shm_camera(self, robot: str, domain_id: int, topic: str, qos: Any) -> Any:
        """The camera's publisher on a container of its own on the robot's domain, with the
        shared-memory transport: the robot's process on this machine reads each frame in
        place (no CDR, no copy but the one into the chunk), and DDS still carries it to
        anyone else there (a ``ros2 topic echo``, the GUI). Its executor runs in a thread
        of its own: it only follows DDS's matched events, which tell the publisher whether
        a plain reader also wants the frame."""
        self.camera = Container(f"{robot}_camera", namespace=f"/{robot}", domain_id=domain_id,
                                serve=False, stats_period_s=0, shm=True)
        handle = self.camera.add(lambda n: n, name=f"{robot}_camera", namespace=f"/{robot}")
        self._camera_thread = threading.Thread(target=self.camera.spin,
                                               name=f"{robot}_camera", daemon=True)
        self._camera_thread.start()
        self._camera_pub = handle.create_publisher(Image, topic, qos=qos)
        return self._camera_pub

    def camera_traffic(self) -> tuple[int, int]:
        """Frames sent to the robot through shared memory, and frames written to DDS (for
        plain readers); (0, 0) without the transport."""
        shm = self.camera.shm if self.camera is not None else None
        if shm is None:
            return 0, 0
        sent = list(shm.traffic().values())
        return sum(t.shm_sends for t in sent), sum(t.dds_writes for t in sent)

    def _imu(self, pub: Any) -> Any:
        def relay(msg: Imu) -> None:
            pub.publish(msg)
            if pub.get_subscription_count():
                self.imu_sent += 1
        return relay

    def _truth(self, pub: Any, msg: PoseStamped, *, count: bool = True) -> None:
        if count:
            self._truth_count += 1
        if self._truth_count % self._truth_every == 0:
            pub.publish(msg)

    def wait_matched(self, timeout_s: float) -> None:
        """Wait until the robot's readers of every device topic have matched (lockstep,
        before the first step): a robot joins when it spins, which may be before discovery
        matched its readers, and what the world wrote until then was lost, the first IMU
        samples of one run and not of another (seen: 13 of 600 under load), so the game
        did not repeat."""
        deadline = time.monotonic() + timeout_s
        while missing := [p.topic_name for p in self.device_pubs if not self._connected(p)]:
            if time.monotonic() > deadline:
                raise LockstepError(f"lockstep: no reader of {', '.join(missing)} within "
                                    f"{timeout_s:g} s")
            time.sleep(0.05)  # DDS discovery has no event rclpy exposes here

    def _connected(self, pub: Any) -> bool:
        """Whether the robot's reader of ``pub`` gets what it writes from now on: matched on
        DDS and, for the camera through shared memory, its subscriber connected too."""
        via_shm = self.camera is not None and pub is self._camera_pub
        return _has_reader(pub) and (not via_shm or pub.shm_subscription_count() > 0)

    def flush(self, timeout_s: float) -> None:
        """Wait until the robot's readers have what this link wrote (lockstep: what the
        robot takes at the next intake is then exactly this step's)."""
        for pub in self.device_pubs:
            if not pub.wait_for_all_acked(Duration(nanoseconds=round(timeout_s * 1e9))):
                raise LockstepError(f"lockstep: the robot's readers of {pub.topic_name} "
                                    f"did not acknowledge within {timeout_s:g} s")

    def close(self) -> None:
        if self.camera is not None:
            self.camera.shutdown()
            if self._camera_thread is not None:
                self._camera_thread.join(timeout=10)
            self.camera.close()
        self.rnode.destroy_node()
        self.context.try_shutdown()


def _has_reader(pub: Any) -> bool:
    """Whether an rclpy publisher has a matched reader (DDS discovery: no event needed)."""
    return bool(pub.get_subscription_count())




def main(argv: list[str] | None = None) -> int:
    plan: dict[str, Any] = json.loads((argv or sys.argv[1:])[0])
    robots: list[str] = plan["robots"]

    stop_on_sigterm()
    lockstep = bool(plan.get("lockstep"))
    with contextlib.ExitStack() as stack:
        # Coordinators first: they prepare the process's DDS for lockstep (efficient_comm.dds:
        # prompt acknowledgements and heartbeats, or each step waits for them).
        coordinators = [stack.enter_context(StepCoordinator(
            [robot], domain_id=plan["domains"][robot], timeout_s=STEP_TIMEOUT_S,
            name=f"{robot}_steps")) for robot in robots] if lockstep else []
        container = stack.enter_context(Container(
            "match_world", dds=True, serve=False, stats_namespace="/world",
            clock=ManualClock() if lockstep else None))
        world: WorldSimulator = container.add(WorldSimulator, name="world",
                                              parameters=plan["world"])
        referee: TeamReferee = container.add(TeamReferee, name="team_referee",
                                             parameters=plan["referee"])
        links: dict[str, SensorLink] = {
            robot: container.add(functools.partial(
                SensorLink, robot=robot, domain_id=plan["domains"][robot],
                truth_every=round(plan["step_hz"] / 10.0), world=world,
                camera_shm=plan.get("camera_transport") == "shm"),
                                 name=f"{robot}_link")
            for robot in robots}
        truth = GroundTruthLog(robots)
        walked = dict.fromkeys(robots, 0.0)
        last: dict[str, tuple[float, float]] = {}
        sampled_at = [-math.inf]
        # [game state, simulated s] at each change, from the referee's first state on (the
        # sampling timer may first run after a loaded start has passed it).
        states: list[list[Any]] = [[STATE_NAMES.get(referee.state, str(referee.state)), 0.0]]

        def sample() -> None:
            name = STATE_NAMES.get(referee.state, str(referee.state))
            if not states or states[-1][0] != name:
                states.append([name, round(world.sim_time_s, 2)])
            truth.sample(world, len(states) - 1)
            if world.sim_time_s - sampled_at[0] < 0.5:
                return
            sampled_at[0] = world.sim_time_s
            for robot in robots:
                position, _ = world.world.torso_pose(robot)
                here = (float(position[0]), float(position[1]))
                if robot in last:
                    walked[robot] += math.dist(last[robot], here)
                last[robot] = here

        def report() -> None:
            status = world.status()
            print("status " + json.dumps({
                "sim_time_s": round(world.sim_time_s, 3),
                "real_time_factor": round(status["real_time_factor"], 3),
                "skipped_s": round(status["skipped_s"], 3),
                "game_state": STATE_NAMES.get(referee.state, str(referee.state)),
                "first_half": referee.first_half,
                "score": referee.score,
                "states": states,
                "goals": [[round(t / 1e9, 1), team] for t, team in referee.goals],
                "walked_m": {r: round(v, 3) for r, v in walked.items()},
                "physics_ms": round(status["physics_ms_mean"], 3),
                "render_ms": round(status["render_ms_mean"], 3),
                "frames": status["frames"],
                "lockstep": bool(coordinators),
                "truth_sha": truth.digest(),
                "moved_in_state_m": truth.moved_m,
                "at_state_start": truth.at_start,
                "ticks": status["ticks"], "tick_hz": round(status["tick_hz"], 1),
                "imu_sent": {r: link.imu_sent for r, link in links.items()},
                "camera_traffic": {r: link.camera_traffic() for r, link in links.items()},
                "cpu_s": {k: round(v, 3) for k, v in status["cpu_s"].items()},
            }), flush=True)

        clocks = add_world_recording(container, world, plan)
        tools = container.add(lambda n: n, name="match_status")
        tools.create_timer(0.1, sample)
        tools.create_timer(plan["status_period_s"], report)
        print("ready", flush=True)
        ok = True
        with contextlib.suppress(KeyboardInterrupt):
            if coordinators:
                ok = play_in_lockstep(container, coordinators, list(links.values()),
                                      dt_s=world.period_s,
                                      end_s=float(plan.get("end_s", 0.0)))
            else:
                container.spin()
        report()
        if clocks is not None:
            clocks.close()
    return 0 if ok else 1


class GroundTruthLog:
    """What the seeded SIL tests compare and check, from the world's ground truth.

    ``digest()``: a fingerprint of every robot's and the ball's exact pose at each sample
    (every 0.1 s simulated): two lockstep runs of one seed give the same, another seed
    (another start) a different one. Per game state entered (the index of the ``states``
    list), ``at_start`` holds each robot's (x, y) as the state began and ``moved_m`` the
    farthest each robot's torso got from where it stood :data:`SETTLE_S` into the state (a
    robot placed for the kick-off as ``set`` begins has not walked; the sway of a standing
    robot is centimetres).
    """

    SETTLE_S = 0.3

    def __init__(self, robots: Sequence[str]) -> None:
        self.robots = list(robots)
        self._sha = hashlib.sha256()
        self.at_start: list[dict[str, list[float]]] = []
        self.moved_m: list[dict[str, float]] = []
        self._state = -1
        self._state_began = 0.0
        self._anchor: dict[str, tuple[float, float]] = {}

    def sample(self, world: WorldSimulator, state: int) -> None:
        now = world.sim_time_s
        here: dict[str, tuple[float, float]] = {}
        for robot in self.robots:
            position, quat = world.world.torso_pose(robot)
            self._sha.update(struct.pack("<7d", *position, *quat))
            here[robot] = (float(position[0]), float(position[1]))
        ball, _ = world.world.ball_pose()
        self._sha.update(struct.pack("<3d", *ball))
        if state != self._state:
            self._state, self._state_began, self._anchor = state, now, {}
            self.at_start.append({r: [round(x, 3), round(y, 3)] for r, (x, y) in here.items()})
            self.moved_m.append(dict.fromkeys(self.robots, 0.0))
        if not self._anchor and now - self._state_began >= self.SETTLE_S:
            self._anchor = here
        if self._anchor:
            for robot, xy in here.items():
                moved = round(math.dist(self._anchor[robot], xy), 3)
                self.moved_m[-1][robot] = max(self.moved_m[-1][robot], moved)

    def digest(self) -> str:
        return self._sha.hexdigest()[:16]


def play_in_lockstep(container: Container, coordinators: Sequence[StepCoordinator],
                     links: Sequence[Any], *, dt_s: float, end_s: float) -> bool:
    """Step the world and every robot's process as one barrier until ``end_s`` simulated
    seconds (0: until stopped).

    Each step the robots run first, from t to t + dt, on what the world published at t
    (every robot's sensors, flushed to its domain before the step); then the world steps
    from t to t + dt with what the drivers wrote on their servo buses meanwhile (the
    world's tick syncs each bus first). The buses are ptys served by threads of their own
    here, so a driver's request inside a robot's step is answered while this thread waits
    on the barrier, and the world holds the buses' lock only while it steps, when no robot
    runs. A robot that does not finish a step within :data:`STEP_TIMEOUT_S`, or whose
    process is gone, ends the world with one line naming it: in lockstep nobody plays on
    without it (the match then ends, reporting what was played); False then.
    """
    for c in coordinators:
        c.wait_ready(timeout_s=JOIN_TIMEOUT_S)
    print("lockstep: every robot joined", flush=True)
    try:
        for link in links:
            link.wait_matched(JOIN_TIMEOUT_S)
        while not end_s or container.executor.clock.now_ns() < round(end_s * 1e9):
            for link in links:
                link.flush(STEP_TIMEOUT_S)
            advance_together(coordinators, dt_s)
            container.advance(dt_s)
    except LockstepError as exc:
        container.logger.error(f"the match ends: {exc}")
        return False
    return True


def add_world_recording(container: Container, world: WorldSimulator, plan: dict[str, Any]
                        ) -> ClockServers | None:
    """The plan's ``recording`` (:mod:`.match_recording`), if it has one: the world's
    clock answering on every robot's domain, its recorder of ground truth and referee, and
    the external video. Returns the clock servers, to be closed at the end."""
    recording = plan.get("recording")
    if not recording:
        return None
    container.add(Recorder, name="recorder", namespace="/world", parameters={
        "topics": world_topics(plan["robots"]), "output_dir": recording["bag_dir"],
        "autostart": True})
    video = recording.get("video")
    if video:
        container.add(functools.partial(MatchCamera, model=world.model, data=world.data,
                                        lock=world.lock),
                      name="match_camera", namespace="/world", parameters=video)
    if plan.get("lockstep"):  # every robot on the world's simulated time: nothing to measure
        return None
    return ClockServers({r: plan["domains"][r] for r in plan["robots"]},
                        clock=container.executor.clock)


if __name__ == "__main__":
    sys.exit(main())
