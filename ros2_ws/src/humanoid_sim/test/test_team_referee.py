"""The team referee on a TestHandle: ground truth injected, game states, scores, set plays,
placements and the broadcast read back from what it published."""

from __future__ import annotations

import math
from typing import Any

import pytest
from geometry_msgs.msg import PoseStamped

from efficient_comm import latched_qos
from efficient_comm.testing import TestHandle
from humanoid_sim.errors import SimConfigError
from humanoid_sim.soccer.laws import (
    Crossing,
    Line,
    Player,
    judge_ball,
    kickoff_pose,
    legal_at_kickoff,
    parse_robot,
)
from humanoid_sim.soccer.team_referee import TeamReferee
from soccer_interfaces.msg import GameState

BLUE, RED = 1, 2  # the default team numbers
INITIAL, READY, SET, PLAYING, FINISHED = (
    GameState.STATE_INITIAL, GameState.STATE_READY, GameState.STATE_SET,
    GameState.STATE_PLAYING, GameState.STATE_FINISHED)
GAME = {"robots": ["blue1", "red1"], "half_s": 60.0, "initial_s": 1.0, "ready_s": 5.0,
        "settle_s": 0.0, "set_s": 1.0, "half_time_s": 2.0, "kickoff_free_s": 10.0,
        "restart_s": 1.0, "free_kick_s": 30.0}


def _pose(x: float, y: float, z: float = 0.0) -> PoseStamped:
    pose = PoseStamped()
    pose.pose.position.x, pose.pose.position.y, pose.pose.position.z = x, y, z
    return pose


def _game(**parameters: Any) -> tuple[TestHandle, TeamReferee]:
    node = TestHandle("referee", parameters={**GAME, **parameters})
    return node, TeamReferee(node)


def _now(node: TestHandle) -> GameState:
    state: GameState = node.published("game_state")[-1]
    return state


def _to_playing(node: TestHandle) -> None:
    """From initial (or ready) through ready and set into playing, both robots legal."""
    node.inject("ground_truth/blue1/pose", _pose(-1.0, 0.0))
    node.inject("ground_truth/red1/pose", _pose(1.2, 0.0))
    for _ in range(200):
        if _now(node).game_state == PLAYING:
            return
        node.advance(0.1)
    raise AssertionError(f"never playing: {_now(node)}")


def test_the_laws_judge_the_ball_and_the_kickoff_positions() -> None:
    assert judge_ball(4.5, 0.0, 0.07) is None  # on the line
    assert judge_ball(4.6, 1.2, 0.07) == Crossing(Line.GOAL, 1.0, 1.0)
    assert judge_ball(4.6, 1.4, 0.07) == Crossing(Line.GOAL_LINE, 1.0, 1.0)
    assert judge_ball(-4.6, 0.0, 1.5) == Crossing(Line.GOAL_LINE, -1.0, 1.0)  # over the bar
    assert judge_ball(1.0, -3.1, 0.07) == Crossing(Line.TOUCH_LINE, 1.0, -1.0)
    assert parse_robot("red3") == Player("red", 3)
    for bad in ("green1", "blue0", "blue4", "blue", "Blue1"):
        with pytest.raises(SimConfigError, match="<team><number>"):
            parse_robot(bad)
    # Blue defends -x in the first half and +x in the second, facing the other way.
    x, y, heading = kickoff_pose(Player("blue", 1), first_half=True, kicking=True)
    assert x < 0 and math.hypot(x, y) < 0.75 and heading == 0.0
    x, y, heading = kickoff_pose(Player("blue", 1), first_half=False, kicking=False)
    assert x > 0.75 and heading == pytest.approx(math.pi)
    for number in (1, 2, 3):
        for first_half in (True, False):
            for kicking in (True, False):
                for team in ("blue", "red"):
                    x, y, _ = kickoff_pose(Player(team, number), first_half=first_half,
                                           kicking=kicking)
                    assert legal_at_kickoff(team, x, y, first_half=first_half, kicking=kicking)
                    assert not legal_at_kickoff(team, -x, -y, first_half=first_half,
                                                kicking=kicking)
    assert not legal_at_kickoff("red", 0.3, 0.0, first_half=True, kicking=False)  # circle
    assert legal_at_kickoff("red", 0.3, 0.0, first_half=True, kicking=True)
    assert not legal_at_kickoff("red", 4.7, 0.0, first_half=True, kicking=True)  # outside


