"""The simulator component: MuJoCo physics behind the emulated servo bus, camera, IMU, truth.

It owns the one-robot world (``models/soccer_field.xml``; several robots share one in
:mod:`.world_simulator`) and serves the robot's 20 servos on a
pseudo-terminal, so the servo driver runs unchanged against it: the only thing the driver
sees of the simulation is a serial port. Every timer tick advances physics by one period:

* on a wall clock (a composed or standalone run), physics follows real time: a late tick
  steps further to catch up, at most :data:`MAX_CATCH_UP` periods; a stalled machine gives
  the rest up (:attr:`Simulator.skipped_s`), so the world slows down for a moment instead
  of jumping or racing afterwards, and :attr:`Simulator.real_time_factor` says whether the
  machine kept up;
* on a manual clock (``Container(clock=ManualClock())``, ``TestHandle``), everything moves in
  lockstep: ``advance(t)`` steps the physics, the driver and the pipeline by exactly ``t``,
  and the same seed gives the same run.

Published (names relative to the component): ``camera/image_raw`` (rgb8, rendered offscreen
only while someone wants a frame: a throttled publisher),
``camera/camera_info`` (transient local), ``imu/data``, and ground truth for tests and views:
``ground_truth/robot``, ``ground_truth/ball`` and ``ground_truth/camera`` (poses in the field
frame: origin at the centre spot, x toward the opponent goal, z up; the camera pose uses
MuJoCo's camera frame, which looks along -z with y up).

``robot_pose`` places the robot (x, y, heading on the field) before the first step; the
``place_ball`` topic (geometry_msgs/Point: x, y on the field) puts the ball there at rest,
as a referee does after a goal.

Pushes, for push-recovery and fall tests: :meth:`Simulator.push` shoves the torso with a
force for a while; the ``push`` topic (geometry_msgs/Vector3, an impulse in N s in the field
frame) does the same from anywhere, spread over :data:`PUSH_SECONDS`. For get-up trials,
:meth:`Simulator.lay_down` lays the robot on its front or back.
"""

from __future__ import annotations

import math
import random
import time
from contextlib import ExitStack
from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np
import numpy.typing as npt
from geometry_msgs.msg import Point, PoseStamped, Vector3
from sensor_msgs.msg import CameraInfo, Image, Imu

from efficient_comm import latched_qos
from efficient_comm.handle import NodeHandle
from efficient_comm.standalone import standalone_main
from throttle_publisher import ThrottledPublisher

from . import sensors
from .dynamixel.bus import Bus
from .dynamixel.pty import PACKET_TIMEOUT_S, PtyBus, make_port_link, remove_port_link
from .errors import SimConfigError
from .joints import JOINTS
from .mujoco_plant import MujocoPlant, set_ball
from .pacing import MAX_CATCH_UP as MAX_CATCH_UP
from .pacing import Pacer
from .render import OffscreenCamera
from .sensors import CAMERA

#: Where kicked balls go: in front of the robot, where its head can follow them.
KICK_AREA = ((0.8, 2.5), (-1.2, 1.2))
#: How fast the field slows a rolling ball (m/s²): the ball's rolling friction in
#: ``models/soccer_field.xml`` (``test_field.py`` measures it); a kick that should reach a
#: point rolls the ball off with the speed that stops it there.
ROLLING_DECELERATION = 0.8
#: How long a push that arrives as an impulse on the ``push`` topic lasts.
PUSH_SECONDS = 0.1
TRANSIENT_LOCAL = latched_qos()


@dataclass(frozen=True)
class SimParameters:
    """What every simulator component declares alike: rates, camera size, line noise."""

    step_hz: float
    camera_hz: float
    width: int
    height: int
    line_noise: float
    seed: int

    @classmethod
    def declare(cls, node: NodeHandle) -> SimParameters:
        """Declare them on ``node``; SimConfigError for values no simulator can work with."""
        p = cls(step_hz=node.declare_parameter("step_hz", 100.0),
                camera_hz=node.declare_parameter("camera_hz", 30.0),
                width=node.declare_parameter("camera_width", 320),
                height=node.declare_parameter("camera_height", 240),
                line_noise=node.declare_parameter("line_noise", 0.0),
                seed=node.declare_parameter("seed", 0))
        if p.step_hz <= 0 or p.camera_hz < 0 or not 0.0 <= p.line_noise < 1.0:
            raise SimConfigError(
                f"need step_hz > 0, camera_hz >= 0, 0 <= line_noise < 1; got {p.step_hz}, "
                f"{p.camera_hz}, {p.line_noise}"
            )
        return p


