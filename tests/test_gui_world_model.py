"""The world view's model fed messages directly (no robot, no browser): colours, ages, the
team match's robots and game."""

from __future__ import annotations

from typing import Any

import pytest
from geometry_msgs.msg import PointStamped, PoseStamped, PoseWithCovarianceStamped
from nav_msgs.msg import Odometry
from std_msgs.msg import String

from debug_gui import RobotId
from debug_gui.models.world import STALE_S, TEAM_COLOURS, WorldModel
from debug_gui.testing import FakeSource
from debug_gui.ui.world import ball_opacity, game_text, world_svg
from soccer_interfaces.msg import GameState, TeamInfo


def test_a_robot_keeps_its_colour_when_another_appears() -> None:
    r1, r2, r3 = (RobotId(5, f"/robot{k}") for k in (1, 2, 3))
    before = {s.robot: s.colour for s in WorldModel(FakeSource(), [r2, r3]).states()}
    after = {s.robot: s.colour for s in WorldModel(FakeSource(), [r1, r2, r3]).states()}
    assert after[r2] == before[r2] and after[r3] == before[r3]
    assert len(set(after.values())) == 3


def _odom(t: float) -> Odometry:
    msg = Odometry()
    msg.header.stamp.sec, msg.header.stamp.nanosec = int(t), int(t % 1 * 1e9)
    msg.pose.pose.orientation.w = 1.0
    return msg


def _ball(t: float) -> PointStamped:
    msg = PointStamped()
    msg.header.stamp.sec, msg.header.stamp.nanosec = int(t), int(t % 1 * 1e9)
    msg.point.x, msg.point.z = 0.0, 1.0  # straight ahead, 1 m
    return msg


def test_a_ball_estimate_ages_by_the_robots_stamps_and_goes_when_stale() -> None:
    """The GUI's clock says nothing here (it stands still): under lockstep the robot's
    time is not the GUI's, and what counts is how old the belief is on the robot."""
    robot = RobotId(5, "/robot1")
    model = WorldModel(FakeSource(), [robot], clock=lambda: 0.0)
    model.on_ball(robot, _ball(0.5))
    model.on_odom(robot, _odom(1.0))
    [state] = model.states()
    assert state.ball == pytest.approx((1.0, 0.0)) and state.ball_age_s == pytest.approx(0.5)
    assert ball_opacity(state.ball_age_s) == 1.0
    model.on_odom(robot, _odom(2.5))
    [state] = model.states()
    assert state.ball is not None and 0.2 < ball_opacity(state.ball_age_s) < 1.0
    assert model.team_ball() is None  # 2 s old: no longer fresh enough to fuse
    model.on_odom(robot, _odom(14.5))  # the robot has not seen the ball for 14 s
    [state] = model.states()
    assert state.ball is None and state.ball_age_s == pytest.approx(14.0)
    assert state.ball_age_s is not None and state.ball_age_s > STALE_S


# -- the team match's robots (issue 19, point 8) -------------------------------------------


def _stamped(msg: Any, t: float) -> Any:
    msg.header.stamp.sec, msg.header.stamp.nanosec = int(t), int(t % 1 * 1e9)
    return msg


def _pose(cls: type, t: float, x: float, y: float) -> Any:
    msg = _stamped(cls(), t)
    pose = msg.pose.pose if cls is PoseWithCovarianceStamped else msg.pose
    pose.position.x, pose.position.y, pose.orientation.w = x, y, 1.0
    return msg


def test_a_match_robot_is_drawn_in_its_teams_colour_where_it_localizes_with_its_role() -> None:
    blue1, blue2, red1 = RobotId(7, "/blue1"), RobotId(8, "/blue2"), RobotId(9, "/red1")
    model = WorldModel(FakeSource(), [red1, blue2, blue1], clock=lambda: 0.0)
    model.on_odom(blue1, _odom(1.0))  # odometry says the origin ...
    model.on_localization(blue1, _pose(PoseWithCovarianceStamped, 1.0, -2.0, 1.5))
    model.on_true_robot(blue1, _pose(PoseStamped, 1.0, -2.1, 1.5))  # as the match names it
    model.on_role(blue1, String(data="striker"))
    states = {s.robot: s for s in model.states()}
    b1 = states[blue1]
    assert b1.pose is not None and (b1.pose.x, b1.pose.y) == (-2.0, 1.5)  # ... localization wins
    assert b1.pose_source == "localization" and b1.role == "striker" and b1.team == "blue"
    assert b1.true_pose is not None and b1.true_pose.x == pytest.approx(-2.1)
    assert {states[r].colour for r in (blue1, blue2)} <= set(TEAM_COLOURS["blue"])
    assert states[blue1].colour != states[blue2].colour
    assert states[red1].colour in TEAM_COLOURS["red"] and states[red1].team == "red"


