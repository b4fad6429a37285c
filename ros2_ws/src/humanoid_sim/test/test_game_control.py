"""Robots obey the referee: the striker's walk commands under each game state (game_state
injected, or sent by the team referee in the same container)."""

from __future__ import annotations

import math

import pytest
from geometry_msgs.msg import PointStamped, PoseStamped, Quaternion, Twist
from sensor_msgs.msg import Imu

from efficient_comm.testing import TestHandle
from humanoid_sim.soccer.game_control import PLAY, POSITION, STAND, GameControl
from humanoid_sim.soccer.laws import Player, kickoff_pose
from humanoid_sim.soccer.striker import APPROACH, WAIT, Striker
from humanoid_sim.soccer.team_referee import TeamReferee
from soccer_interfaces.msg import GameState, PlayerInfo, TeamInfo

INITIAL, READY, SET, PLAYING, FINISHED = (
    GameState.STATE_INITIAL, GameState.STATE_READY, GameState.STATE_SET,
    GameState.STATE_PLAYING, GameState.STATE_FINISHED)


def _game_state(state: int, *, kicking: int = 1, first_half: bool = True,
                secondary_s: int = 0, penalised: int = 0) -> GameState:
    """Blue is team 1, red team 2, three players each; ``penalised``: blue's player."""
    msg = GameState(game_state=state, kicking_team=kicking, first_half=first_half,
                    secondary_seconds_remaining=secondary_s, players_per_team=3)
    msg.teams = [TeamInfo(team_number=number, team_colour=colour,
                          players=[PlayerInfo() for _ in range(3)])
                 for number, colour in ((1, TeamInfo.COLOUR_BLUE), (2, TeamInfo.COLOUR_RED))]
    if penalised:
        msg.teams[0].players[penalised - 1].penalty = PlayerInfo.PENALTY_PICKUP_OR_INCAPABLE
    return msg


def _striker(robot: str, start: list[float], **parameters: object) -> tuple[TestHandle, Striker]:
    node = TestHandle("striker", parameters={"robot": robot, "start_pose": start,
                                             "settle_s": 0.0, **parameters})
    striker = Striker(node)
    node.inject("imu/data", Imu(orientation=Quaternion(w=1.0)))
    return node, striker


def _cmd(node: TestHandle) -> tuple[float, float, float]:
    twist: Twist = node.published("cmd_vel")[-1]
    return twist.linear.x, twist.linear.y, twist.angular.z


def _ball(node: TestHandle, x: float, y: float) -> None:
    """The ball seen at x, y in the robot's frame."""
    position = PointStamped()
    position.point.x, position.point.y = x, y
    node.inject("ball/position", position)


def test_in_ready_it_walks_to_its_kickoff_spot_and_in_set_it_stands() -> None:
    node, striker = _striker("blue1", [-2.0, 1.0, 0.0])
    node.inject("game_state", _game_state(READY))
    node.advance(0.1)
    assert striker.state == "position"
    vx, vy, wz = _cmd(node)
    spot = kickoff_pose(Player("blue", 1), first_half=True, kicking=True)
    to_spot = striker.pose.to_local(spot[0], spot[1])  # (1.7, -1.0) ahead and right
    assert vx * to_spot[0] + vy * to_spot[1] > 0.05  # towards the spot
    assert wz < 0  # turning to face it
    node.inject("game_state", _game_state(SET))  # at once, not at the next decision
    assert _cmd(node) == (0.0, 0.0, 0.0) and striker.state == WAIT
    _ball(node, 0.5, 0.0)  # the ball in sight changes nothing
    node.advance(1.0)
    assert _cmd(node) == (0.0, 0.0, 0.0) and striker.state == WAIT
    node.inject("game_state", _game_state(PLAYING))
    _ball(node, 0.5, 0.0)
    node.advance(0.1)
    assert striker.state == APPROACH and _cmd(node)[0] > 0  # playing: to the ball
    node.inject("game_state", _game_state(FINISHED))
    assert _cmd(node) == (0.0, 0.0, 0.0) and striker.state == WAIT


def test_in_initial_and_when_penalised_it_never_walks() -> None:
    node, striker = _striker("blue2", [-2.0, 1.0, 0.0])
    node.inject("game_state", _game_state(INITIAL))
    _ball(node, 0.5, 0.0)
    node.advance(2.0)
    assert all(t.linear.x == t.linear.y == t.angular.z == 0.0
               for t in node.published("cmd_vel"))
    assert striker.state == WAIT
    node.inject("game_state", _game_state(PLAYING, penalised=2))
    _ball(node, 0.5, 0.0)
    node.advance(1.0)
    assert striker.state == WAIT and not any(t.linear.x for t in node.published("cmd_vel"))