def test_a_game_goes_through_the_states_with_its_clock_and_changes_ends_at_half_time() -> None:
    node, referee = _game()
    first = _now(node)
    assert (first.game_state, first.first_half, first.kicking_team) == (INITIAL, True, BLUE)
    assert first.seconds_remaining == 60 and first.packet_number == 0
    assert [(t.team_number, t.team_colour, t.score) for t in first.teams] == [
        (BLUE, 0, 0), (RED, 1, 0)]
    node.advance(1.0)
    assert _now(node).game_state == READY
    assert _now(node).secondary_seconds_remaining == 5  # the ready time left
    node.advance(5.0)
    assert _now(node).game_state == SET
    node.advance(1.0)
    playing = _now(node)
    assert playing.game_state == PLAYING and playing.seconds_remaining == 54  # ready and set count
    assert playing.secondary_seconds_remaining == 10  # the kick-off's ball is not free yet
    node.advance(10.0)
    assert _now(node).secondary_seconds_remaining == 0  # free after 10 s
    node.advance(43.9)
    assert _now(node).game_state == PLAYING and _now(node).seconds_remaining == 1
    node.advance(0.2)
    half_time = _now(node)
    assert (half_time.game_state, half_time.seconds_remaining) == (FINISHED, 0)
    node.advance(2.0)
    second = _now(node)
    # The second half: the other team kicks off, the ends are changed, the clock is full.
    assert (second.game_state, second.first_half, second.kicking_team) == (INITIAL, False, RED)
    assert second.seconds_remaining == 60
    node.advance(1.0)
    assert _now(node).game_state == READY
    node.advance(70.0)
    assert _now(node).game_state == FINISHED and referee.state == FINISHED
    node.advance(30.0)
    assert _now(node).game_state == FINISHED and not _now(node).first_half  # over


def test_goals_for_either_team_count_and_the_team_that_conceded_kicks_off() -> None:
    node, referee = _game()
    _to_playing(node)
    assert _now(node).kicking_team == BLUE
    node.inject("ground_truth/ball", _pose(0.5, 0.0, 0.07))  # kicked off
    node.inject("ground_truth/ball", _pose(4.6, 0.5, 0.07))  # blue scores at +x
    goal = _now(node)
    assert goal.game_state == READY and goal.kicking_team == RED
    assert [t.score for t in goal.teams] == [1, 0]
    placed = len(node.published("place_ball"))
    node.inject("ground_truth/ball", _pose(4.8, 0.5, 0.07))  # still in the goal: once
    assert referee.score == {"blue": 1, "red": 0}
    node.advance(0.9)
    assert len(node.published("place_ball")) == placed
    node.advance(0.1)  # a moment for everyone to see it, then back on the centre mark
    (centre,) = node.published("place_ball")[placed:]
    assert (centre.x, centre.y) == (0.0, 0.0)
    node.inject("ground_truth/ball", _pose(0.0, 0.0, 0.07))
    _to_playing(node)
    assert _now(node).kicking_team == RED
    node.inject("ground_truth/ball", _pose(-4.6, -1.0, 0.07))  # red scores at -x
    assert [t.score for t in _now(node).teams] == [1, 1] and _now(node).kicking_team == BLUE
    assert [team for _, team in referee.goals] == ["blue", "red"]
    node.inject("ground_truth/ball", _pose(-4.6, 2.0, 0.07))  # not judged outside playing
    assert referee.set_plays == []
    # The second half: blue attacks -x.
    while _now(node).game_state != FINISHED:
        node.advance(0.5)
    assert _now(node).first_half and referee.seconds_remaining() <= 0
    node.advance(2.0)
    node.inject("ground_truth/ball", _pose(0.0, 0.0, 0.07))
    _to_playing(node)
    node.inject("ground_truth/ball", _pose(-4.6, 0.0, 0.07))
    assert [t.score for t in _now(node).teams] == [2, 1] and _now(node).kicking_team == RED


def test_a_ball_out_restarts_with_the_set_play_for_the_other_team_on_its_spot() -> None:
    node, referee = _game()
    _to_playing(node)
    # Blue touched it last, out over the touch line: red's throw-in where it left.
    node.inject("ground_truth/blue1/pose", _pose(2.0, 2.7))
    node.inject("ground_truth/ball", _pose(2.0, 2.9, 0.07))
    node.inject("ground_truth/ball", _pose(2.2, 3.1, 0.07))
    throw_in = _now(node)
    assert throw_in.game_state == PLAYING
    assert throw_in.secondary_state == GameState.STATE2_THROW_IN
    assert list(throw_in.secondary_state_info) == [RED, 0, 0, 0]
    assert throw_in.kicking_team == RED
    node.advance(1.0)
    spot = node.published("place_ball")[-1]
    assert (spot.x, spot.y) == pytest.approx((2.2, 3.0))
    node.inject("ground_truth/ball", _pose(2.2, 3.0, 0.07))
    node.advance(1.0)
    assert _now(node).secondary_state == GameState.STATE2_THROW_IN  # not yet played
    node.inject("ground_truth/blue1/pose", _pose(-1.0, 0.0))
    node.inject("ground_truth/red1/pose", _pose(2.2, 2.8))
    node.inject("ground_truth/ball", _pose(2.1, 2.6, 0.07))  # red plays it
    node.advance(0.1)
    assert _now(node).secondary_state == GameState.STATE2_NORMAL
    # Red, defending +x, last touched it over its own goal line: blue's corner kick.
    node.inject("ground_truth/ball", _pose(4.6, -2.0, 0.07))
    corner = _now(node)
    assert corner.secondary_state == GameState.STATE2_CORNER_KICK
    assert corner.secondary_state_info[0] == BLUE and corner.kicking_team == BLUE
    node.advance(1.0)
    spot = node.published("place_ball")[-1]
    assert (spot.x, spot.y) == pytest.approx((4.5, -3.0))
    node.advance(30.0)  # not played within free_kick_s: the set play is over
    assert _now(node).secondary_state == GameState.STATE2_NORMAL
    # Blue, attacking +x, last touched it over the goal line: red's goal kick.
    node.inject("ground_truth/blue1/pose", _pose(4.2, 2.0))
    node.inject("ground_truth/ball", _pose(4.4, 2.0, 0.07))
    node.inject("ground_truth/ball", _pose(4.6, 2.0, 0.07))
    assert _now(node).secondary_state == GameState.STATE2_GOAL_KICK
    assert _now(node).kicking_team == RED
    node.advance(1.0)
    spot = node.published("place_ball")[-1]
    assert (spot.x, spot.y) == pytest.approx((3.5, 1.5))
    assert [(p.team, p.kind) for p in referee.set_plays] == [
        ("red", GameState.STATE2_THROW_IN), ("blue", GameState.STATE2_CORNER_KICK),
        ("red", GameState.STATE2_GOAL_KICK)]


