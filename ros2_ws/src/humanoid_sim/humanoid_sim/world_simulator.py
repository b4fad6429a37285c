"""The team's simulator component: one world, several robots, each with its own servo bus.

It owns one :class:`~.world.World` (the field, the ball, up to six robots) and, per robot,
an emulated servo bus on a pty of its own, so each robot's servo driver runs unchanged,
in this process or another one (``port_dir``: a symlink ``<port_dir>/<robot>`` to the
robot's pty; the directory is made if missing). Every timer tick steps the shared world
once for all robots, paced as the one-robot :class:`~.simulator.Simulator` is
(:mod:`.pacing`): real time with catch-up on a wall clock, lockstep on a manual clock (each
bus is synced first, so every driver's last writes are applied before the step).

Topics, relative to the component's namespace (``/`` in the world process, so a robot's
topics are ``/<robot>/...``):

* per robot: ``<robot>/camera/image_raw`` (rgb8, rendered only while someone wants a frame:
  a throttled publisher; all cameras from one GL context on a render thread of their own,
  each frame published ``camera_latency_s`` after the instant it shows and stamped with
  that instant), ``<robot>/camera/camera_info``
  (transient local), ``<robot>/imu/data``;
* ground truth (field frame): ``ground_truth/<robot>/pose`` (the torso) and
  ``ground_truth/ball``, throttled publishers;
* in: ``place_robot`` (geometry_msgs/PoseStamped: ``header.frame_id`` names the robot, z is
  ignored, the orientation's yaw is its heading), ``place_ball`` (geometry_msgs/Point: x, y;
  the ball at rest). Placements that name no robot of the world or lie beyond the field's
  border strip are refused with one logged line.

CPU (:meth:`WorldSimulator.status`, ``cpu_s``): the world process's CPU seconds split into
physics (the executor thread while it steps), rendering (that thread while it takes the
cameras' views, the render thread while it draws them, and the software rasteriser's
``llvmpipe`` threads), bus emulation (every pty's emulator
thread) and the rest of the process (DDS, the sensor topics, the referee): what the match
reports and ``bench/match_bench.py`` measures.

Parameters: ``robots`` (names, ``blue1``..``red3``), per robot ``<robot>.pose`` (x, y,
heading; default :data:`~.world.DEFAULT_START`), ``ball_position``,
``step_hz``, ``camera_hz`` (0: no cameras), ``camera_width``, ``camera_height``,
``camera_latency_s`` (default 0.02: the world steps on while a frame is drawn; 0 publishes
it in the tick that took it, the world waiting for the draw), ``port_dir``,
``line_noise`` and ``seed`` (per bus, as the one-robot simulator's).
"""

from __future__ import annotations

import os
import threading
import time
from collections.abc import Callable
from contextlib import ExitStack
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from geometry_msgs.msg import Point, PoseStamped
from sensor_msgs.msg import CameraInfo, Image, Imu

from efficient_comm import Container, latched_qos
from efficient_comm.handle import NodeHandle, Publisher
from efficient_comm.standalone import standalone_main
from throttle_publisher import ThrottledPublisher

from . import sensors
from .driver import ServoDriver
from .dynamixel.bus import Bus
from .dynamixel.pty import PACKET_TIMEOUT_S, PtyBus, make_port_link, remove_port_link
from .errors import SimConfigError
from .joints import JOINTS
from .pacing import Pacer
from .render import RenderThread
from .sensors import CAMERA
from .simulator import SimParameters
from .world import DEFAULT_START, Pose2D, World, team_of


def _thread_cpu_s(task: Path) -> float:
    """User + system CPU seconds of one thread (``/proc/<pid>/task/<tid>``); 0 if gone."""
    try:
        fields = (task / "stat").read_text().rsplit(")", 1)[1].split()
        return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")
    except (OSError, IndexError, ValueError):
        return 0.0


def rasteriser_cpu_s() -> float:
    """CPU seconds of this process's software-rasteriser threads (Mesa's ``llvmpipe-N``):
    the part of a frame that is not on the thread that asked for it."""
    total = 0.0
    for task in Path("/proc/self/task").iterdir():
        try:
            if task.joinpath("comm").read_text().startswith("llvmpipe"):
                total += _thread_cpu_s(task)
        except OSError:
            continue
    return total


@dataclass
class ServedRobot:
    """One robot as the world serves it: its bus, the port its driver opens, its topics."""

    name: str
    pty: PtyBus
    port: str
    image_pub: ThrottledPublisher
    imu_pub: Publisher
    truth_pub: ThrottledPublisher
    #: Consumers of the camera outside this process's bus (:meth:`WorldSimulator.
    #: add_camera_demand`), each asked whether it wants a frame now.
    demands: list[Callable[[], bool]] = field(default_factory=list)
    #: Frames rendered for this robot.
    frames: int = 0


