"""Software in the loop: the robot falls, the fall detector reports it, the robot gets up.

Lockstep on a manual clock: simulator, servo driver (dynamixel-sdk on the pty), fall
detector, walk engine and get-up component in one test container with the mutation guard
raising; the get-up's commands go to ``joint_commands`` (no arbiter needed: the walk is
silent while the robot is down, the get-up while it stands). The robot is laid on its front
or back, or shoved over from behind or from the front; it must stand again, as the fall
detector judges it, within 5 s. The statistic over many seeds is bench/getup_bench.py's.
"""

from __future__ import annotations

import math

import pytest

from efficient_comm.testing import test_container
from humanoid_sim.soccer.getup_rig import GetUpResult, getup_trial, standing_torso_height
from humanoid_sim.soccer.walk_rig import WalkResult, compose_walker, walk_trial

#: Issue 13: standing again within this many simulated seconds.
STAND_WITHIN_S = 5.0
#: A shove that fells the standing robot (it stands 10 N, falls from 20 N; 0.1 s).
SHOVE_N = 45.0


def _trial(*, side: str | None = None, push_n: tuple[float, float, float] | None = None,
           seed: int = 0, line_noise: float = 0.0, guard: bool = True,
           walk_after: tuple[float, float, float] | None = None
           ) -> tuple[GetUpResult, WalkResult | None, float]:
    walked = None
    with test_container(guard_mutation="raise" if guard else False) as container:
        robot = compose_walker(container, simulator={"seed": seed, "line_noise": line_noise},
                               getup={})
        result = getup_trial(container, robot, side=side, push_n=push_n, timeout_s=8.0)
        if walk_after is not None and result.stood_at_s is not None:
            walked = walk_trial(container, robot, walk_after, seconds=2.5, settle_s=0.2,
                                warmup_s=1.0)
        assert robot.driver.status()["present"] == list(range(1, 21))
        assert not robot.simulator.pty.errors
        assert sum(s.exceptions for s in container.stats()) == 0
        height = standing_torso_height(robot)
    return result, walked, height


def _assert_stood(result: GetUpResult, height: float) -> None:
    assert result.fallen_at_s is not None, result.states
    assert result.stood_at_s is not None, (result.states, result.height_m, result.tilt_deg)
    assert result.states[-1] == "standing"
    assert result.successes == 1
    assert abs(result.height_m - height) < 0.04, (result.height_m, height)
    assert result.tilt_deg < 12.0


@pytest.mark.timeout(240)
@pytest.mark.parametrize("side", ["front", "back"])
def test_gets_up_from_the_front_and_the_back_within_5_s(side: str) -> None:
    result, _, height = _trial(side=side)
    assert result.side == side
    _assert_stood(result, height)
    assert result.stood_at_s is not None and result.stood_at_s <= STAND_WITHIN_S
    assert result.attempts == 1


@pytest.mark.timeout(300)
@pytest.mark.parametrize(("direction", "side"), [(1.0, "front"), (-1.0, "back")])
def test_a_shoved_robot_falls_is_reported_gets_up_and_walks_on(direction: float,
                                                               side: str) -> None:
    # Shoved from behind it falls on its front, from the front on its back.
    result, walked, height = _trial(push_n=(direction * SHOVE_N, 0.0, 0.0), seed=1,
                                    walk_after=(0.15, 0.0, 0.0))
    assert result.states[:3] == ["standing", "falling", "fallen"], result.states
    assert result.side == side
    _assert_stood(result, height)
    assert result.stood_at_s is not None and result.fallen_at_s is not None
    assert result.stood_at_s - result.fallen_at_s <= STAND_WITHIN_S
    assert walked is not None and not walked.fell, walked
    assert walked.vx > 0.08, walked.vx


@pytest.mark.timeout(300)
def test_same_seed_same_fall_and_get_up_another_seed_another() -> None:
    def run(seed: int) -> GetUpResult:
        result, _, _ = _trial(push_n=(SHOVE_N * math.cos(0.3), SHOVE_N * math.sin(0.3), 0.0),
                              seed=seed, line_noise=0.03, guard=False)
        return result  # (the guard's checks run in the tests above)

    first, again, other = run(3), run(3), run(4)
    assert first.stood_at_s is not None
    assert first.path == again.path and first.states == again.states
    assert other.path != first.path
