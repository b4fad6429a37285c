"""A robot that only walks, and a measured walking trial: for the walking tests and bench.

The rig is the simulator, the real servo driver on the emulated bus, the fall detector and
the walk engine, whose whole-body commands go straight to ``joint_commands`` (the motion
arbiter, which normally owns that topic, is not needed to test walking). A trial stands
the robot for a moment, sends one velocity on ``cmd_vel``, walks for a while and measures
against the simulator's ground truth: the velocity achieved, whether it fell, how far the
walk engine's odometry drifted, and the peak torque and speed each joint's servo used.
"""

from __future__ import annotations

import math
import random
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import mujoco
from geometry_msgs.msg import Twist

from efficient_comm import Container
from efficient_comm.testing import TestHandle

from ..driver import ServoDriver
from ..joints import JOINTS
from ..mujoco_plant import NO_LOAD_SPEED_RAD_S, MujocoPlant
from ..simulator import Simulator
from .compose import add_body
from .fall import FallDetector
from .getup import GetUp
from .walk import Gait, GaitParameters, WalkEngine, standing_height

#: How often a trial samples ground truth and the servos (s of simulated time).
SAMPLE_S = 0.01
#: A torso tilted further than 40° has fallen (the fall detector's ``fall_tilt_deg``).
FALL_COS = math.cos(math.radians(40.0))


@dataclass(frozen=True)
class WalkingRobot:
    simulator: Simulator
    driver: ServoDriver
    fall_detector: FallDetector
    walk: WalkEngine
    #: The get-up component, when composed (``compose_walker(getup=...)``).
    getup: GetUp | None = None


def compose_walker(container: Container, *, namespace: str = "/robot",
                   simulator: Mapping[str, Any] | None = None,
                   driver: Mapping[str, Any] | None = None,
                   walk: Mapping[str, Any] | None = None,
                   getup: Mapping[str, Any] | None = None) -> WalkingRobot:
    """Add the walking robot to ``container``; the mappings override parameters.

    The camera is off unless ``simulator`` turns it on: walking does not look. With
    ``getup`` (its parameters, ``{}`` for the defaults) the robot also gets up after a fall:
    the get-up component sends to ``joint_commands`` too, which needs no arbiter because
    the walk is silent whenever the fall detector does not say ``standing`` and the get-up
    is silent whenever it does.
    """
    sim, servo_driver = add_body(container, namespace=namespace,
                                 simulator={"camera_hz": 0.0, **(simulator or {})},
                                 driver=driver)
    return WalkingRobot(
        simulator=sim, driver=servo_driver,
        fall_detector=container.add(FallDetector, name="fall_detector", namespace=namespace),
        walk=container.add(WalkEngine, name="walk", namespace=namespace,
                           parameters={"output_topic": "joint_commands", **(walk or {})}),
        getup=None if getup is None else container.add(
            GetUp, name="getup", namespace=namespace,
            parameters={"output_topic": "joint_commands", **getup}),
    )


def torso_pose(plant: MujocoPlant) -> tuple[float, float, float]:
    """Ground truth: the torso's x, y (m) and heading (rad) on the field."""
    data, torso = plant.data, plant.model.body("torso").id
    w, x, y, z = (float(v) for v in data.xquat[torso])
    return (float(data.xpos[torso][0]), float(data.xpos[torso][1]),
            math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z)))


def record_servo_peaks(plant: MujocoPlant, *, torque: dict[str, float],
                       speed: dict[str, float]) -> None:
    """Raise each joint's entry in ``torque`` (N m) and ``speed`` (rad/s) to what its servo
    uses now: a trial's peaks, sampled as it runs, say how near the servos' limits a motion
    goes (walking and kicking alike are limited by speed, not torque)."""
    for dxl_id, name in JOINTS.items():
        torque[name] = max(torque.get(name, 0.0), abs(plant.motor_torque(dxl_id)))
        speed[name] = max(speed.get(name, 0.0), abs(plant.state(dxl_id).velocity_rad_s))


def _wrap(angle: float) -> float:
    return (angle + math.pi) % (2 * math.pi) - math.pi


@dataclass
class WalkResult:
    """What a trial measured; velocities in the robot's starting frame (x forward)."""

    command: tuple[float, float, float]
    seconds: float
    vx: float = 0.0
    vy: float = 0.0
    wz: float = 0.0
    #: Simulated seconds into the walk at which the fall detector saw a fall (None: stood).
    fell_at_s: float | None = None
    #: Odometry minus ground truth at the end: position (m) and heading (rad).
    odom_drift_m: float = 0.0
    odom_drift_rad: float = 0.0
    #: Ground truth and odometry, (x, y, heading) at every sample, for plots.
    path: list[tuple[float, float, float]] = field(default_factory=list)
    #: Peak |torque| (N m) and |speed| (rad/s) by joint over the walk.
    peak_torque: dict[str, float] = field(default_factory=dict)
    peak_speed: dict[str, float] = field(default_factory=dict)

    @property
    def fell(self) -> bool:
        return self.fell_at_s is not None