class WorldSimulator:
    def __init__(self, node: NodeHandle) -> None:
        self.node = node
        names = node.declare_parameter("robots", ["blue1"])
        ball = node.declare_parameter("ball_position", [0.0, 0.0])
        port_dir = node.declare_parameter("port_dir", "")
        common = SimParameters.declare(node)
        step_hz, camera_hz, width, height = (common.step_hz, common.camera_hz, common.width,
                                             common.height)
        if len(set(names)) != len(names):
            raise SimConfigError(f"robots: each name once, got {names}")
        if len(ball) != 2:
            raise SimConfigError(f"ball_position is [x, y] in metres, got {ball}")
        starts = {name: self._start_pose(name) for name in names}
        self.world = World(starts, ball=(ball[0], ball[1]))
        self.model, self.data = self.world.model, self.world.data
        self.period_s = 1.0 / step_hz
        self.camera_period_ns = round(1e9 / camera_hz) if camera_hz > 0 else 0
        latency_s = node.declare_parameter("camera_latency_s", 0.02)
        if not 0.0 <= latency_s <= 1.0:
            raise SimConfigError(f"camera_latency_s is 0..1 s, got {latency_s}")
        self.camera_latency_ns = round(latency_s * 1e9)
        self._lockstep = node.clock_kind == "manual"
        #: Held by every robot's bus while it answers, and while the world steps.
        self.lock = threading.Lock()
        self.renderer: RenderThread | None = None
        self.robots: dict[str, ServedRobot] = {}
        with ExitStack() as opened:
            if camera_hz > 0:
                self.renderer = RenderThread(self.model, width=width, height=height,
                                             name="world_render")
                opened.callback(self.renderer.close)
            for index, name in enumerate(names):
                pty = PtyBus(Bus(JOINTS, self.world.robots[name]), corrupt=common.line_noise,
                             seed=common.seed + index, lock=self.lock,
                             packet_timeout_s=None if self._lockstep else PACKET_TIMEOUT_S)
                opened.callback(pty.close)
                port = pty.port
                if port_dir:
                    port = os.path.join(port_dir, name)
                    try:
                        os.makedirs(port_dir, exist_ok=True)
                    except OSError as exc:
                        raise SimConfigError(f"cannot make port_dir {port_dir!r}: {exc}"
                                             ) from exc
                    make_port_link(pty.port, port)
                    opened.callback(remove_port_link, pty.port, port)
                node.create_publisher(
                    CameraInfo, f"{name}/camera/camera_info", qos=latched_qos(),
                ).publish(sensors.camera_info(self.model, camera=f"{name}/{CAMERA}",
                                              width=width, height=height))
                self.robots[name] = ServedRobot(
                    name=name, pty=pty, port=port,
                    image_pub=ThrottledPublisher(node, Image, f"{name}/camera/image_raw", qos=2),
                    imu_pub=node.create_publisher(Imu, f"{name}/imu/data", qos=10),
                    truth_pub=ThrottledPublisher(node, PoseStamped,
                                                 f"ground_truth/{name}/pose", qos=10),
                )
            self.ball_pub = ThrottledPublisher(node, PoseStamped, "ground_truth/ball", qos=10)
            node.create_subscription(PoseStamped, "place_robot", self._on_place_robot, qos=10)
            node.create_subscription(Point, "place_ball", self._on_place_ball, qos=10)
            self._pacer = Pacer(period_s=self.period_s)
            self._next_frame_ns: int | None = None
            #: The batch being drawn: its time, its robots, when it is published.
            self._drawing: tuple[int, list[str], int] | None = None
            self.frames = 0
            self.frames_skipped = 0
            self.render_ns = 0
            self.physics_ns = 0
            self.render_cpu_ns = 0  # thread CPU: what a loaded machine does not stretch
            self.physics_cpu_ns = 0
            self.ticks = 0
            self._first_tick = self._first_tick_cpu = 0.0
            node.create_timer(self.period_s, self.tick)
            self._opened = opened.pop_all()
        node.logger.info(
            f"{len(names)} robots, physics {step_hz:g} Hz, camera {camera_hz:g} Hz "
            f"({self.renderer.backend if self.renderer else 'off'}); servos on "
            + ", ".join(f"{r.name} {r.port}" for r in self.robots.values()))

    def _start_pose(self, robot: str) -> Pose2D:
        """The ``<robot>.pose`` parameter: [x, y, heading], by default the robot's
        :data:`~.world.DEFAULT_START` (checked against the field by the world)."""
        team_of(robot)
        default = DEFAULT_START[robot]
        pose = self.node.declare_parameter(f"{robot}.pose",
                                           [default.x, default.y, default.heading])
        if len(pose) != 3:
            raise SimConfigError(f"{robot}.pose is [x, y, heading] in m and rad, got {pose}")
        return Pose2D(*pose)

    @property
    def ports(self) -> dict[str, str]:
        """Each robot's servo port: what its driver opens (the link if ``port_dir``)."""
        return {name: robot.port for name, robot in self.robots.items()}

    def add_camera_demand(self, robot: str, wants: Callable[[], bool]) -> None:
        """Render ``robot``'s camera also while ``wants()`` says so.

        The world renders a camera only for a consumer: a subscriber of its image topic
        (or a throttled one whose rate is due), or one of these. A relay that forwards the
        image elsewhere (the match's sensor link, onto the robot's own DDS domain) observes
        the topic without counting as a subscriber and tells the world here whether anyone
        at the far end reads it: an unread camera costs no rendering.
        """
        self.robots[robot].demands.append(wants)

    # -- placements -----------------------------------------------------------------------

    def place_robot(self, robot: str, pose: Pose2D) -> None:
        """Put ``robot`` at ``pose``, upright and at rest (SimConfigError if it cannot be)."""
        with self.lock:
            self.world.place_robot(robot, pose)

    def place_ball(self, *, x: float, y: float, velocity: tuple[float, float] = (0.0, 0.0)
                   ) -> None:
        with self.lock:
            self.world.place_ball(x=x, y=y, velocity=velocity)

    def _on_place_robot(self, msg: PoseStamped) -> None:
        p = msg.pose.position
        pose = Pose2D(p.x, p.y, sensors.heading_of(msg.pose.orientation))
        try:
            self.place_robot(msg.header.frame_id, pose)
        except SimConfigError as exc:
            self.node.logger.error(f"place_robot ignored: {exc}")

    def _on_place_ball(self, point: Point) -> None:
        try:
            self.place_ball(x=point.x, y=point.y)
        except SimConfigError as exc:
            self.node.logger.error(f"place_ball ignored: {exc}")

    # -- the loop -------------------------------------------------------------------------

    @property
    def sim_time_s(self) -> float:
        return self.world.time_s

    @property
    def real_time_factor(self) -> float:
        return self._pacer.real_time_factor(self.sim_time_s)

    def tick(self) -> None:
        step = self._pacer.step_s(self.sim_time_s, lockstep=self._lockstep)
        if self._lockstep:  # every driver's last writes applied first
            for robot in self.robots.values():
                if not robot.pty.sync():
                    self.node.logger.error(f"{robot.name}'s servo bus emulator has stopped: "
                                           "physics steps without its last writes")
        started = time.perf_counter_ns()
        cpu = time.thread_time_ns()
        with self.lock:
            self.world.step(step)
        self.physics_cpu_ns += time.thread_time_ns() - cpu
        self.physics_ns += time.perf_counter_ns() - started
        if not self.ticks:
            self._first_tick, self._first_tick_cpu = time.monotonic(), time.process_time()
        self.ticks += 1
        now = self.node.clock.now_ns()
        for name, robot in self.robots.items():
            robot.imu_pub.publish(sensors.imu(self.data, prefix=f"{name}/", stamp_ns=now))
            position, quat = self.world.torso_pose(name)
            robot.truth_pub.publish(sensors.pose_stamped(position, quat, stamp_ns=now))
        position, quat = self.world.ball_pose()
        self.ball_pub.publish(sensors.pose_stamped(position, quat, stamp_ns=now))
        if self._drawing is not None and now >= self._drawing[2]:
            self._publish_images()
        if self.renderer is not None and (self._next_frame_ns is None
                                          or now >= self._next_frame_ns):
            self._next_frame_ns = (self._next_frame_ns or now) + self.camera_period_ns
            self._next_frame_ns = max(self._next_frame_ns, now)  # no burst after a stall
            self._capture_images(now)

    def _capture_images(self, now: int) -> None:
        """Take the views of the cameras someone wants a frame of; the render thread draws
        them while the world goes on, and they are published ``camera_latency_s`` later
        (a tick's time: in lockstep at the same step of every run, as a camera's frame
        arrives a while after the instant it shows)."""
        assert self.renderer is not None
        if self._drawing is not None:  # a latency beyond the camera's period
            self._publish_images()
        wanted = []
        for name, robot in self.robots.items():
            if robot.image_pub.wants() or any(wants() for wants in robot.demands):
                wanted.append(name)
            else:
                robot.image_pub.skip()  # so every_nth keeps counting the camera's frames
                self.frames_skipped += 1
        if not wanted:
            return
        started, cpu = time.perf_counter_ns(), time.thread_time_ns()
        self.renderer.capture(self.data, [f"{name}/{CAMERA}" for name in wanted])
        self.render_cpu_ns += time.thread_time_ns() - cpu
        self.render_ns += time.perf_counter_ns() - started
        self._drawing = (now, wanted, now + self.camera_latency_ns)
        if not self.camera_latency_ns:
            self._publish_images()

    def _publish_images(self) -> None:
        """Publish the batch the render thread drew (waiting for it if it is not done)."""
        assert self.renderer is not None and self._drawing is not None
        (stamp_ns, wanted, _), self._drawing = self._drawing, None
        images = self.renderer.collect()
        width, height = self.renderer.width, self.renderer.height
        for name in wanted:
            robot = self.robots[name]
            self.frames += 1
            robot.frames += 1
            robot.image_pub.publish(sensors.rgb8_image(
                images[f"{name}/{CAMERA}"], width=width, height=height, stamp_ns=stamp_ns))

    def status(self) -> dict[str, Any]:
        return {
            "sim_time_s": self.sim_time_s,
            "real_time_factor": self.real_time_factor,
            "skipped_s": self._pacer.skipped_s,
            "frames": self.frames,
            "frames_by_robot": {n: r.frames for n, r in self.robots.items()},
            "frames_skipped": self.frames_skipped,
            "render_ms_mean": self._render_wall_ns() / self.frames / 1e6 if self.frames else 0.0,
            "physics_ms_mean": self.physics_ns / self.ticks / 1e6 if self.ticks else 0.0,
            "bus_exceptions": {n: len(r.pty.errors) for n, r in self.robots.items()},
            "ticks": self.ticks,
            "tick_hz": ((self.ticks - 1) / (time.monotonic() - self._first_tick)
                        if self.ticks > 1 else 0.0),
            "cpu_s": self.cpu_split(),
        }

    def _render_wall_ns(self) -> int:
        """Wall time of the frames: their views taken here, their draws on the thread."""
        return self.render_ns + (self.renderer.draw_ns if self.renderer else 0)

    def cpu_split(self) -> dict[str, float]:
        """This process's CPU seconds since the first tick: physics, render, bus, other
        (the rest: DDS, the sensor topics, the referee; start-up not counted)."""
        process = time.process_time() - self._first_tick_cpu if self.ticks else 0.0
        physics = self.physics_cpu_ns / 1e9
        render = (self.render_cpu_ns + self.renderer.draw_cpu_ns) / 1e9 + rasteriser_cpu_s(
            ) if self.renderer else 0.0
        bus = sum(_thread_cpu_s(Path(f"/proc/self/task/{r.pty.thread_id}"))
                  for r in self.robots.values() if r.pty.thread_id is not None)
        return {"physics": physics, "render": render, "bus": bus,
                "other": max(0.0, process - physics - render - bus), "total": process}

    def close(self) -> None:
        """Close the GL context, the ptys and the port links (each once)."""
        self._opened.close()


