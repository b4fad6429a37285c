"""The walk engine alone: the gait generator and the component on a TestHandle (no physics)."""

from __future__ import annotations

import itertools
import math

import pytest
from geometry_msgs.msg import Twist
from nav_msgs.msg import Odometry
from sensor_msgs.msg import JointState
from std_msgs.msg import String

from efficient_comm import ManualClock, ParameterError
from efficient_comm.testing import TestHandle
from humanoid_sim.errors import SimConfigError
from humanoid_sim.soccer.leg_ik import leg_ik
from humanoid_sim.soccer.motion import MAX_STEP_S
from humanoid_sim.soccer.spline import BUMP, SMOOTH_STEP, Knot, QuinticSpline
from humanoid_sim.soccer.walk import PARAMETERS, Gait, GaitParameters, WalkEngine

DT = 0.01


def test_quintic_splines_meet_their_knots_smoothly() -> None:
    spline = QuinticSpline([Knot(0.0, 1.0, 0.5), Knot(2.0, -1.0, 0.0, 1.0), Knot(3.0, 0.0)])
    assert spline(0.0) == pytest.approx(1.0) and spline(2.0) == pytest.approx(-1.0)
    assert spline(3.0) == 0.0 and spline(-1.0) == 1.0 and spline(9.0) == 0.0
    h = 1e-6
    assert (spline(h) - spline(0.0)) / h == pytest.approx(0.5, abs=1e-4)
    assert (spline(2.0 + h) - spline(2.0 - h)) / (2 * h) == pytest.approx(0.0, abs=1e-4)
    assert SMOOTH_STEP(0.5) == pytest.approx(0.5) and BUMP(0.5) == pytest.approx(1.0)
    with pytest.raises(SimConfigError):
        QuinticSpline([Knot(1.0, 0.0), Knot(1.0, 1.0)])


def _run(gait: Gait, seconds: float) -> list[dict[str, float]]:
    return [gait.update(DT) for _ in range(round(seconds / DT))]


def test_standing_still_is_the_standing_pose() -> None:
    gait = Gait()
    stand = gait.joint_goals()
    assert _run(gait, 1.0)[-1] == stand and not gait.walking
    # The legs mirror each other, the soles level; the feet a little wider than the hips.
    assert stand["l_hip_roll"] == pytest.approx(-stand["r_hip_roll"]) and stand["l_hip_roll"] > 0
    for side in "lr":
        assert stand[f"{side}_hip_roll"] + stand[f"{side}_ankle_roll"] == pytest.approx(0.0)
        angles = leg_ik(0.0, 0.0, -GaitParameters().trunk_height, pitch=-0.08)
        assert stand[f"{side}_knee"] == pytest.approx(angles.knee, abs=0.02)


def _start_walk_stop(command: tuple[float, float, float], dt: float
                     ) -> tuple[dict[str, float], list[dict[str, float]], float]:
    """Stand, walk 4 s, stop 3 s at control period ``dt``: the standing pose, every goal
    and the largest change of any joint's goal from one cycle to the next."""
    gait = Gait()
    stand = gait.joint_goals()
    gait.set_command(*command)
    goals = [stand] + [gait.update(dt) for _ in range(round(4.0 / dt))]
    assert gait.walking and gait.velocity == pytest.approx(command)
    gait.set_command(0.0, 0.0, 0.0)
    goals += [gait.update(dt) for _ in range(round(3.0 / dt))]
    assert gait.amplitude == 0.0
    jumps = [max(abs(b[n] - a[n]) for n in a) for a, b in itertools.pairwise(goals)]
    return stand, goals, max(jumps)


@pytest.mark.parametrize("command", [(0.25, 0.0, 0.0), (0.0, 0.12, 0.0), (0.0, 0.0, 0.9),
                                     (-0.2, -0.1, -0.5)])
def test_start_and_stop_are_smooth_and_end_in_the_standing_pose(
        command: tuple[float, float, float]) -> None:
    stand, goals, jump = _start_walk_stop(command, DT)
    assert goals[-1] == pytest.approx(stand)
    # The feet really step: the swing foot's knee bends further than the standing one.
    assert max(g["l_knee"] for g in goals) > stand["l_knee"] + 0.15
    # No goal ever jumps: at half the control period every step between goals halves
    # (a discontinuity, at the start, the stop or anywhere, would not shrink).
    _, _, half = _start_walk_stop(command, DT / 2)
    assert half < 0.6 * jump
    # The first quarter second only begins to lift and sway: far gentler than full steps.
    start = goals[: round(0.25 / DT) + 1]
    assert max(max(abs(b[n] - a[n]) for n in a)
               for a, b in itertools.pairwise(start)) < 0.5 * jump


