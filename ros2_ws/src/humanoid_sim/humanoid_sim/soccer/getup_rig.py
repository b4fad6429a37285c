"""A measured fall and get-up: for the get-up tests and bench.

The robot is the walking rig with the get-up component (:func:`.walk_rig.compose_walker`
with ``getup``). A trial stands it for a moment, then either lays it on its front or back
(:meth:`Simulator.lay_down`) or shoves it (:meth:`Simulator.push`), and follows the fall
detector and the get-up component against the simulator's ground truth until the robot
stands again (the fall detector says ``standing``) or the time is up.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from efficient_comm import Container

from ..errors import SimConfigError
from ..joints import JOINTS
from .walk import standing_height
from .walk_rig import SAMPLE_S, WalkingRobot, torso_pose


@dataclass
class GetUpResult:
    """What a get-up trial saw; times in simulated seconds from the lay-down or the shove."""

    #: The fall detector's states in the order it reported them (repeats collapsed).
    states: list[str] = field(default_factory=list)
    #: When the fall detector said ``fallen`` and, after that, ``standing`` again (None: never).
    fallen_at_s: float | None = None
    stood_at_s: float | None = None
    #: The side the get-up component found the robot lying on (None: it never played).
    side: str | None = None
    attempts: int = 0
    successes: int = 0
    #: Torso height (m) and tilt (deg) at the end.
    height_m: float = 0.0
    tilt_deg: float = 0.0
    #: The impact, from the lay-down or shove until 0.5 s after ``fallen``: the torso's peak
    #: acceleration (m/s², the IMU's accelerometer less gravity) and the peak motor torque
    #: of any servo (N m): what a protective reaction should lower.
    impact_accel: float = 0.0
    impact_torque: float = 0.0
    #: Ground truth every sample: x, y (m), heading (rad), height (m), for comparing runs.
    path: list[tuple[float, float, float, float]] = field(default_factory=list)

    @property
    def time_to_stand_s(self) -> float | None:
        """From the lay-down or shove to the fall detector's ``standing``."""
        return self.stood_at_s


def torso_tilt_deg(robot: WalkingRobot) -> float:
    plant = robot.simulator.plant
    up_z = float(plant.data.xmat[plant.model.body("torso").id][8])
    return math.degrees(math.acos(max(-1.0, min(1.0, up_z))))


def getup_trial(container: Container, robot: WalkingRobot, *, side: str | None = None,
                push_n: tuple[float, float, float] | None = None, settle_s: float = 1.0,
                timeout_s: float = 10.0, after_s: float = 0.0) -> GetUpResult:
    """Stand ``settle_s``, then lay the robot on ``side`` or shove it with ``push_n`` (N,
    field frame, 0.1 s), or neither (follow a robot that is already down), and advance until
    it stands again after having been down (then ``after_s`` more) or ``timeout_s`` has
    passed."""
    if robot.getup is None:
        raise SimConfigError("getup_trial needs a robot composed with getup")
    if side is not None and push_n is not None:
        raise SimConfigError("getup_trial takes side or push_n, not both")
    container.advance(settle_s)
    if side is not None:
        robot.simulator.lay_down(side)
    elif push_n is not None:
        robot.simulator.push(push_n)
    detector, getup = robot.fall_detector, robot.getup
    attempts0, successes0 = getup.attempts, getup.successes
    result = GetUpResult(states=[detector.state])
    elapsed, stood_for = 0.0, None
    down = detector.state != "standing"
    plant = robot.simulator.plant
    while elapsed < timeout_s - 1e-9:
        container.advance(SAMPLE_S)
        elapsed += SAMPLE_S
        if result.fallen_at_s is None or elapsed <= result.fallen_at_s + 0.5:
            ax, ay, az = (float(v) for v in plant.data.sensor("imu_accel").data)
            result.impact_accel = max(result.impact_accel,
                                      abs(math.sqrt(ax * ax + ay * ay + az * az) - 9.81))
            result.impact_torque = max(result.impact_torque, *(
                abs(plant.motor_torque(i)) for i in JOINTS))
        x, y, heading = torso_pose(robot.simulator.plant)
        result.path.append((x, y, heading, robot.simulator.plant.torso_height()))
        state = detector.state
        if state != result.states[-1]:
            result.states.append(state)
            if state == "fallen" and result.fallen_at_s is None:
                result.fallen_at_s = elapsed
            down = down or state != "standing"
            if state == "standing" and down:
                result.stood_at_s = elapsed
                stood_for = 0.0
        if stood_for is not None:
            stood_for += SAMPLE_S
            if stood_for >= after_s - 1e-9:
                break
    result.side = getup.side
    result.attempts = getup.attempts - attempts0
    result.successes = getup.successes - successes0
    result.height_m = robot.simulator.plant.torso_height()
    result.tilt_deg = torso_tilt_deg(robot)
    return result


def standing_torso_height(robot: WalkingRobot) -> float:
    """The torso's height when the robot stands in the walk's crouch (m)."""
    return standing_height(robot.walk.gait.p)