def add_team(container: Container, *, namespace: str = "/",
             world: dict[str, Any] | None = None) -> tuple[WorldSimulator, dict[str, ServoDriver]]:
    """Add the world and, per robot, its servo driver on its own pty (namespace
    ``/<robot>``): the team's bodies without their software, in one process.

    On a manual clock each driver's port is wired straight to its bus
    (:class:`~.dynamixel.pty.DirectPortHandler`), as :func:`~.soccer.compose.add_body` does
    for one robot: a lockstep run does not depend on the machine's load.
    """
    sim: WorldSimulator = container.add(WorldSimulator, name="world", namespace=namespace,
                                        parameters=dict(world or {}))
    drivers: dict[str, ServoDriver] = {}
    for name, robot in sim.robots.items():
        parameters: dict[str, Any] = {"port": robot.port, "ids": list(JOINTS),
                                      "joint_names": list(JOINTS.values())}
        driver: ServoDriver = container.add(ServoDriver, name="servo_driver",
                                            namespace=f"/{name}", parameters=parameters)
        if container.clock_kind == "manual":
            driver.port_factory = robot.pty.direct_port
        drivers[name] = driver
    return sim, drivers


#: ``ros2 run humanoid_sim world --ros-args -p robots:=[blue1,red1] -p port_dir:=/tmp``: the
#: world in a process of its own; each robot's driver opens ``<port_dir>/<robot>``.
main = standalone_main(WorldSimulator, name="world")