class Simulator:
    def __init__(self, node: NodeHandle) -> None:
        self.node = node
        common = SimParameters.declare(node)
        step_hz, camera_hz, width, height = (common.step_hz, common.camera_hz, common.width,
                                             common.height)
        line_noise, seed = common.line_noise, common.seed
        port_link = node.declare_parameter("port_link", "")
        ball_position = node.declare_parameter("ball_position", [1.5, 0.0])
        ball_velocity = node.declare_parameter("ball_velocity", [0.0, 0.0])
        robot_pose = node.declare_parameter("robot_pose", [0.0, 0.0, 0.0])
        self.kick_period_s = node.declare_parameter("ball_kick_period", 0.0)
        self._push_at_s = node.declare_parameter("push_at", 0.0)
        push_force = node.declare_parameter("push_force", [40.0, 0.0, 0.0])
        if len(ball_position) != 2 or len(ball_velocity) != 2:
            raise SimConfigError("ball_position and ball_velocity are [x, y] in metres (per s)")
        if len(robot_pose) != 3 or not all(map(math.isfinite, robot_pose)):
            raise SimConfigError(f"robot_pose is [x, y, heading] in m and rad, got {robot_pose}")
        if (len(push_force) != 3 or not all(map(math.isfinite, push_force))
                or not self._push_at_s >= 0):
            raise SimConfigError(f"push_force is [x, y, z] in newtons and push_at >= 0 s, got "
                                 f"{push_force} at {self._push_at_s}")
        self._push_force = (push_force[0], push_force[1], push_force[2])

        self.plant = MujocoPlant()
        self.model, self.data = self.plant.model, self.plant.data
        self._rng = random.Random(seed)
        self.period_s = 1.0 / step_hz
        self.camera: OffscreenCamera | None = None
        self.camera_period_ns = round(1e9 / camera_hz) if camera_hz > 0 else 0
        # What is opened here is closed again if a later step fails: the container never
        # sees a half-built simulator, so its close() would not run.
        with ExitStack() as opened:
            if camera_hz > 0:
                self.camera = OffscreenCamera(self.model, camera=CAMERA, width=width,
                                              height=height)
                opened.callback(self.camera.close)
            # In lockstep nothing may depend on wall time: no packet is dropped for being
            # slow to complete (a loaded machine may split a write by any time).
            self.pty = PtyBus(Bus(JOINTS, self.plant), corrupt=line_noise, seed=seed,
                              packet_timeout_s=None if node.clock_kind == "manual"
                              else PACKET_TIMEOUT_S)
            opened.callback(self.pty.close)
            self.port = self.pty.port
            if port_link:
                make_port_link(self.pty.port, port_link)
                opened.callback(remove_port_link, self.pty.port, port_link)
                self.port = port_link
            self.place_robot(x=robot_pose[0], y=robot_pose[1], heading=robot_pose[2])
            self.roll_ball(position=(ball_position[0], ball_position[1]),
                           velocity=(ball_velocity[0], ball_velocity[1]))

            # Throttled: a viewer off the robot asks for the rate it shows, and with nobody
            # subscribed no frame is rendered at all (each counted in ``frames_skipped``).
            self.image_pub = ThrottledPublisher(node, Image, "camera/image_raw", qos=2)
            info_pub = node.create_publisher(CameraInfo, "camera/camera_info",
                                             qos=TRANSIENT_LOCAL)
            info_pub.publish(self.camera_info(width, height))
            self.imu_pub = node.create_publisher(Imu, "imu/data", qos=10)
            # Throttled, so a viewer's rate (the debug GUI's world view) reaches them.
            self.truth_pubs = {
                what: ThrottledPublisher(node, PoseStamped, f"ground_truth/{what}", qos=10)
                for what in ("robot", "ball", "camera")
            }
            node.create_subscription(Vector3, "push", self._on_push, qos=10)
            node.create_subscription(Point, "place_ball", self._on_place_ball, qos=10)
            self.pushes = 0
            self.frames = 0
            self.frames_skipped = 0
            self.render_ns = 0
            self._next_frame_ns: int | None = None
            self._next_kick_s = self.kick_period_s
            self._pacer = Pacer(period_s=self.period_s, monotonic=time.monotonic)
            self._lockstep = node.clock_kind == "manual"
            node.create_timer(self.period_s, self.tick)
            self._opened = opened.pop_all()
        node.logger.info(
            f"servos on {self.port}; physics {step_hz:g} Hz, camera {camera_hz:g} Hz "
            f"({self.camera.backend if self.camera else 'off'})"
        )

    # -- the world ------------------------------------------------------------------------

    def camera_info(self, width: int, height: int) -> CameraInfo:
        return sensors.camera_info(self.model, camera=CAMERA, width=width, height=height)

    def roll_ball(self, *, position: tuple[float, float] | None = None,
                  velocity: tuple[float, float] = (0.0, 0.0)) -> None:
        """Put the ball at ``position`` (if given) and set it rolling at ``velocity`` (m/s)."""
        with self.pty.lock:
            set_ball(self.model, self.data, position=position, velocity=velocity)

    def place_robot(self, *, x: float, y: float, heading: float) -> None:
        """Put the robot's torso above (x, y) on the field, facing ``heading`` (rad), at rest
        (see :meth:`~.mujoco_plant.RobotPlant.place`)."""
        with self.pty.lock:
            self.plant.place(x=x, y=y, heading=heading)
            mujoco.mj_forward(self.model, self.data)

    def _on_place_ball(self, point: Point) -> None:
        if not (math.isfinite(point.x) and math.isfinite(point.y)):
            self.node.logger.error(f"place_ball ignored: ({point.x}, {point.y}) is not finite")
            return
        self.roll_ball(position=(point.x, point.y))

    def push(self, force_n: tuple[float, float, float], *, duration_s: float = PUSH_SECONDS,
             body: str = "torso") -> None:
        """Push ``body`` with ``force_n`` (newtons, field frame) for ``duration_s`` of simulated
        time, starting with the next physics step: a shove, as a push-recovery test gives.

        A robot of 3.6 kg standing in its crouch takes 10 N for 0.1 s and falls from 20 N.
        """
        with self.pty.lock:
            self.plant.push(force_n, duration_s=duration_s, body=body)
        self.pushes += 1

    def lay_down(self, side: str, *, heading: float | None = None, height_m: float = 0.12
                 ) -> None:
        """Lay the robot on its ``"front"`` (face down) or ``"back"``, where it stands now,
        as if it had fallen forward or backward from standing with ``heading`` (rad, field
        frame; default: its present heading), its torso ``height_m`` above the ground and at
        rest: a fallen robot for get-up trials.

        The joints keep their angles; the robot drops the last few centimetres onto the
        ground with the next physics steps.
        """
        if side not in ("front", "back"):
            raise SimConfigError(f"lay_down: side is 'front' or 'back', got {side!r}")
        with self.pty.lock:
            torso = self.model.body("torso").id
            w, x, y, z = (float(v) for v in self.data.xquat[torso])
            if heading is None:
                heading = math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
            pitch = math.pi / 2 if side == "front" else -math.pi / 2
            yaw_q = np.array([math.cos(heading / 2), 0.0, 0.0, math.sin(heading / 2)])
            pitch_q = np.array([math.cos(pitch / 2), 0.0, math.sin(pitch / 2), 0.0])
            quat = np.zeros(4)
            mujoco.mju_mulQuat(quat, yaw_q, pitch_q)
            root = self.model.joint("root")
            q, v = root.qposadr[0], root.dofadr[0]
            self.data.qpos[q + 2] = height_m
            self.data.qpos[q + 3 : q + 7] = quat
            self.data.qvel[v : v + 6] = 0.0
            for name in JOINTS.values():
                self.data.qvel[self.model.joint(name).dofadr[0]] = 0.0
            mujoco.mj_forward(self.model, self.data)

    def _on_push(self, impulse: Vector3) -> None:
        force = (impulse.x / PUSH_SECONDS, impulse.y / PUSH_SECONDS, impulse.z / PUSH_SECONDS)
        if not all(map(math.isfinite, force)):
            self.node.logger.error(f"push ignored: impulse ({impulse.x}, {impulse.y}, "
                                   f"{impulse.z}) N s is not finite")
            return
        self.push(force)

    def ball_position(self) -> npt.NDArray[np.float64]:
        return np.array(self.data.xpos[self.model.body("ball").id])

    def _kick(self) -> None:
        (x0, x1), (y0, y1) = KICK_AREA
        target = np.array([self._rng.uniform(x0, x1), self._rng.uniform(y0, y1)])
        way = target - self.ball_position()[:2]
        distance = float(np.linalg.norm(way))
        speed = math.sqrt(2 * ROLLING_DECELERATION * distance)  # rolls to rest there
        velocity = way / distance * speed if distance > 0 else way
        self.roll_ball(velocity=(float(velocity[0]), float(velocity[1])))

    # -- the loop -------------------------------------------------------------------------

    @property
    def sim_time_s(self) -> float:
        return float(self.data.time)

    @property
    def real_time_factor(self) -> float:
        """Simulated seconds per wall-clock second since the first tick."""
        return self._pacer.real_time_factor(self.sim_time_s)

    @property
    def skipped_s(self) -> float:
        """Simulated time given up because the machine fell behind (real time only)."""
        return self._pacer.skipped_s

    def tick(self) -> None:
        step = self._pacer.step_s(self.sim_time_s, lockstep=self._lockstep)
        if self.kick_period_s > 0 and self.sim_time_s >= self._next_kick_s:
            self._next_kick_s += self.kick_period_s
            self._kick()
        if self._push_at_s and self.sim_time_s >= self._push_at_s:
            self._push_at_s = 0.0
            self.push(self._push_force)
        if self._lockstep and not self.pty.sync():  # the driver's last writes applied first
            self.node.logger.error("servo bus emulator has stopped: physics steps without "
                                   "the servos' last writes")
        with self.pty.lock:
            self.plant.step(step)
        now = self.node.clock.now_ns()
        self._publish_imu(now)
        self._publish_truth(now)
        if self.camera is not None and (self._next_frame_ns is None or now >= self._next_frame_ns):
            self._next_frame_ns = (self._next_frame_ns or now) + self.camera_period_ns
            self._next_frame_ns = max(self._next_frame_ns, now)  # no burst after a stall
            self._publish_image(now)

    def _publish_image(self, now: int) -> None:
        assert self.camera is not None
        if not self.image_pub.wants():
            self.image_pub.skip()  # so every_nth keeps counting the camera's frames
            self.frames_skipped += 1
            return
        started = time.perf_counter_ns()
        image = sensors.image(self.camera.renderer, self.data, camera=CAMERA, stamp_ns=now)
        self.render_ns += time.perf_counter_ns() - started
        self.frames += 1
        self.image_pub.publish(image)

    def _publish_imu(self, now: int) -> None:
        self.imu_pub.publish(sensors.imu(self.data, stamp_ns=now))

    def _publish_truth(self, now: int) -> None:
        torso, ball = self.model.body("torso").id, self.model.body("ball").id
        cam = self.model.camera(CAMERA).id
        cam_quat = np.zeros(4)
        mujoco.mju_mat2Quat(cam_quat, self.data.cam_xmat[cam])
        poses = {
            "robot": (self.data.xpos[torso], self.data.xquat[torso]),
            "ball": (self.data.xpos[ball], self.data.xquat[ball]),
            "camera": (self.data.cam_xpos[cam], cam_quat),
        }
        for what, (position, quat) in poses.items():
            self.truth_pubs[what].publish(sensors.pose_stamped(position, quat, stamp_ns=now))

    def status(self) -> dict[str, Any]:
        return {
            "sim_time_s": self.sim_time_s,
            "real_time_factor": self.real_time_factor,
            "frames": self.frames,
            "frames_skipped": self.frames_skipped,
            "render_ms_mean": self.render_ns / self.frames / 1e6 if self.frames else 0.0,
            "skipped_s": self.skipped_s,
            "pushes": self.pushes,
            # What the emulated bus received that a real one would have refused or lost.
            "bus_exceptions": len(self.pty.errors),
            "bus_crc_errors": self.pty.bus.crc_errors,
            "bus_discarded_bytes": self.pty.discarded_bytes,
            "bus_dropped_replies": self.pty.dropped_replies,
        }

    def close(self) -> None:
        """Close the camera, the pty and the port link (each once)."""
        self._opened.close()


#: ``ros2 run humanoid_sim simulator --ros-args -p port_link:=/tmp/ttyDXL``: the simulator in
#: a process of its own; a driver elsewhere opens the link.
main = standalone_main(Simulator, name="simulator")
