"""The motion arbiter and the kick alone on a TestHandle: priorities, state topic, requests."""

from __future__ import annotations

from dataclasses import replace

import pytest
from sensor_msgs.msg import JointState
from std_msgs.msg import Bool, String

from efficient_comm import ManualClock, ParameterError, to_msg
from efficient_comm.testing import TestHandle
from humanoid_sim.errors import SimConfigError
from humanoid_sim.soccer.arbiter import MotionArbiter
from humanoid_sim.soccer.kick import Kick, KickMotion, KickParameters
from humanoid_sim.soccer.motion import NECK_LIMITS, STANCE


def _pose(value: float, stamp_ns: int = 0) -> JointState:
    """Every joint at ``value``: a motion's whole-body goals, told apart by the value."""
    goals = JointState(name=list(STANCE), position=[value] * len(STANCE))
    goals.header.stamp = to_msg(stamp_ns)
    return goals


def _last(node: TestHandle) -> dict[str, float]:
    command = node.published("joint_commands")[-1]
    return dict(zip(command.name, command.position, strict=True))


def _states(node: TestHandle) -> list[str]:
    return [s.data for s in node.published("motion/state")]


def test_arbiter_stands_and_clamps_head_goals() -> None:
    node = TestHandle("motion")
    MotionArbiter(node)
    node.advance(0.05)
    assert _last(node) == STANCE
    assert _states(node) == ["stand"]
    node.inject("head/goal", JointState(name=["neck_yaw", "neck_pitch", "l_knee"],
                                        position=[9.0, -9.0, 2.0]))
    command = _last(node)
    assert command["neck_yaw"] == NECK_LIMITS["neck_yaw"][1]
    assert command["neck_pitch"] == NECK_LIMITS["neck_pitch"][0]
    assert command["l_knee"] == STANCE["l_knee"]  # the head goal moves only the head


def test_arbiter_priorities_blending_and_state_topic() -> None:
    node = TestHandle("motion", parameters={"blend_s": 0.0})
    arbiter = MotionArbiter(node)
    node.inject("head/goal", JointState(name=["neck_yaw"], position=[0.3]))
    # The walk's goals count only while it says it is active.
    node.inject("motion/walk", _pose(0.1))
    assert _last(node)["l_knee"] == STANCE["l_knee"]
    node.inject("motion/walk/active", Bool(data=True))
    node.inject("motion/walk", _pose(0.1))
    assert _last(node)["l_knee"] == 0.1 and _last(node)["neck_yaw"] == 0.3
    # A kick outranks the walk; the head still moves the neck.
    node.inject("motion/kick/active", Bool(data=True))
    node.inject("motion/kick", _pose(0.2))
    node.inject("motion/walk", _pose(0.1))  # not forwarded while kicking
    assert _last(node)["l_knee"] == 0.2 and _last(node)["neck_yaw"] == 0.3
    # Fallen outranks the kick: the last command is held, head goals do not move the neck.
    node.inject("fall/state", String(data="fallen"))
    node.inject("head/goal", JointState(name=["neck_yaw"], position=[-0.5]))
    node.inject("motion/kick", _pose(0.25))
    node.advance(0.1)
    assert _last(node)["l_knee"] == 0.2 and _last(node)["neck_yaw"] == 0.3
    # The get-up outranks everything and moves the neck too.
    node.inject("motion/getup/active", Bool(data=True))
    node.inject("motion/getup", _pose(0.4))
    assert _last(node)["l_knee"] == 0.4 and _last(node)["neck_yaw"] == 0.4
    node.inject("motion/getup/active", Bool(data=False))
    assert arbiter.state == "fallen"
    node.inject("fall/state", String(data="standing"))
    node.inject("motion/kick/active", Bool(data=False))
    node.inject("motion/walk/active", Bool(data=False))
    node.advance(0.05)
    assert _last(node) == STANCE | {"neck_yaw": -0.5}
    assert _states(node) == ["stand", "walk", "kick", "fallen", "getup", "fallen", "kick",
                             "walk", "stand"]
    assert arbiter.transitions == 8
    assert arbiter.changes[("fallen", "getup")] == 1


def test_arbiter_blends_a_change_of_motion() -> None:
    node = TestHandle("motion", parameters={"blend_s": 0.2})
    MotionArbiter(node)
    node.advance(0.1)
    node.inject("motion/walk/active", Bool(data=True))
    start = STANCE["l_knee"]
    knees = []
    for _ in range(30):
        node.advance(0.01)
        node.inject("motion/walk", _pose(1.0))
        knees.append(_last(node)["l_knee"])
    steps = [b - a for a, b in zip([start, *knees], knees, strict=False)]
    assert knees[-1] == 1.0
    assert max(steps) <= (1.0 - start) * 0.01 / 0.2 + 1e-9  # no jump: at most its share
    assert knees[0] > start  # under way at once


def test_arbiter_refuses_bad_parameters() -> None:
    with pytest.raises(SimConfigError, match="blend_s"):
        MotionArbiter(TestHandle("motion", parameters={"blend_s": -1.0}))


def _kick_node() -> tuple[TestHandle, Kick]:
    node = TestHandle("kick")
    return node, Kick(node)


def _active(node: TestHandle) -> list[bool]:
    return [m.data for m in node.published("motion/kick/active")]


