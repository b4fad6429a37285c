"""Software in the loop: the striker walks to a ball 2 m away and kicks it towards the goal.

The whole robot runs composed on a manual clock (lockstep), as in the demo: simulator,
real servo driver on the emulated bus, vision, ball model, head behaviour, striker, walk
engine, kick, get-up and the motion arbiter. Ground truth judges the result; the robot's
software never sees it. The same seed gives the same run, to the bit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import pytest

from efficient_comm.testing import test_container
from humanoid_sim.soccer.compose import compose
from humanoid_sim.soccer.referee import HALF_LENGTH

GOAL = (HALF_LENGTH, 0.0)
#: The robot 2 m from the ball, not facing the goal, the ball off its axis.
ROBOT_POSE = [-1.0, 0.5, 0.6]
BALL = [1.0, 0.5]
#: Kicked towards the goal: the ball ends at least this much closer to the goal's centre,
#: and its path leaves within this angle of the line from where it lay to the goal.
CLOSER_M = 0.3  # one kick rolls about 0.5 m on turf-like rolling friction
DIRECTION_DEG = 20.0
#: Time for walking there and kicking (simulated s); the run stops earlier once the ball
#: kicked has come to rest or left the field (a goal: the referee would put it back).
LIMIT_S = 40.0


@dataclass(frozen=True)
class Outcome:
    kicked_at_s: float
    ball_end: tuple[float, float]
    goals: int
    robot_end: tuple[float, float]
    falls: int
    kicks: int
    striker_states: tuple[str, ...]


def play(seed: int) -> Outcome:
    with test_container(guard_mutation=False) as container:
        robot = compose(container, simulator={"robot_pose": ROBOT_POSE, "ball_position": BALL,
                                              "seed": seed, "line_noise": 0.01})
        striker = robot.striker
        assert striker is not None  # compose() plays by default
        states: list[str] = []
        kicked_at: float | None = None
        rest: list[tuple[float, float]] = []
        while robot.simulator.sim_time_s < LIMIT_S:
            container.advance(0.1)
            if not states or states[-1] != striker.state:
                states.append(striker.state)
            if kicked_at is None and robot.monitor.kicks:
                kicked_at = robot.simulator.sim_time_s
            if kicked_at is not None:
                ball = robot.simulator.ball_position()
                rest.append((float(ball[0]), float(ball[1])))
                if robot.referee.goals or robot.referee.outs:
                    break  # over a line: where it is now is where it ends
                # At rest once the kick is over: moved less than 1 mm in the last 0.5 s.
                if (robot.monitor.motion != "kick" and len(rest) > 5
                        and math.dist(rest[-1], rest[-6]) < 1e-3):
                    break
        body = robot.simulator.data.xpos[robot.simulator.model.body("torso").id]
        return Outcome(
            kicked_at_s=kicked_at if kicked_at is not None else math.nan,
            ball_end=rest[-1] if rest else (math.nan, math.nan), goals=robot.referee.goals,
            robot_end=(float(body[0]), float(body[1])),
            falls=robot.fall_detector.falls, kicks=robot.monitor.kicks,
            striker_states=tuple(states))


@pytest.mark.timeout(600)  # two runs of about 20 simulated seconds each, whole robot
def test_a_robot_2m_from_the_ball_walks_to_it_and_kicks_it_towards_the_goal() -> None:
    first = play(seed=4)
    assert not math.isnan(first.kicked_at_s), f"no kick within {LIMIT_S} s: {first}"
    assert first.falls == 0, first
    assert first.striker_states[:2] == ("search", "approach") or (
        first.striker_states[0] == "approach"), first
    start_to_goal = math.dist(BALL, GOAL)
    end_to_goal = math.dist(first.ball_end, GOAL)
    assert start_to_goal - end_to_goal >= CLOSER_M, first
    wanted = math.atan2(GOAL[1] - BALL[1], GOAL[0] - BALL[0])
    went = math.atan2(first.ball_end[1] - BALL[1], first.ball_end[0] - BALL[0])
    assert abs(math.degrees(went - wanted)) < DIRECTION_DEG, first
    # It walked there: the robot ends near where the ball lay, not where it started.
    assert math.dist(first.robot_end, BALL) < 0.6, first

    assert play(seed=4) == first  # lockstep: the same seed, the same run