def test_ages_go_by_the_robots_own_clock_however_skewed_against_the_worlds() -> None:
    """Ground truth and the game state are stamped by the world; a robot's clock runs 100 s
    behind it. Its fresh ball estimate and team ball are still fresh."""
    robot = RobotId(7, "/red1")
    model = WorldModel(FakeSource(), [robot], clock=lambda: 0.0)
    model.on_localization(robot, _pose(PoseWithCovarianceStamped, 10.0, 1.0, 0.0))
    model.on_ball(robot, _ball(10.0))
    model.on_team_ball(robot, _pose(PoseWithCovarianceStamped, 10.0, 2.5, 0.5))
    model.on_true_robot(robot, _pose(PoseStamped, 110.0, 1.0, 0.0))
    model.on_true_ball(robot, _pose(PoseStamped, 110.0, 2.0, 0.0))
    model.on_game_state(robot, _stamped(GameState(), 110.0))
    [state] = model.states()
    assert state.ball == pytest.approx((2.0, 0.0)) and state.ball_age_s == pytest.approx(0.0)
    assert state.team_ball == pytest.approx((2.5, 0.5))
    assert state.team_ball_age_s == pytest.approx(0.0)
    # The robots share a ball: theirs is drawn, not the GUI's own fusion.
    assert model.team_ball([state]) is None


def _game(t: float, state: int, blue: int, red: int, packet: int) -> GameState:
    msg = _stamped(GameState(), t)
    msg.game_state, msg.first_half, msg.packet_number = state, True, packet
    msg.kicking_team, msg.seconds_remaining = 2, 600
    for team, (number, colour, score) in zip(
            msg.teams, ((1, TeamInfo.COLOUR_BLUE, blue), (2, TeamInfo.COLOUR_RED, red)),
            strict=True):
        team.team_number, team.team_colour, team.score = number, colour, score
    return msg


def test_the_game_is_the_newest_broadcast_any_robot_passed_on() -> None:
    blue1, red1 = RobotId(7, "/blue1"), RobotId(8, "/red1")
    model = WorldModel(FakeSource(), [blue1, red1])
    assert model.game() is None
    model.on_game_state(red1, _game(20.0, GameState.STATE_READY, 1, 0, packet=41))
    model.on_game_state(blue1, _game(12.0, GameState.STATE_PLAYING, 0, 0, packet=30))  # late
    game = model.game()
    assert game is not None and game.state == "ready" and game.score == {"blue": 1, "red": 0}
    assert game.kicking == "red"
    assert game.text() == "ready, 1st half, blue 1 : 0 red, kick-off red, 600 s left"


def test_the_drawing_names_each_robot_with_its_role_team_and_team_ball() -> None:
    blue1, red1 = RobotId(7, "/blue1"), RobotId(8, "/red1")
    model = WorldModel(FakeSource(), [blue1, red1], clock=lambda: 0.0)
    for robot, x in ((blue1, -1.0), (red1, 1.0)):
        model.on_localization(robot, _pose(PoseWithCovarianceStamped, 5.0, x, 0.0))
    model.on_role(blue1, String(data="goalie"))
    model.on_team_ball(blue1, _pose(PoseWithCovarianceStamped, 5.0, 0.5, 0.5))
    states = model.states()
    svg = world_svg(states, model.team_ball(states))
    assert 'data-testid="world-robot-7:/blue1"' in svg and 'data-role="goalie"' in svg
    assert 'data-team="blue"' in svg and 'data-team="red"' in svg
    assert ">blue1 goalie</text>" in svg and ">red1</text>" in svg
    assert 'data-testid="world-team-ball-7:/blue1"' in svg
    assert 'data-testid="world-team-ball"' not in svg  # the robots share one: no GUI fusion
    model.on_game_state(red1, _game(9.0, GameState.STATE_PLAYING, 0, 2, packet=3))
    assert game_text(model.game()) == "game: playing, 1st half, blue 0 : 2 red, 600 s left"