def test_kick_refuses_requests_unless_standing_and_idle() -> None:
    node, kick = _kick_node()

    def running() -> bool:  # a call: mypy does not narrow it between the steps
        return kick.active

    node.inject("motion/state", String(data="walk"))
    node.inject("motion/kick/request", String(data="right"))
    assert kick.refused == 1 and not running()
    assert any(level == "warning" and "refused" in text and "walk" in text
               for level, text in node.records)
    node.inject("motion/state", String(data="stand"))
    node.inject("motion/kick/request", String(data="middle"))
    assert kick.refused == 2 and not running()
    node.inject("motion/kick/request", String(data="left"))
    assert running() and _active(node) == [False, True]
    node.inject("motion/state", String(data="kick"))
    node.inject("motion/kick/request", String(data="left"))  # one at a time
    assert kick.refused == 3
    node.advance(KickMotion("left").duration + 0.05)
    assert not running() and kick.kicks == 1 and _active(node) == [False, True, False]
    goals = node.published("motion/kick")
    first = dict(zip(goals[0].name, goals[0].position, strict=True))
    last = dict(zip(goals[-1].name, goals[-1].position, strict=True))
    # It starts and ends in the standing pose (within the IK's rounding).
    for name, value in STANCE.items():
        assert first[name] == pytest.approx(value, abs=1e-3)
        assert last[name] == pytest.approx(value, abs=1e-6)


def test_a_kick_late_timer_still_takes_the_kicks_duration() -> None:
    """Its timer's rounds 40 ms apart, not 10 (a loaded real-time process): the kick is
    played against the clock, not slowed to four times its length."""
    node, kick = _kick_node()
    clock = node.container.executor.clock
    assert isinstance(clock, ManualClock)
    node.inject("motion/kick/request", String(data="right"))
    started, rounds = clock.now_ns(), 0
    while kick.active and rounds < 1000:
        clock.set_ns(clock.now_ns() + 40_000_000)
        kick.cycle()
        rounds += 1
    took_s = (clock.now_ns() - started) / 1e9
    assert kick.kicks == 1
    assert took_s == pytest.approx(KickMotion("right").duration, abs=0.05)  # to a round


def test_kick_is_aborted_by_a_fall() -> None:
    node, kick = _kick_node()
    node.inject("motion/kick/request", String(data="right"))
    node.advance(0.5)
    node.inject("fall/state", String(data="falling"))
    assert not kick.active and kick.aborted == 1 and _active(node)[-1] is False


def test_kick_swings_the_kicking_foot_only() -> None:
    motion = KickMotion("right")
    start, end = motion.swing
    before, after = motion.goals(start), motion.goals(end)
    assert after["r_hip_pitch"] < before["r_hip_pitch"] - 0.3  # the right leg swings forward
    assert after["l_hip_pitch"] == pytest.approx(before["l_hip_pitch"], abs=1e-9)
    with pytest.raises(SimConfigError, match="reach"):
        KickParameters(reach=1.0).check()
    with pytest.raises(SimConfigError, match="side"):
        KickMotion("middle")


def test_the_joint_swing_winds_the_leg_up_then_flexes_the_hip_and_extends_the_knee_at_once(
        ) -> None:
    p = KickParameters()
    assert p.swing == "joint"
    motion = KickMotion("left", p)
    start, end = motion.swing
    wound, swung = motion.goals(start), motion.goals(end)
    assert (wound["l_hip_pitch"], wound["l_knee"], wound["l_ankle_pitch"]) == pytest.approx(
        (p.windup_hip_pitch, p.windup_knee, p.windup_ankle_pitch))
    assert (swung["l_hip_pitch"], swung["l_knee"], swung["l_ankle_pitch"]) == pytest.approx(
        (p.swing_hip_pitch, p.swing_knee, p.swing_ankle_pitch))
    # Half way through the swing both joints are on their way: their speeds add at the foot.
    half = motion.goals((start + end) / 2)
    assert p.swing_hip_pitch < half["l_hip_pitch"] < p.windup_hip_pitch - 0.5
    assert p.swing_knee < half["l_knee"] < p.windup_knee - 0.5
    # The support leg does what it does in the spline kick; start and end are the stance.
    spline = KickMotion("left", replace(p, swing="spline"))
    for t in (start, (start + end) / 2, end):
        assert motion.goals(t)["r_knee"] == spline.goals(t)["r_knee"]
    assert motion.goals(0.0) == pytest.approx(STANCE)
    assert motion.goals(motion.duration) == pytest.approx(STANCE)
    with pytest.raises(SimConfigError, match="swing"):
        replace(p, swing="sideways").check()
    with pytest.raises(SimConfigError, match="windup_knee"):
        replace(p, windup_knee=3.0).check()  # beyond the knee's range


def test_kick_parameters_out_of_range_or_reach_are_refused() -> None:
    node, kick = _kick_node()
    node.set_parameter("swing_s", 0.25)
    assert kick.p.swing_s == 0.25
    with pytest.raises(ParameterError, match="reach"):
        node.set_parameter("reach", 0.19)  # in range, but no leg reaches that far
    with pytest.raises(ParameterError, match="shift_y"):
        node.set_parameter("shift_y", 0.5)
    assert kick.p.reach == KickParameters().reach and kick.p.shift_y == KickParameters().shift_y
    with pytest.raises(SimConfigError, match="reach"):
        Kick(TestHandle("kick", parameters={"reach": 0.19}))