def walk_trial(container: Container, robot: WalkingRobot, command: tuple[float, float, float],
               *, seconds: float, settle_s: float = 1.0, warmup_s: float = 0.0,
               stop_on_fall: bool = True) -> WalkResult:
    """Stand for ``settle_s``, walk at ``command`` (vx, vy, wz) for ``seconds``, measure.

    Velocities are the displacement from ``warmup_s`` into the walk to its end (0: start
    and acceleration included), turned into the heading the robot had when the command was
    sent; the heading change is summed over the samples, so turns of more than half a
    circle count in full. Odometry drift is over the whole walk.
    """
    container.advance(settle_s)
    probe = TestHandle("walk_trial", container=container)
    cmd_vel = probe.create_publisher(Twist, robot.walk.node.resolve_topic_name("cmd_vel"), qos=10)
    twist = Twist()
    twist.linear.x, twist.linear.y, twist.angular.z = command
    detector = robot.fall_detector
    falls0 = detector.falls + (detector.state != "standing")
    cmd_vel.publish(twist)
    result = _measure(command, robot.simulator.plant, robot.walk.gait,
                      lambda: container.advance(SAMPLE_S),
                      lambda: detector.falls + (detector.state != "standing") > falls0,
                      seconds=seconds, warmup_s=warmup_s, stop_on_fall=stop_on_fall)
    cmd_vel.publish(Twist())
    probe.destroy_publisher(cmd_vel)
    return result


def plant_trial(command: tuple[float, float, float], *, seconds: float, settle_s: float = 1.0,
                warmup_s: float = 0.0, stop_on_fall: bool = True,
                parameters: Mapping[str, float] | None = None,
                shove_seed: int | None = None, shove_newtons: float = 6.0) -> WalkResult:
    """:func:`walk_trial` without the bus: the gait drives the MuJoCo plant directly.

    Same physics, same servo model (goals slewed at the no-load speed, as the driver's
    writes with profile velocity 0 are), the gait fed the IMU's rates every 10 ms; what is
    missing is the driver and the emulated bus (a cycle's delay, the goals' rounding to
    encoder ticks, line noise). Ten times cheaper: for statistics over many long walks on a
    loaded machine, and for tuning. A fall is a tilt of 40° (the fall detector's).

    With ``shove_seed``, the walk is disturbed as a real one is (uneven turf, a touch of
    another robot): every 2 to 5 s a shove of up to ``shove_newtons`` in a random
    horizontal direction for 0.1 s (a standing robot takes 10 N), all drawn from the seed.
    """
    plant = MujocoPlant()
    gait = Gait(GaitParameters(**(parameters or {})))
    model, data = plant.model, plant.data
    ids = {name: dxl_id for dxl_id, name in JOINTS.items()}
    torso = model.body("torso").id
    rng = random.Random(shove_seed)
    next_shove = [settle_s + rng.uniform(2.0, 5.0) if shove_seed is not None else math.inf]

    def cycle() -> None:
        if data.time >= next_shove[0]:
            angle, force = rng.uniform(-math.pi, math.pi), rng.uniform(0.0, shove_newtons)
            plant.push((force * math.cos(angle), force * math.sin(angle), 0.0), duration_s=0.1)
            next_shove[0] += rng.uniform(2.0, 5.0)
        gyro = data.sensor("imu_gyro").data
        gait.set_gyro(float(gyro[1]), float(gyro[0]), SAMPLE_S)
        for name, goal in gait.update(SAMPLE_S).items():
            plant.command(ids[name], torque=True, goal_rad=goal,
                          max_speed_rad_s=NO_LOAD_SPEED_RAD_S)
        plant.step(SAMPLE_S)

    def fallen() -> bool:
        return float(data.xmat[torso][8]) < FALL_COS

    for name, goal in gait.joint_goals().items():  # the standing pose, then let it settle
        data.qpos[model.joint(name).qposadr[0]] = goal
    data.qpos[2] = standing_height(gait.p) - 0.02
    mujoco.mj_forward(model, data)
    for _ in range(round(settle_s / SAMPLE_S)):
        cycle()
    gait.set_command(*command)
    return _measure(command, plant, gait, cycle, fallen, seconds=seconds, warmup_s=warmup_s,
                    stop_on_fall=stop_on_fall)


def _measure(command: tuple[float, float, float], plant: MujocoPlant, gait: Gait,
             advance: Callable[[], None], fallen: Callable[[], bool], *, seconds: float,
             warmup_s: float, stop_on_fall: bool) -> WalkResult:
    """Advance in steps of :data:`SAMPLE_S` for ``seconds`` and measure (the trials' core)."""
    x0, y0, yaw0 = torso_pose(plant)
    odom0 = gait.odometry
    result = WalkResult(command=command, seconds=seconds)
    heading, last_yaw = 0.0, yaw0
    elapsed = 0.0
    warm: tuple[float, float, float, float] | None = None  # elapsed, x, y, heading
    while elapsed < seconds - 1e-9:
        advance()
        elapsed += SAMPLE_S
        x, y, yaw = torso_pose(plant)
        heading += _wrap(yaw - last_yaw)
        last_yaw = yaw
        result.path.append((x, y, heading))
        if warm is None and elapsed >= warmup_s - 1e-9:
            warm = (elapsed, x, y, heading)
        record_servo_peaks(plant, torque=result.peak_torque, speed=result.peak_speed)
        if result.fell_at_s is None and fallen():
            result.fell_at_s = elapsed
            if stop_on_fall:
                break
    c, s = math.cos(yaw0), math.sin(yaw0)
    x, y, _ = torso_pose(plant)
    result.seconds = elapsed
    if warm is not None and elapsed - warm[0] > 0:
        span, wx, wy = elapsed - warm[0], x - warm[1], y - warm[2]
        result.vx = (c * wx + s * wy) / span
        result.vy = (-s * wx + c * wy) / span
        result.wz = (heading - warm[3]) / span
    dx, dy = x - x0, y - y0
    ox, oy, oyaw = (a - b for a, b in zip(gait.odometry, odom0, strict=True))
    result.odom_drift_m = math.hypot(ox - (c * dx + s * dy), oy - (-s * dx + c * dy))
    result.odom_drift_rad = abs(oyaw - heading)
    return result