def test_robots_in_illegal_positions_at_the_end_of_ready_are_placed_for_the_kickoff() -> None:
    node, referee = _game(robots=["blue1", "blue2", "red1", "red3"])
    node.inject("ground_truth/blue1/pose", _pose(-0.3, 0.0))  # kicking: may be in the circle
    node.inject("ground_truth/blue2/pose", _pose(1.0, 1.0))  # in the opponent half
    node.inject("ground_truth/red1/pose", _pose(0.4, 0.0))  # in the circle without kick-off
    node.inject("ground_truth/red3/pose", _pose(3.0, -3.5))  # outside the field
    node.advance(1.0)
    node.advance(4.9)
    assert _now(node).game_state == READY and node.published("place_robot") == []
    node.advance(0.1)
    assert _now(node).game_state == SET
    placed = {p.header.frame_id: p for p in node.published("place_robot")}
    assert sorted(placed) == ["blue2", "red1", "red3"]
    for name, pose in placed.items():
        player = parse_robot(name)
        x, y, heading = kickoff_pose(player, first_half=True, kicking=player.team == "blue")
        q = pose.pose.orientation
        assert (pose.pose.position.x, pose.pose.position.y) == pytest.approx((x, y))
        assert 2 * math.atan2(q.z, q.w) == pytest.approx(heading)
        assert legal_at_kickoff(player.team, x, y, first_half=True,
                                kicking=player.team == "blue")
    assert [name for _, name in referee.placements] == ["blue2", "red1", "red3"]
    assert (node.published("place_ball")[-1].x, node.published("place_ball")[-1].y) == (0, 0)


def test_ready_ends_early_once_every_robot_stands_legally_for_settle_s() -> None:
    node, _ = _game(ready_s=45.0, settle_s=2.0)
    node.inject("ground_truth/blue1/pose", _pose(-2.0, 0.0))
    node.inject("ground_truth/red1/pose", _pose(0.5, 0.0))  # in the circle
    node.advance(1.0)
    assert _now(node).game_state == READY
    for step in range(24):  # red walks out of the circle, 0.1 m a step, until t = 1.5 s
        node.inject("ground_truth/blue1/pose", _pose(-2.0, 0.0))
        node.inject("ground_truth/red1/pose", _pose(0.5 + 0.1 * min(step, 5), 0.0))
        node.advance(0.1)
    assert _now(node).game_state == READY  # t = 3.4 s: red has stood for 1.9 s
    node.advance(0.1)
    assert _now(node).game_state == SET
    assert node.published("place_robot") == []


def test_the_state_is_latched_and_broadcast_at_its_rate_and_on_every_change() -> None:
    node, _ = _game(initial_s=10.0, rate_hz=2.0)
    node.advance(5.0)
    sent = node.published("game_state")
    assert len(sent) == 11  # at start, then every 0.5 s
    assert [s.packet_number for s in sent] == list(range(11))
    node.advance(5.0)  # the change to ready is sent at once
    assert node.published("game_state")[-1].game_state == READY
    late: list[GameState] = []
    node.create_subscription(GameState, "game_state", late.append, qos=latched_qos())
    node.spin_some()
    assert [s.game_state for s in late] == [READY]  # a late subscriber gets the last one


@pytest.mark.parametrize(("parameter", "value"), [
    ("robots", ["blue1", "blue1"]), ("robots", ["green2"]), ("half_s", 0.0),
    ("ready_s", -1.0), ("halves", 3), ("first_kickoff", "yellow"),
    ("red_team_number", 1)])
def test_bad_parameters_are_refused_with_their_name(parameter: str, value: Any) -> None:
    with pytest.raises(SimConfigError):
        _game(**{parameter: value})
