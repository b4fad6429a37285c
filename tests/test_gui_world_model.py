"""The world view's model fed messages directly (no robot, no browser): colours and ages."""

from __future__ import annotations

import pytest
from geometry_msgs.msg import PointStamped
from nav_msgs.msg import Odometry

from debug_gui import RobotId
from debug_gui.models.world import STALE_S, WorldModel
from debug_gui.ui.world import ball_opacity


def test_a_robot_keeps_its_colour_when_another_appears() -> None:
    r1, r2, r3 = (RobotId(5, f"/robot{k}") for k in (1, 2, 3))
    before = {s.robot: s.colour for s in WorldModel(None, [r2, r3]).states()}  # type: ignore[arg-type]
    after = {s.robot: s.colour for s in WorldModel(None, [r1, r2, r3]).states()}  # type: ignore[arg-type]
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
    model = WorldModel(None, [robot], clock=lambda: 0.0)  # type: ignore[arg-type]
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
