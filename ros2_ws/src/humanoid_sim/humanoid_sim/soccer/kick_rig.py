"""A robot that stands behind a ball and kicks it, and a measured kick trial: for tests and bench.

The rig is the simulator (camera off), the real servo driver on the emulated bus, the fall
detector, the walk engine, the kick and the motion arbiter that owns ``joint_commands``,
as :func:`~.compose.compose` wires them, without the vision pipeline. A trial stands the
robot, asks for a kick on ``motion/kick/request`` and follows the ball in the simulator's
ground truth until it lies still: how far it went, in which direction (against the torso's
heading when the kick was asked for), whether the robot fell, and the servos' peak torque
and speed. :func:`plant_kick_trial` is the same kick on the MuJoCo plant alone (no driver,
no bus): for tuning.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import mujoco
from sensor_msgs.msg import Imu
from std_msgs.msg import String

from efficient_comm import Container
from efficient_comm.testing import TestHandle

from ..driver import ServoDriver
from ..joints import JOINTS
from ..mujoco_plant import BALL_RADIUS_M, NO_LOAD_SPEED_RAD_S, MujocoPlant
from ..simulator import Simulator
from .arbiter import MotionArbiter
from .compose import add_body
from .fall import FallDetector
from .kick import SIDES, ImuSample, Kick, KickMotion, KickParameters
from .leg_ik import HIP_OFFSET
from .motion import STANCE
from .walk import WalkEngine
from .walk_rig import FALL_COS, SAMPLE_S, record_servo_peaks, torso_pose

#: Where the ball's centre lies ahead of the torso's origin for a kick (m).
BALL_AHEAD_M = 0.16
#: The ball is at rest below this speed (m/s).
REST_SPEED = 0.02


@dataclass(frozen=True)
class KickingRobot:
    simulator: Simulator
    driver: ServoDriver
    fall_detector: FallDetector
    walk: WalkEngine
    kick: Kick
    arbiter: MotionArbiter


def ball_spot(side: str, *, ahead_m: float = BALL_AHEAD_M, dx: float = 0.0,
              dy: float = 0.0) -> tuple[float, float]:
    """Where to put the ball for a robot standing at the origin facing +x (field frame)."""
    return (ahead_m + dx, HIP_OFFSET[SIDES[side][0]][1] + dy)


def compose_kicker(container: Container, *, namespace: str = "/robot",
                   simulator: Mapping[str, Any] | None = None,
                   driver: Mapping[str, Any] | None = None,
                   kick: Mapping[str, Any] | None = None) -> KickingRobot:
    """Add the kicking robot to ``container``; the mappings override parameters."""
    sim, servo_driver = add_body(container, namespace=namespace,
                                 simulator={"camera_hz": 0.0, **(simulator or {})},
                                 driver=driver)
    return KickingRobot(
        simulator=sim, driver=servo_driver,
        fall_detector=container.add(FallDetector, name="fall_detector", namespace=namespace),
        walk=container.add(WalkEngine, name="walk", namespace=namespace),
        kick=container.add(Kick, name="kick", namespace=namespace,
                           parameters=dict(kick or {})),
        arbiter=container.add(MotionArbiter, name="motion", namespace=namespace),
    )


@dataclass
class KickResult:
    """What a kick trial measured."""

    side: str
    #: The ball's way from where it lay to where it came to rest (or the trial ended), m.
    distance_m: float = 0.0
    #: Its direction against the torso's heading at the request (degrees, left positive).
    angle_deg: float = 0.0
    #: The ball's top speed (m/s).
    ball_speed: float = 0.0
    #: Seconds after the request at which the robot fell (None: it stood).
    fell_at_s: float | None = None
    #: The kick ran to its end (not refused, not aborted).
    completed: bool = False
    seconds: float = 0.0
    #: The ball's (x, y) on the field at every sample, for comparisons and plots.
    path: list[tuple[float, float]] = field(default_factory=list)
    peak_torque: dict[str, float] = field(default_factory=dict)
    peak_speed: dict[str, float] = field(default_factory=dict)

    @property
    def fell(self) -> bool:
        return self.fell_at_s is not None

    def success(self, *, distance_m: float = 0.3, angle_deg: float = 15.0) -> bool:
        """The issue's criterion: far enough, straight enough, and the robot stood."""
        return (not self.fell and self.distance_m >= distance_m
                and abs(self.angle_deg) <= angle_deg)


