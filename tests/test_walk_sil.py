"""Software in the loop: the walk engine drives the real servo driver on the emulated bus.

Lockstep on a manual clock: simulator, servo driver (dynamixel-sdk on the pty), fall
detector and walk engine in one test container with the mutation guard raising; the walk
engine's commands go to ``joint_commands`` (no arbiter needed). Each direction walks a few
seconds from standing; the velocity is measured against the simulator's ground truth after
the start. The long statistic (60 s, many seeds) is bench/walk_bench.py's.
"""

from __future__ import annotations

import pytest

from efficient_comm.testing import test_container
from humanoid_sim.soccer.walk_rig import WalkResult, compose_walker, walk_trial

#: Achieved velocity along the commanded axis, as a share of the command: the steps are
#: open loop, so the feet slip a little (bench/walk_bench.py measures 0.85 to 0.9).
TOLERANCE = (0.65, 1.15)
#: Velocity across the commanded axis that still counts as going straight.
DRIFT_M_S, DRIFT_RAD_S = 0.04, 0.15


def _walk(command: tuple[float, float, float], *, seconds: float = 4.5, seed: int = 0,
          line_noise: float = 0.0, settle_s: float = 1.0, warmup_s: float = 2.0,
          guard: bool = True) -> WalkResult:
    with test_container(guard_mutation="raise" if guard else False) as container:
        robot = compose_walker(container, simulator={"seed": seed, "line_noise": line_noise})
        result = walk_trial(container, robot, command, seconds=seconds, settle_s=settle_s,
                            warmup_s=warmup_s)
        assert robot.driver.status()["present"] == list(range(1, 21))
        assert not robot.simulator.pty.errors
        assert sum(s.exceptions for s in container.stats()) == 0
    return result


@pytest.mark.timeout(120)
@pytest.mark.parametrize(("command", "axis"), [
    ((0.25, 0.0, 0.0), 0), ((-0.15, 0.0, 0.0), 0), ((0.0, 0.1, 0.0), 1),
    ((0.0, -0.1, 0.0), 1), ((0.0, 0.0, 0.7), 2), ((0.0, 0.0, -0.7), 2)])
def test_walks_each_direction_at_the_commanded_velocity(
        command: tuple[float, float, float], axis: int) -> None:
    result = _walk(command)
    assert not result.fell, f"fell at {result.fell_at_s} s"
    achieved = (result.vx, result.vy, result.wz)
    low, high = TOLERANCE
    assert low <= achieved[axis] / command[axis] <= high, achieved
    for other in range(3):
        if other != axis:
            limit = DRIFT_RAD_S if other == 2 else DRIFT_M_S
            assert abs(achieved[other]) < limit, achieved
    # Odometry from the commanded steps follows the truth within the slip.
    assert result.odom_drift_m < 0.35 * max(0.3, abs(command[0]) * result.seconds)


@pytest.mark.timeout(120)
def test_same_seed_same_walk_another_seed_another() -> None:
    def walk(seed: int) -> WalkResult:
        return _walk((0.2, 0.0, 0.3), seconds=1.0, seed=seed, line_noise=0.03, settle_s=0.4,
                     warmup_s=0.0, guard=False)  # (the guard's checks run in the tests above)

    first, again, other = walk(3), walk(3), walk(4)
    assert first.path == again.path and first.peak_torque == again.peak_torque
    assert other.path != first.path
