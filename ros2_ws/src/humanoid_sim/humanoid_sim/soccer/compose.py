"""The simulated soccer robot in one container: simulator, driver and the soccer pipeline.

The pipeline's motions (walk engine, kick) publish on their own topics; the motion arbiter
(:mod:`.arbiter`) is the one writer of ``joint_commands``.

The same wiring serves the demo, the software-in-the-loop tests and the benchmarks, on a
wall clock (real time) or a manual one (lockstep). The driver is given the simulator's pty
path as its port; everything else it does is what it would do on the robot.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from debug_probes import JpegCompressor
from efficient_comm import Container

from ..driver import ServoDriver
from ..joints import JOINTS
from ..simulator import Simulator
from .arbiter import MotionArbiter
from .behaviour import HeadBehaviour
from .fall import FallDetector
from .getup import GetUp
from .kick import Kick
from .localization import (
    PARTICLE_FILTER,
    Localization,
    NoisyTruthPose,
    TruthPose,
    add_localization,
)
from .monitor import SoccerMonitor
from .pose_error import PoseErrorMonitor
from .referee import Referee
from .striker import Striker
from .vision import BallDetector
from .walk import WalkEngine
from .world_model import BallModel

LOCKSTEP_LATENCY_TIMER_MS = 250.0


@dataclass(frozen=True)
class SoccerRobot:
    """The composed components, for inspection by tests, benchmarks and the demo."""

    simulator: Simulator
    driver: ServoDriver
    #: None when perception runs in another process (``compose(perception=False)``).
    detector: BallDetector | None
    ball_model: BallModel
    fall_detector: FallDetector
    behaviour: HeadBehaviour
    #: The motions (``motion/walk``, ``motion/kick``, ``motion/getup``) and the arbiter
    #: that owns ``joint_commands`` (``motion/state``).
    walk: WalkEngine
    kick: Kick
    getup: GetUp
    arbiter: MotionArbiter
    monitor: SoccerMonitor
    #: The body's behaviour: walk to the ball and kick it towards the opponent goal (None:
    #: a robot that only stands and tracks, ``compose(play=False)``).
    striker: Striker | None
    #: Goals and balls out of play, from ground truth; puts the ball back (not the robot's).
    referee: Referee
    #: ``camera/image_raw/compressed`` for viewers off the robot (encodes only on demand).
    compressor: JpegCompressor | None
    #: ``localization/pose`` from the particle filter or noisy ground truth (None: neither
    #: runs), and its error against ground truth.
    localization: Localization | NoisyTruthPose | TruthPose | None = None
    pose_error: PoseErrorMonitor | None = None


def add_body(container: Container, *, namespace: str,
             simulator: Mapping[str, Any] | None = None,
             driver: Mapping[str, Any] | None = None) -> tuple[Simulator, ServoDriver]:
    """Add the simulator and the servo driver on its pty: the robot without its software.

    On a manual clock (lockstep) the driver's port is wired straight to the emulator
    (:class:`~..dynamixel.pty.DirectPortHandler`): every write is answered before it
    returns, and a reply has timed out when the servos have sent everything and it is still
    short, never after wall time, so the run is the same at any load (and a fifth cheaper
    than through the pty). (The relaxed :data:`LOCKSTEP_LATENCY_TIMER_MS` stays for drivers
    given another port.)
    """
    sim: Simulator = container.add(Simulator, name="simulator", namespace=namespace,
                                   parameters=dict(simulator or {}))
    driver_parameters: dict[str, Any] = {"port": sim.port, "ids": list(JOINTS),
                                         "joint_names": list(JOINTS.values())}
    if container.clock_kind == "manual":
        driver_parameters["latency_timer_ms"] = LOCKSTEP_LATENCY_TIMER_MS
    driver_parameters.update(driver or {})
    servo_driver: ServoDriver = container.add(ServoDriver, name="servo_driver",
                                              namespace=namespace, parameters=driver_parameters)
    if container.clock_kind == "manual" and servo_driver.port_name == sim.port:
        # Answered in the driver's thread, no wall-clock timeout: the same run at any load
        # (the driver opens its port at its first cycle).
        servo_driver.port_factory = sim.pty.direct_port
    return sim, servo_driver


def compose(container: Container, *, namespace: str = "/robot",
            simulator: Mapping[str, Any] | None = None,
            driver: Mapping[str, Any] | None = None,
            striker: Mapping[str, Any] | None = None, play: bool = True,
            perception: bool = True, localization: str | None = None,
            localization_parameters: Mapping[str, Any] | None = None) -> SoccerRobot:
    """Add the robot to ``container``; ``simulator``/``driver``/``striker`` override their
    parameters. The striker's ``start_pose`` is the simulator's ``robot_pose`` unless given:
    where the robot was placed is what it knows at kick-off. ``play=False`` leaves the
    striker out: the robot stands and its head tracks (the tracking tests' robot).
    ``perception=False`` leaves out the ball detector and the JPEG compressor, the readers
    of the camera image that need nothing else: another process runs them
    (:mod:`humanoid_sim.split`).
    ``localization`` picks this robot's source of ``localization/pose``
    (:data:`.localization.SOURCES`; None: none) with ``localization_parameters``, measured by
    a :class:`.pose_error.PoseErrorMonitor`; the filter starts where the robot was placed
    unless its ``initial_pose`` is given.

    Order matters on a shared timer deadline: the simulator steps (and renders, and the
    pipeline reacts to the image in the same pass) before the driver reads and writes the
    servos, as on a robot whose camera and servo bus are sampled each cycle.
    The simulator and driver come from :func:`add_body`.
    """
    sim, servo_driver = add_body(container, namespace=namespace, simulator=simulator,
                                 driver=driver)
    striker = {"start_pose": list((simulator or {}).get("robot_pose", [0.0, 0.0, 0.0])),
               **(striker or {})}
    robot = SoccerRobot(
        simulator=sim,
        driver=servo_driver,
        detector=container.add(BallDetector, name="ball_detector", namespace=namespace)
        if perception else None,
        ball_model=container.add(BallModel, name="ball_model", namespace=namespace),
        fall_detector=container.add(FallDetector, name="fall_detector", namespace=namespace),
        behaviour=container.add(HeadBehaviour, name="behaviour", namespace=namespace),
        walk=container.add(WalkEngine, name="walk", namespace=namespace),
        kick=container.add(Kick, name="kick", namespace=namespace),
        getup=container.add(GetUp, name="getup", namespace=namespace),
        arbiter=container.add(MotionArbiter, name="motion", namespace=namespace),
        monitor=container.add(SoccerMonitor, name="monitor", namespace=namespace),
        striker=container.add(Striker, name="striker", namespace=namespace,
                              parameters=striker) if play else None,
        referee=container.add(Referee, name="referee", namespace=namespace),
        compressor=container.add(JpegCompressor, name="jpeg_compressor", namespace=namespace)
        if perception else None,
    )
    if localization is not None:
        if localization == PARTICLE_FILTER:  # placed there: what it knows at kick-off
            localization_parameters = {"initial_pose": striker["start_pose"],
                                       **(localization_parameters or {})}
        return dataclasses.replace(
            robot, localization=add_localization(container, namespace=namespace,
                                                 source=localization,
                                                 parameters=localization_parameters),
            pose_error=container.add(PoseErrorMonitor, name="pose_error", namespace=namespace))
    return robot