def _follow(result: KickResult, plant: MujocoPlant, advance: Callable[[], None],
            fallen: Callable[[], bool], kicking: Callable[[], bool], *,
            seconds: float, until_m: float | None = None) -> KickResult:
    """Advance in steps of :data:`SAMPLE_S` until the kick is over and the ball at rest
    (or, with ``until_m``, has gone that far), for at most ``seconds``."""
    ball = plant.model.body("ball").id
    velocity = plant.model.joint("ball").dofadr[0]
    start = [float(v) for v in plant.data.xpos[ball][:2]]
    _, _, heading = torso_pose(plant)
    elapsed = 0.0
    while elapsed < seconds - 1e-9:
        advance()
        elapsed += SAMPLE_S
        speed = math.hypot(float(plant.data.qvel[velocity]), float(plant.data.qvel[velocity + 1]))
        result.ball_speed = max(result.ball_speed, speed)
        bx, by = float(plant.data.xpos[ball][0]), float(plant.data.xpos[ball][1])
        result.path.append((bx, by))
        record_servo_peaks(plant, torque=result.peak_torque, speed=result.peak_speed)
        if result.fell_at_s is None and fallen():
            result.fell_at_s = elapsed
        if not kicking() and ((speed < REST_SPEED and elapsed > 1.0) or (until_m is not None
                              and math.hypot(bx - start[0], by - start[1]) >= until_m)):
            break
    result.seconds = elapsed
    dx = float(plant.data.xpos[ball][0]) - start[0]
    dy = float(plant.data.xpos[ball][1]) - start[1]
    result.distance_m = math.hypot(dx, dy)
    if result.distance_m > 1e-3:
        angle = math.atan2(dy, dx) - heading
        result.angle_deg = math.degrees((angle + math.pi) % (2 * math.pi) - math.pi)
    return result


def kick_trial(container: Container, robot: KickingRobot, side: str, *,
               settle_s: float = 1.5, seconds: float = 12.0,
               until_m: float | None = None) -> KickResult:
    """Stand for ``settle_s``, ask for a ``side`` kick, follow the ball for up to ``seconds``
    (or until the kick is over and the ball ``until_m`` away)."""
    container.advance(settle_s)
    probe = TestHandle("kick_trial", container=container)
    request = probe.create_publisher(
        String, robot.kick.node.resolve_topic_name("motion/kick/request"), qos=10)
    detector, kick = robot.fall_detector, robot.kick
    falls0 = detector.falls + (detector.state != "standing")
    kicks0 = kick.kicks
    result = KickResult(side=side)
    request.publish(String(data=side))
    result = _follow(result, robot.simulator.plant, lambda: container.advance(SAMPLE_S),
                     lambda: detector.falls + (detector.state != "standing") > falls0,
                     lambda: kick.active, seconds=seconds, until_m=until_m)
    result.completed = kick.kicks > kicks0
    probe.destroy_publisher(request)
    return result


def plant_kick_trial(side: str, *, ball: tuple[float, float] | None = None,
                     parameters: Mapping[str, Any] | None = None, settle_s: float = 1.0,
                     seconds: float = 12.0, until_m: float | None = None,
                     shove: tuple[float, tuple[float, float, float]] | None = None
                     ) -> KickResult:
    """:func:`kick_trial` on the MuJoCo plant alone: the kick's goals straight to the joints.

    Same physics and servo model (goals slewed at the no-load speed), the IMU's rates fed
    every 10 ms; no driver, no bus. ``ball`` is its (x, y) on the field, by default
    :func:`ball_spot`'s. ``shove`` is (seconds into the kick, force in N on the torso in the
    field frame) for 0.1 s: a disturbance while on one foot.
    """
    plant = MujocoPlant()
    model, data = plant.model, plant.data
    ids = {name: dxl_id for dxl_id, name in JOINTS.items()}
    torso = model.body("torso").id
    motion = KickMotion(side, KickParameters(**(parameters or {})))
    clock = [0.0]
    started = [False]

    def command(goals: Mapping[str, float]) -> None:
        for name, goal in goals.items():
            plant.command(ids[name], torque=True, goal_rad=goal,
                          max_speed_rad_s=NO_LOAD_SPEED_RAD_S)

    def cycle() -> None:
        gyro = data.sensor("imu_gyro").data
        w, x, y, z = (float(v) for v in data.sensor("imu_orientation").data)
        imu = Imu()
        imu.orientation.w, imu.orientation.x, imu.orientation.y, imu.orientation.z = w, x, y, z
        imu.angular_velocity.x, imu.angular_velocity.y = float(gyro[0]), float(gyro[1])
        motion.set_imu(ImuSample.from_imu(imu), SAMPLE_S)
        if started[0]:
            clock[0] += SAMPLE_S
            if shove is not None and abs(clock[0] - shove[0]) < SAMPLE_S / 2:
                plant.push(shove[1], duration_s=0.1)
            command(motion.goals(clock[0]))
        else:
            command(STANCE)
        plant.step(SAMPLE_S)

    for name, goal in STANCE.items():
        data.qpos[model.joint(name).qposadr[0]] = goal
    data.qpos[2] = 0.38
    bx, by = ball or ball_spot(side)
    q = model.joint("ball").qposadr[0]
    data.qpos[q:q + 7] = [bx, by, BALL_RADIUS_M, 1, 0, 0, 0]
    mujoco.mj_forward(model, data)
    for _ in range(round(settle_s / SAMPLE_S)):
        cycle()
    started[0] = True
    result = _follow(KickResult(side=side), plant, cycle,
                     lambda: float(data.xmat[torso][8]) < FALL_COS,
                     lambda: clock[0] < motion.duration, seconds=seconds, until_m=until_m)
    result.completed = clock[0] >= motion.duration and not result.fell
    return result
