"""Issue 19, point 9: a striker alone scores within a bounded time from kick-off in most
seeds.

One robot against nobody (the match's ``1v0``), the ball on the centre mark as at a
kick-off, the robot where the match's seed puts it before ``ready`` (:func:`humanoid_sim.
match.start_poses`: anywhere in its own half, facing anywhere). It must walk to the ball
and kick it, again and again, until the ball is in the goal: the whole robot in the
simulated world (servo driver on the emulated bus, camera, ball detection and model, head
behaviour, striker, walk, kick, get-up, motion arbiter), judged by the one-robot referee
from ground truth, which the robot's software never sees.

Why one process on a manual clock (lockstep) and not the match command: with nobody else
on the field the match's processes add nothing to what is asserted (its referee's states
and team link are the other SIL tests' concern, tests/test_match_lockstep_sil.py), and
here the run is a function of the seed, at whatever load, at a fraction of the cost (no
barrier across processes, no DDS). Each run stops at its first goal, and the camera runs
at 10 Hz (the match's tests run theirs at 5 to 10): seed 1 scored at 76.3 s simulated with
30 Hz and at 76.6 s with 10 Hz, for 77 and 50 s of CPU.

The bound: seeds 1, 2 and 3 scored after 76.3, 75.2 and 75.6 simulated seconds (each
with six kicks, walking from its half's far side to the centre mark first, no fall; at
30 Hz, 1 % line noise); a kick cycle (walk behind the ball, line up, kick) takes about
12 s, so :data:`BOUND_S` allows one more cycle than the slowest took. Since the camera
renders without multisampling (models/field.xml, 2026-11-27) the seeds score after 76.7,
75.9 and 76.2 s, six kicks each, for 27 to 33 s of CPU a seed beside other tests (about 50
before). Slow for a test because scoring from the centre mark takes six kicks; there is no
shorter span that still shows it. The third seed runs only when the first two disagree.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import pytest

from efficient_comm.testing import test_container
from humanoid_sim.match import start_poses
from humanoid_sim.soccer.compose import compose

SEEDS = (1, 2, 3)
#: Simulated seconds from kick-off to the first goal that a seed may take (the module
#: docstring says how it was chosen).
BOUND_S = 90.0
#: Seeds of :data:`SEEDS` that must score within :data:`BOUND_S` ("most").
MOST = 2


@dataclass(frozen=True)
class Run:
    seed: int
    goal_s: float  # simulated s to the first goal, nan: none within the bound
    own_goals: int
    kicks: int
    falls: int


def play(seed: int) -> Run:
    """The robot from the seed's start, the ball on the centre mark, until its first goal
    or :data:`BOUND_S`."""
    poses, _ = start_poses(["blue1"], seed)
    with test_container(guard_mutation=False) as container:
        robot = compose(container, simulator={"robot_pose": list(poses["blue1"]),
                                              "ball_position": [0.0, 0.0], "seed": seed,
                                              "camera_hz": 10.0})
        while robot.simulator.sim_time_s < BOUND_S and not (
                robot.referee.goals or robot.referee.own_goals):
            container.advance(0.5)
        goal = robot.referee.goal_at_ns[0] / 1e9 if robot.referee.goals else math.nan
        return Run(seed=seed, goal_s=goal, own_goals=robot.referee.own_goals,
                   kicks=robot.monitor.kicks, falls=robot.fall_detector.falls)


@pytest.mark.timeout(2400)  # three runs of up to 90 simulated s; 21 min at load 12 to 31
def test_a_striker_alone_scores_within_a_bounded_time_from_kick_off_in_most_seeds() -> None:
    runs: list[Run] = []
    for seed in SEEDS:  # until the outcome is decided: the third seed only if it decides
        runs.append(play(seed))
        scored = [run for run in runs if run.goal_s <= BOUND_S]
        if len(scored) >= MOST or len(runs) - len(scored) > len(SEEDS) - MOST:
            break
    assert len(scored) >= MOST, runs
    # Scored by walking to the ball and kicking it into the opponent's goal: kicks, and no
    # own goal on the way.
    assert all(run.kicks >= 1 and run.own_goals == 0 for run in scored), runs