def test_at_its_spot_it_stands_and_it_attacks_its_teams_goal_in_each_half() -> None:
    spot = kickoff_pose(Player("red", 2), first_half=True, kicking=False)
    node, striker = _striker("red2", list(spot))
    node.inject("game_state", _game_state(READY))
    node.advance(0.5)
    assert striker.state == WAIT and node.published("cmd_vel") == []  # there already
    assert striker.game.goal() == (-4.5, 0.0)  # red attacks -x in the first half
    _ball(node, 1.0, 0.0)  # ahead of the robot facing -x: at (0.5, -1.0)
    assert striker.target().heading == pytest.approx(math.atan2(1.0, -5.0))
    node.inject("game_state", _game_state(PLAYING, first_half=False))
    assert striker.game.goal() == (4.5, 0.0)  # the ends changed
    assert striker.target().heading == pytest.approx(math.atan2(1.0, 4.0))


def test_during_the_other_teams_kickoff_it_keeps_out_of_the_centre_circle() -> None:
    node, striker = _striker("red1", [0.3, 0.0, math.pi])  # inside the circle
    node.inject("game_state", _game_state(PLAYING, kicking=1, secondary_s=10))
    _ball(node, 0.3, 0.0)  # the ball on the centre mark, right ahead
    node.advance(0.1)
    assert striker.game.order(0.3, 0.0).what == POSITION
    vx, _, _ = _cmd(node)
    assert striker.state == "position" and vx < 0  # backs out, away from the ball
    assert striker.game.order(1.2, 0.0).what == STAND  # outside: it waits there
    node.inject("game_state", _game_state(PLAYING, kicking=1, secondary_s=0))  # ball free
    assert striker.game.order(0.3, 0.0).what == PLAY
    node.inject("game_state", _game_state(PLAYING, kicking=1, secondary_s=5))
    node.advance(10.0)  # 10 s after playing began the ball is free, whatever was said
    assert striker.game.order(0.3, 0.0).what == PLAY


def test_a_robot_the_referee_placed_takes_its_kickoff_spot_as_its_pose() -> None:
    node, striker = _striker("blue1", [1.0, 1.0, 0.0])  # in the opponent half: illegal
    node.inject("game_state", _game_state(SET))
    node.advance(0.1)
    spot = kickoff_pose(Player("blue", 1), first_half=True, kicking=True)
    assert (striker.pose.x, striker.pose.y, striker.pose.heading) == pytest.approx(spot)
    legal = kickoff_pose(Player("blue", 2), first_half=True, kicking=True)
    node2, striker2 = _striker("blue2", [legal[0] - 0.4, legal[1], 0.0])
    node2.inject("game_state", _game_state(SET))
    node2.advance(0.1)
    assert (striker2.pose.x, striker2.pose.y) == pytest.approx((legal[0] - 0.4, legal[1]))


def test_without_a_name_or_a_game_state_it_plays_or_stands_safely() -> None:
    node = TestHandle("behaviour")
    game = GameControl(node)
    assert game.order(0.0, 0.0).what == PLAY  # no referee: the one-robot demo
    node.inject("game_state", _game_state(READY))
    assert game.order(0.0, 0.0).what == STAND and game.goal() is None
    node.inject("game_state", _game_state(PLAYING))
    assert game.order(0.0, 0.0).what == PLAY


def test_robots_obey_the_team_referee_in_the_same_container() -> None:
    referee_node = TestHandle("referee", parameters={
        "robots": ["blue1", "red1"], "initial_s": 1.0, "ready_s": 3.0, "settle_s": 0.0,
        "set_s": 1.0})
    TeamReferee(referee_node)
    blue_node = TestHandle("striker", namespace="/blue1", container=referee_node.container,
                           remappings={"/blue1/game_state": "/game_state"},
                           parameters={"robot": "blue1", "start_pose": [-2.0, 0.0, 0.0],
                                       "settle_s": 0.0})
    blue = Striker(blue_node)
    blue_node.inject("imu/data", Imu(orientation=Quaternion(w=1.0)))
    referee_node.advance(0.5)
    assert blue.state == WAIT  # initial
    referee_node.advance(1.0)
    assert blue.state == "position" and _cmd(blue_node)[0] > 0  # ready: to (-0.3, 0)
    referee_node.inject("ground_truth/blue1/pose", PoseStamped())  # (not needed: legal)
    referee_node.advance(2.6)
    assert referee_node.published("game_state")[-1].game_state == SET
    assert blue.state == WAIT and _cmd(blue_node) == (0.0, 0.0, 0.0)
