"""The get-up component alone on a TestHandle: its states, topics and counts from exact inputs.

Whether the motions stand the robot up is physics: tests/test_getup_sil.py and
bench/getup_bench.py run them through the driver on the simulated robot.
"""

from __future__ import annotations

import itertools
import math

import pytest
from geometry_msgs.msg import Quaternion
from sensor_msgs.msg import Imu, JointState
from std_msgs.msg import String

from efficient_comm import to_msg
from efficient_comm.testing import TestHandle
from humanoid_sim.errors import SimConfigError
from humanoid_sim.soccer.getup import (
    BACK_GETUP,
    FRONT_GETUP,
    GetUp,
    Keyframe,
    Trajectory,
    lying_on,
)
from humanoid_sim.soccer.motion import STANCE


def _lying(stamp_s: float, pitch_deg: float, *, heading_deg: float = 0.0,
           rate: float = 0.0) -> Imu:
    """The torso turned to ``heading_deg``, then pitched by ``pitch_deg`` (+90: face down)."""
    h, p = math.radians(heading_deg) / 2, math.radians(pitch_deg) / 2
    imu = Imu()  # q = yaw(h) * pitch(p)
    imu.orientation = Quaternion(w=math.cos(h) * math.cos(p), x=-math.sin(h) * math.sin(p),
                                 y=math.cos(h) * math.sin(p), z=math.sin(h) * math.cos(p))
    imu.angular_velocity.x = rate
    imu.header.stamp = to_msg(round(stamp_s * 1e9))
    return imu


@pytest.mark.parametrize("heading", [0.0, 100.0, -170.0])
def test_tells_front_from_back_whatever_the_heading(heading: float) -> None:
    assert lying_on(_lying(0.0, 90.0, heading_deg=heading)) == "front"
    assert lying_on(_lying(0.0, 70.0, heading_deg=heading)) == "front"
    assert lying_on(_lying(0.0, -90.0, heading_deg=heading)) == "back"
    assert lying_on(_lying(0.0, -110.0, heading_deg=heading)) == "back"


def test_trajectory_joins_the_keyframes_smoothly_and_ends_in_the_crouch() -> None:
    start = {name: 0.3 for name in STANCE}
    for motion in (FRONT_GETUP, BACK_GETUP):
        path = Trajectory(start, motion)
        assert path.at(0.0) == start
        assert path.at(path.duration_s) == pytest.approx(STANCE)
        assert path.at(path.duration_s + 5.0) == pytest.approx(STANCE)
        # No jumps: halving the control period halves the largest step between goals
        # (a jump would stay the same size).
        def largest_step(period: float, path: Trajectory = path) -> float:
            goals = [path.at(k * period) for k in range(round(path.duration_s / period) + 1)]
            return max(abs(b[n] - a[n]) for a, b in itertools.pairwise(goals) for n in a)

        assert largest_step(0.005) < 0.55 * largest_step(0.01)
    with pytest.raises(SimConfigError):
        Trajectory(start, [Keyframe(0.0, STANCE)])


def _states(node: TestHandle) -> list[bool]:
    return [m.data for m in node.published("motion/getup/active")]


def _imu_for(node: TestHandle, seconds: float, pitch_deg: float, rate: float = 0.0) -> None:
    """IMU messages every 10 ms while the clock advances (the timer runs in between)."""
    for _ in range(round(seconds / 0.01)):
        node.inject("imu/data", _lying(node.now_ns() / 1e9, pitch_deg, rate=rate))
        node.advance(0.01)


def _posture(node: TestHandle, state: str) -> None:
    node.inject("fall/state", String(data=state))


def test_relaxes_while_falling_then_gets_up_from_the_side_it_lies_on() -> None:
    node = TestHandle("getup", parameters={"rest_s": 0.2, "confirm_s": 1.0})
    getup = GetUp(node)
    node.advance(0.1)
    assert _states(node) == [False] and not node.published("motion/getup")
    _posture(node, "falling")
    assert _states(node) == [False, True]
    bent = dict(STANCE) | {"l_knee": 1.1, "neck_yaw": 0.4}
    node.inject("joint_states", JointState(name=list(bent), position=list(bent.values())))
    node.advance(0.02)
    relaxed = node.published("motion/getup")[-1]
    assert dict(zip(relaxed.name, relaxed.position, strict=True)) == bent  # goals follow
    _posture(node, "fallen")
    _imu_for(node, 0.5, -90.0, rate=2.0)  # still rolling: no get-up yet
    assert getup.phase == "wait" and getup.attempts == 0
    _imu_for(node, 0.3, -90.0)  # at rest on the back for rest_s
    assert getup.phase == "play" and getup.side == "back" and getup.attempts == 1
    first = node.published("motion/getup")[-1]
    assert set(first.name) == set(STANCE)  # every joint, the neck included
    _imu_for(node, 12.0, -90.0)  # the motion plays, then the crouch is held
    assert getup.phase in ("confirm", "wait", "play")
    node.clear_published()
    _posture(node, "standing")
    assert getup.phase == "idle" and getup.successes == 1
    assert _states(node) == [False]
    assert len(getup.durations_s) == 1 and 12.0 < getup.durations_s[0] < 14.0
    node.advance(0.5)
    assert not node.published("motion/getup")  # standing: silent


def test_tries_again_while_still_lying_and_gives_up_after_max_attempts() -> None:
    node = TestHandle("getup", parameters={"rest_s": 0.1, "confirm_s": 0.5,
                                           "max_attempts": 2})
    getup = GetUp(node)
    _posture(node, "fallen")  # laid down: fallen without falling first
    assert _states(node) == [False, True]
    _imu_for(node, 0.2, 90.0)
    assert getup.side == "front" and getup.attempts == 1
    _imu_for(node, FRONT_GETUP_S + 0.7, 90.0)  # played, held, still lying: try again
    assert getup.attempts == 2 and getup.phase == "play"
    _imu_for(node, FRONT_GETUP_S + 0.7, 90.0)
    assert getup.phase == "gave_up" and getup.successes == 0
    assert _states(node)[-1] is False
    assert any("giving up" in message for _, message in node.records)


FRONT_GETUP_S = sum(k.duration_s for k in FRONT_GETUP)


@pytest.mark.parametrize("parameters", [
    {"protect": "flail"}, {"rest_rate": 0.0}, {"max_attempts": -1}, {"rate_hz": 0.5}])
def test_refuses_bad_parameters_with_their_names(parameters: dict[str, object]) -> None:
    with pytest.raises(SimConfigError, match=next(iter(parameters))):
        GetUp(TestHandle("getup", parameters=parameters))
