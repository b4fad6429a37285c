"""Software in the loop: a whole robot obeys the team referee's game states.

The demo's robot (simulator, real servo driver on the emulated bus, vision, striker, walk,
kick, get-up, arbiter) runs composed on a manual clock with the team referee beside it, as
``blue1``: the referee reads the simulator's ground truth and broadcasts ``game_state``;
the robot reads only that. Ground truth judges what the robot did: in ``ready`` it walks
towards its kick-off spot, in ``set`` it stands still, in ``playing`` it plays.
"""

from __future__ import annotations

import math

import pytest

from efficient_comm.testing import test_container
from humanoid_sim.soccer.compose import compose
from humanoid_sim.soccer.laws import Player, kickoff_pose
from humanoid_sim.soccer.team_referee import TeamReferee
from soccer_interfaces.msg import GameState

START = [-2.0, 1.0, 0.0]
SPOT = kickoff_pose(Player("blue", 1), first_half=True, kicking=True)
#: Ready for 12 s (the striker first stands 2 s while its servos settle), set for 3 s.
GAME = {"robots": ["blue1"], "initial_s": 1.0, "ready_s": 12.0, "settle_s": 0.0,
        "set_s": 3.0, "half_s": 600.0}


@pytest.mark.timeout(600)  # about 18 simulated seconds, whole robot
def test_a_robot_walks_to_its_kickoff_spot_in_ready_stands_in_set_and_plays() -> None:
    with test_container(guard_mutation=False) as container:
        robot = compose(container, simulator={"robot_pose": START, "ball_position": [1.0, -1.5],
                                              "seed": 3},
                        striker={"robot": "blue1"})
        referee: TeamReferee = container.add(
            TeamReferee, name="team_referee", namespace="/robot", parameters=GAME,
            remappings={"/robot/ground_truth/blue1/pose": "/robot/ground_truth/robot"})
        striker = robot.striker
        assert striker is not None

        def torso() -> tuple[float, float]:
            body = robot.simulator.data.xpos[robot.simulator.model.body("torso").id]
            return float(body[0]), float(body[1])

        seen: dict[int, list[tuple[float, tuple[float, float]]]] = {}
        states: list[str] = []
        while robot.simulator.sim_time_s < 18.0:
            container.advance(0.1)
            seen.setdefault(referee.state, []).append((robot.simulator.sim_time_s, torso()))
            if not states or states[-1] != striker.state:
                states.append(striker.state)
        assert robot.fall_detector.falls == 0, states

    ready = seen[GameState.STATE_READY]
    set_ = seen[GameState.STATE_SET]
    walked = math.dist(ready[0][1], SPOT[:2]) - math.dist(ready[-1][1], SPOT[:2])
    assert walked > 0.8, (ready[0], ready[-1], states)  # towards the spot
    # Set: after the last step of the stop (1 s), it stands where it is.
    still = [where for t, where in set_ if t >= set_[0][0] + 1.0]
    assert still and max(math.dist(still[0], w) for w in still) < 0.03, (set_, states)
    assert striker.state != "wait" and referee.state == GameState.STATE_PLAYING, states
    # Initial, ready, set (the referee's first broadcast reaches the striker at once), then
    # the game.
    assert states[:3] == ["wait", "position", "wait"], states
    assert states[3] in ("search", "approach"), states