def test_odometry_integrates_the_commanded_steps() -> None:
    gait = Gait()
    gait.set_command(0.2, 0.0, 0.5)
    _run(gait, 10.0)
    x, y, yaw = gait.odometry
    # Start: one cycle stepping in place, then the accelerations; the rest at 0.5 rad/s.
    assert 3.5 < yaw < 5.0
    assert math.hypot(x, y) < 0.2 * 10.0 / 1.0  # a curve, shorter than the arc's length
    gait.set_command(5.0, -5.0, 9.0)  # clipped to the limits
    assert gait.command == (GaitParameters().max_vx, -GaitParameters().max_vy,
                            GaitParameters().max_wz)


def test_the_component_walks_on_cmd_vel_and_publishes_odometry() -> None:
    node = TestHandle("walk", namespace="/robot")
    engine = WalkEngine(node)
    odometry: list[Odometry] = []
    node.create_subscription(Odometry, "odom", odometry.append, qos=10)
    node.advance(0.5)
    commands: list[JointState] = node.published("motion/walk")
    assert commands and len(commands[-1].name) == 20  # the whole body
    twist = Twist()
    twist.linear.x = 0.2
    node.inject("cmd_vel", twist)
    node.advance(3.0)
    assert engine.gait.walking and odometry[-1].pose.pose.position.x > 0.1
    assert odometry[-1].twist.twist.linear.x == pytest.approx(0.2)
    assert odometry[-1].header.frame_id == "odom"
    broken = Twist()
    broken.linear.x = math.nan
    node.inject("cmd_vel", broken)  # refused, logged; the walk goes on
    assert engine.gait.command[0] == 0.2


def test_gait_parameters_change_at_run_time_and_bad_ones_are_refused() -> None:
    node = TestHandle("walk", parameters={"output_topic": "joint_commands", "freq": 1.8})
    engine = WalkEngine(node)
    assert engine.gait.p.freq == 1.8 and set(PARAMETERS) <= {f for f in dir(engine.gait.p)}
    node.set_parameter("step_height", 0.05)
    node.set_parameter("trunk_pitch", 0.12)
    assert engine.gait.p.step_height == 0.05 and engine.gait.p.trunk_pitch == 0.12
    with pytest.raises(ParameterError):
        node.set_parameter("freq", 40.0)
    assert engine.gait.p.freq == 1.8
    node.advance(0.1)
    assert node.published("joint_commands")
    with pytest.raises(SimConfigError, match="double_support"):
        GaitParameters(double_support=1.5).check()


def test_a_fall_stops_the_walk_and_its_commands() -> None:
    node = TestHandle("walk")
    engine = WalkEngine(node)
    twist = Twist()
    twist.angular.z = 0.5
    node.inject("cmd_vel", twist)
    node.advance(1.0)
    assert engine.gait.walking
    node.inject("fall/state", String(data="falling"))
    sent = len(node.published("motion/walk"))
    node.advance(1.0)
    assert engine.gait.amplitude == 0.0 and len(node.published("motion/walk")) == sent
    node.inject("fall/state", String(data="standing"))
    node.advance(0.1)
    assert len(node.published("motion/walk")) > sent and engine.gait.amplitude == 0.0


def test_the_gait_keeps_pace_with_the_clock_when_cycles_run_late() -> None:
    """A loaded real-time process runs the 100 Hz cycle at 25 Hz: the gait still advances by
    the time that passed (the body's physics did), and a stall moves it by a few periods only."""
    on_time, late = TestHandle("walk"), TestHandle("walk")
    engines = WalkEngine(on_time), WalkEngine(late)
    twist = Twist()
    twist.linear.x = 0.2
    for node in (on_time, late):
        node.inject("cmd_vel", twist)
    on_time.advance(1.01)
    clock = late.container.executor.clock
    assert isinstance(clock, ManualClock)
    engines[1].cycle()
    for _ in range(25):  # the timer's rounds 40 ms apart, not 10
        clock.set_ns(clock.now_ns() + 40_000_000)
        engines[1].cycle()
    assert engines[1].gait.phase == pytest.approx(engines[0].gait.phase, abs=0.02)
    assert engines[1].gait.odometry[0] == pytest.approx(engines[0].gait.odometry[0], rel=0.1)
    before = engines[1].gait.phase
    clock.set_ns(clock.now_ns() + 2_000_000_000)  # a 2 s stall
    engines[1].cycle()
    advanced = (engines[1].gait.phase - before) % 1.0
    assert advanced == pytest.approx(MAX_STEP_S * engines[1].gait.p.freq)
