"""The striker's decisions, the ball's place on the ground, and the game's figures (referee
and monitor), each alone on a TestHandle."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest
from geometry_msgs.msg import (
    PointStamped,
    PoseStamped,
    PoseWithCovarianceStamped,
    Quaternion,
    Twist,
)
from nav_msgs.msg import Odometry
from sensor_msgs.msg import Image, Imu
from std_msgs.msg import String

from efficient_comm.testing import TestHandle
from humanoid_sim.errors import SimConfigError
from humanoid_sim.mujoco_plant import MujocoPlant
from humanoid_sim.soccer.monitor import SoccerMonitor
from humanoid_sim.soccer.referee import Referee
from humanoid_sim.soccer.roles import Role
from humanoid_sim.soccer.striker import (
    APPROACH,
    FALLEN,
    KICK,
    SEARCH,
    STOP,
    Pose,
    Striker,
    kick_pose,
    role_pose,
)
from humanoid_sim.soccer.world_model import ground_position
from soccer_field import KIDSIZE

KICK_DISTANCE, FOOT_OFFSET = 0.16, 0.045


def _quaternion(*, roll: float = 0.0, pitch: float = 0.0, yaw: float = 0.0) -> Quaternion:
    cr, sr = math.cos(roll / 2), math.sin(roll / 2)
    cp, sp = math.cos(pitch / 2), math.sin(pitch / 2)
    cy, sy = math.cos(yaw / 2), math.sin(yaw / 2)
    return Quaternion(w=cr * cp * cy + sr * sp * sy, x=sr * cp * cy - cr * sp * sy,
                      y=cr * sp * cy + sr * cp * sy, z=cr * cp * sy - sr * sp * cy)


@pytest.mark.parametrize(("neck_yaw", "neck_pitch", "roll", "pitch", "yaw"), [
    (0.0, 0.45, 0.0, 0.0, 0.0), (0.6, 0.9, 0.05, 0.08, 1.0), (-0.8, 1.2, -0.04, 0.12, -2.5)])
def test_the_ball_on_the_ground_from_its_bearing_matches_the_robots_kinematics(
        neck_yaw: float, neck_pitch: float, roll: float, pitch: float, yaw: float) -> None:
    # MuJoCo's forward kinematics of robot.xml place the camera; the bearing of a ball on
    # the ground seen from there, in the torso's frame, must lead back to where it lies.
    plant = MujocoPlant()
    model, data = plant.model, plant.data
    torso_height = 0.37
    q = _quaternion(roll=roll, pitch=pitch, yaw=yaw)
    data.qpos[0:7] = [0.3, -0.2, torso_height, q.w, q.x, q.y, q.z]
    data.qpos[model.joint("neck_yaw").qposadr[0]] = neck_yaw
    data.qpos[model.joint("neck_pitch").qposadr[0]] = neck_pitch
    mujoco.mj_forward(model, data)
    torso = data.xmat[model.body("torso").id].reshape(3, 3)
    camera = data.cam_xpos[model.camera("head_camera").id]
    heading = math.atan2(torso[1, 0], torso[0, 0])
    local = (0.9, 0.35)  # the ball in the level frame under the torso (x forward, y left)
    c, s = math.cos(heading), math.sin(heading)
    ball = np.array([0.3 + c * local[0] - s * local[1], -0.2 + s * local[0] + c * local[1],
                     0.07])
    x, y, z = torso.T @ (ball - camera)
    found = ground_position(math.atan2(y, x), math.atan2(-z, math.hypot(x, y)),
                            neck_yaw=neck_yaw, neck_pitch=neck_pitch, orientation=q,
                            torso_height=torso_height)
    assert found == pytest.approx(local, abs=1e-6)


def test_a_ray_at_or_above_the_horizon_has_no_place_on_the_ground() -> None:
    assert ground_position(0.0, -0.1, neck_yaw=0.0, neck_pitch=0.0) is None
    assert ground_position(0.0, 0.5, neck_yaw=0.0, neck_pitch=0.5) is not None


def _striker(**parameters: object) -> tuple[TestHandle, Striker]:
    node = TestHandle("striker", parameters={"kick_distance": KICK_DISTANCE,
                                             "foot_offset": FOOT_OFFSET, "settle_s": 0.0,
                                             **parameters})
    return node, Striker(node)


def _ball(node: TestHandle, x: float, y: float) -> None:
    position = PointStamped()
    position.point.x, position.point.y = x, y
    node.inject("ball/position", position)


def _imu(node: TestHandle, yaw: float) -> None:
    node.inject("imu/data", Imu(orientation=_quaternion(yaw=yaw)))


def _odom(node: TestHandle, x: float, y: float, yaw: float) -> None:
    odom = Odometry()
    odom.pose.pose.position.x, odom.pose.pose.position.y = x, y
    odom.pose.pose.orientation = _quaternion(yaw=yaw)
    node.inject("odom", odom)


def _last_cmd(node: TestHandle) -> tuple[float, float, float]:
    twist: Twist = node.published("cmd_vel")[-1]
    return twist.linear.x, twist.linear.y, twist.angular.z


def _states(node: TestHandle) -> list[str]:
    return [m.data for m in node.published("behaviour/state")]


def test_kick_pose_is_behind_the_ball_facing_the_goal_with_the_foot_in_line() -> None:
    pose = kick_pose((2.0, 1.0), (4.5, 1.0), foot="left", kick_distance=0.2, foot_offset=0.05)
    assert (pose.x, pose.y, pose.heading) == pytest.approx((1.8, 0.95, 0.0))
    pose = kick_pose((0.0, 0.0), (0.0, -3.0), foot="right", kick_distance=0.2, foot_offset=0.05)
    # Facing -y its left is +x: the torso stands there, the right foot behind the ball.
    assert (pose.x, pose.y, pose.heading) == pytest.approx((0.05, 0.2, -math.pi / 2))


def test_without_the_ball_it_looks_first_then_turns_in_place() -> None:
    node, striker = _striker(search_wait_s=3.0)
    assert _states(node) == [SEARCH]
    node.advance(2.5)
    assert node.published("cmd_vel") == []  # the head's sweep looks first
    node.advance(1.0)
    vx, vy, wz = _last_cmd(node)
    assert (vx, vy) == (0.0, 0.0)
    assert wz == pytest.approx(striker.p["search_turn"])
    assert striker.kicks == 0


def test_it_walks_to_a_ball_ahead_then_stops_lines_up_and_kicks() -> None:
    node, striker = _striker()
    _imu(node, 0.0)
    _ball(node, 1.0, 0.1)  # 1 m ahead, a little left: the left foot kicks
    node.advance(0.1)
    assert striker.state == APPROACH
    vx, vy, wz = _last_cmd(node)
    assert vx == pytest.approx(striker.p["max_vx"])  # far: full speed ahead
    assert abs(vy) < 0.02 and abs(wz) < 0.2
    assert striker.foot == "left"
    # Walked there (odometry says so): the ball now lies at the kick distance, in line
    # with the left foot.
    _odom(node, 0.0, 0.0, 0.0)
    _odom(node, 1.0 - KICK_DISTANCE, 0.1 - FOOT_OFFSET, 0.0)
    _ball(node, KICK_DISTANCE, FOOT_OFFSET)
    node.inject("motion/state", String(data="walk"))
    node.advance(0.1)
    assert striker.state == STOP
    assert _last_cmd(node) == (0.0, 0.0, 0.0)
    assert node.published("motion/kick/request") == []  # not while still walking
    node.inject("motion/state", String(data="stand"))
    assert [m.data for m in node.published("motion/kick/request")] == ["left"]
    assert striker.state == KICK
    node.inject("motion/state", String(data="kick"))
    node.advance(0.2)
    assert striker.state == KICK  # until the kick is over
    node.inject("motion/state", String(data="stand"))
    node.advance(0.1)
    assert striker.kicks == 1
    # The ball did not move (no simulator here): it lines up for the next kick at once.
    assert _states(node)[:5] == [SEARCH, APPROACH, STOP, KICK, APPROACH]


def test_at_the_start_it_stands_still_for_a_while() -> None:
    node, striker = _striker(settle_s=2.0)
    _imu(node, 0.0)
    _ball(node, 1.0, 0.0)
    node.advance(1.9)
    assert node.published("cmd_vel") == []
    assert striker.state == SEARCH
    _ball(node, 1.0, 0.0)  # the head kept it in view
    node.advance(0.2)
    assert striker.state == APPROACH and _last_cmd(node)[0] > 0


def test_a_ball_on_the_right_is_kicked_with_the_right_foot() -> None:
    node, _ = _striker()
    _imu(node, 0.0)
    _ball(node, KICK_DISTANCE, -FOOT_OFFSET)
    node.inject("motion/state", String(data="stand"))
    node.advance(0.1)
    node.inject("motion/state", String(data="stand"))
    assert [m.data for m in node.published("motion/kick/request")] == ["right"]


def test_the_goal_direction_comes_from_its_own_pose_estimate() -> None:
    # Started at the centre facing +y (left of the goal direction), the IMU's heading
    # counted from its first reading: a ball 1 m ahead is to be kicked towards +x, so the
    # robot's kick position is behind it and to the left, and it walks there.
    node, striker = _striker(start_pose=[0.0, 0.0, math.pi / 2])
    _imu(node, 0.7)  # whatever the IMU's own zero is
    _ball(node, 1.0, 0.0)
    node.advance(0.1)
    assert striker.ball == pytest.approx((0.0, 1.0))
    target = striker.target()
    assert target.heading == pytest.approx(math.atan2(-1.0, 4.5))  # ball to goal
    assert target.x < -0.1 and target.y < 1.0
    _imu(node, 0.7 - 0.5)  # turned right by 0.5 rad
    assert striker.pose.heading == pytest.approx(math.pi / 2 - 0.5)
    # Odometry's steps are turned into the field by the heading: 1 m forward now is along
    # the heading, whatever the odometry's own frame.
    _odom(node, 5.0, 5.0, 2.0)
    _odom(node, 5.0 + math.cos(2.0), 5.0 + math.sin(2.0), 2.0)
    assert (striker.pose.x, striker.pose.y) == pytest.approx(
        (math.cos(math.pi / 2 - 0.5), math.sin(math.pi / 2 - 0.5)))


def test_a_kick_that_does_not_begin_is_given_up_and_tried_again() -> None:
    node, striker = _striker(kick_start_s=1.0)
    _imu(node, 0.0)
    _ball(node, KICK_DISTANCE, FOOT_OFFSET)
    node.inject("motion/state", String(data="stand"))
    node.advance(0.1)
    assert striker.state == KICK
    node.advance(0.8)
    assert striker.state == KICK
    node.advance(0.6)  # refused: motion/state never said kick
    assert striker.kicks == 0
    assert len(node.published("motion/kick/request")) == 2  # lined up still: asked again
    assert any("did not happen" in text for _, text in node.records)


def test_in_front_of_the_ball_it_walks_around_it_not_through_it() -> None:
    # Facing its own goal, the ball 1 m ahead: the kick position is on the far side.
    node, striker = _striker(start_pose=[2.0, 0.0, math.pi])
    _imu(node, 0.0)
    _ball(node, 1.0, 0.0)
    node.advance(0.1)
    vx, vy, wz = _last_cmd(node)
    ball = striker.pose.to_local(*striker.ball) if striker.ball else (0.0, 0.0)
    direction = math.atan2(vy, vx) if (vx or vy) else math.atan2(0.0, 1.0) + wz
    assert abs(direction - math.atan2(ball[1], ball[0])) > 0.2 or abs(wz) > 0.3


def test_it_stands_still_while_down_and_searches_once_up() -> None:
    node, striker = _striker()
    _imu(node, 0.0)
    _ball(node, 1.0, 0.0)
    node.advance(0.1)
    assert striker.state == APPROACH
    node.inject("fall/state", String(data="fallen"))
    assert striker.state == FALLEN
    assert _last_cmd(node) == (0.0, 0.0, 0.0)
    node.clear_published()
    _ball(node, KICK_DISTANCE, FOOT_OFFSET)  # what it sees lying down is not believed
    node.inject("motion/state", String(data="getup"))
    node.inject("fall/state", String(data="standing"))
    node.advance(1.0)
    assert striker.state == FALLEN  # the get-up is not over
    assert node.published("cmd_vel") == []
    assert node.published("motion/kick/request") == []
    node.inject("motion/state", String(data="stand"))
    assert striker.state == SEARCH


def test_bad_parameters_are_refused_with_their_names() -> None:
    with pytest.raises(SimConfigError, match="max_vx"):
        _striker(max_vx=-0.1)
    with pytest.raises(SimConfigError, match="start_pose"):
        _striker(start_pose=[0.0, 0.0])


def test_pose_frames_round_trip() -> None:
    pose = Pose(1.0, -2.0, 0.7)
    assert pose.to_local(*pose.to_field(0.3, -0.4)) == pytest.approx((0.3, -0.4))


def _pose(x: float, y: float, z: float = 0.07, q: Quaternion | None = None) -> PoseStamped:
    pose = PoseStamped()
    pose.pose.position.x, pose.pose.position.y, pose.pose.position.z = x, y, z
    if q is not None:
        pose.pose.orientation = q
    return pose


def test_the_referee_counts_a_goal_only_between_the_posts_and_puts_the_ball_back() -> None:
    node = TestHandle("referee", parameters={"restart_s": 1.0})
    referee = Referee(node)
    node.inject("ground_truth/ball", _pose(4.5, 0.0))  # on the line: not yet over it
    node.inject("ground_truth/ball", _pose(4.6, 1.2))  # wholly over, inside the post
    assert (referee.goals, referee.outs) == (1, 0)
    node.inject("ground_truth/ball", _pose(4.9, 1.2))  # still in the goal: counted once
    assert referee.goals == 1
    assert node.published("place_ball") == []  # a moment for everyone to see it
    node.advance(1.0)
    node.inject("ground_truth/ball", _pose(5.0, 1.2))
    (centre,) = node.published("place_ball")
    assert (centre.x, centre.y) == (0.0, 0.0)
    node.inject("ground_truth/ball", _pose(0.0, 0.0))
    node.inject("ground_truth/ball", _pose(4.6, 1.5))  # wide of the post: out
    node.inject("ground_truth/ball", _pose(-1.0, -3.2))  # (not judged while waiting)
    assert (referee.goals, referee.outs) == (1, 1)
    node.advance(1.0)
    node.inject("ground_truth/ball", _pose(4.6, 1.5))
    back = node.published("place_ball")[-1]
    assert (back.x, back.y) == pytest.approx((4.2, 1.5))
    node.inject("ground_truth/ball", _pose(-4.6, 0.0))
    assert referee.own_goals == 1 and referee.goal_at_ns == [0]


def test_the_monitor_counts_kicks_get_ups_the_first_kick_and_the_way_walked() -> None:
    node = TestHandle("monitor")
    monitor = SoccerMonitor(node)
    for x in (0.0, 0.01, 0.1, 0.2):  # 1 cm of sway is not walking; the rest is
        node.inject("ground_truth/robot", _pose(x, 0.0, 0.37))
        node.advance(0.5)
    assert monitor.walked_m == pytest.approx(0.2)
    node.inject("motion/state", String(data="walk"))
    node.inject("motion/state", String(data="stand"))
    node.advance(1.0)
    node.inject("motion/state", String(data="kick"))
    node.inject("motion/state", String(data="stand"))
    node.inject("motion/state", String(data="kick"))
    node.inject("motion/state", String(data="fallen"))
    node.inject("fall/state", String(data="fallen"))
    node.inject("ground_truth/robot", _pose(5.0, 0.0, 0.1))  # lying down: not walking
    node.inject("motion/state", String(data="getup"))
    node.inject("motion/state", String(data="stand"))
    assert (monitor.kicks, monitor.getups) == (2, 1)
    assert monitor.first_kick_ns == 3_000_000_000
    assert monitor.walked_m == pytest.approx(0.2)


@pytest.mark.parametrize("states", [
    ["fallen", "getup", "stand"],
    ["fallen", "getup", "fallen", "stand"],  # the motion over before fall/state says standing
    ["fallen", "getup", "fallen", "getup", "fallen", "walk"],  # a second attempt
])
def test_the_monitor_counts_a_get_up_however_the_arbiter_got_back_to_standing(
        states: list[str]) -> None:
    node = TestHandle("monitor")
    monitor = SoccerMonitor(node)
    for state in ["stand", *states, "stand", "fallen", "stand"]:  # no get-up in the last fall
        node.inject("motion/state", String(data=state))
    assert monitor.getups == 1


def test_the_monitor_does_not_score_frames_without_the_ball_in_the_image() -> None:
    node = TestHandle("monitor")
    monitor = SoccerMonitor(node)
    # MuJoCo's camera frame looks along -z; this one looks along +x (the field's).
    looking_ahead = Quaternion(w=0.5, x=0.5, y=-0.5, z=-0.5)
    node.inject("ground_truth/camera", _pose(0.0, 0.0, 0.5, looking_ahead))
    image = Image(height=240, width=320, encoding="rgb8", step=960)
    for ball in ((2.0, 0.1), (-2.0, 0.0), (0.5, 2.0)):  # ahead; behind; far to the side
        node.inject("ground_truth/ball", _pose(*ball))
        node.inject("camera/image_raw", image)
    totals = monitor.totals()
    assert (totals.frames, totals.frames_out_of_view) == (3, 2)
    assert len(totals.tracking_error_deg) == 1
    assert totals.tracking_error_deg[0] == pytest.approx(
        math.degrees(math.atan2(math.hypot(0.1, 0.43), 2.0)), abs=0.01)


def _role(node: TestHandle, role: str) -> None:
    node.inject("role", String(data=role))


def _team_ball(node: TestHandle, x: float, y: float) -> None:
    ball = PoseWithCovarianceStamped()
    ball.pose.pose.position.x, ball.pose.pose.position.y = x, y
    node.inject("team_ball", ball)


def test_only_the_striker_goes_for_the_ball_the_others_take_their_places() -> None:
    # The robot at -2, 0 facing +x; the ball 1.5 m ahead. Supporter, defender, goalie each
    # walk to their place (none towards the kick position) and wait there facing the ball.
    own_goal = (-KIDSIZE.half_length, 0.0)
    for role, state in (("supporter", "support"), ("defender", "defend"), ("goalie", "guard")):
        node, striker = _striker(start_pose=[-2.0, 0.0, 0.0])
        _role(node, role)
        _ball(node, 1.5, 0.0)
        node.advance(0.2)
        assert striker.state == state, (role, _states(node))
        place = role_pose(Role(role), (-0.5, 0.0), own_goal, support_distance=1.0,
                          support_side=0.5, goalie_distance=0.5)
        assert math.dist((place.x, place.y), own_goal) < math.dist((-0.5, 0.0), own_goal)
        x, y = striker.pose.to_local(place.x, place.y)
        vx, vy, _ = _last_cmd(node)
        assert vx * x + vy * y > 0, (role, place, _last_cmd(node))  # towards its place
    # The defender lies between the ball and its goal; the goalie in front of its goal.
    defender = role_pose(Role.DEFENDER, (1.0, 1.0), own_goal, support_distance=1.0,
                         support_side=0.5, goalie_distance=0.5)
    assert own_goal[0] < defender.x < 1.0
    goalie = role_pose(Role.GOALIE, (1.0, 1.0), own_goal, support_distance=1.0,
                       support_side=0.5, goalie_distance=0.5)
    assert math.isclose(goalie.x, own_goal[0] + 0.5) and abs(goalie.y) <= 0.6
    # Made striker, it approaches the ball.
    node, striker = _striker(start_pose=[-2.0, 0.0, 0.0])
    _role(node, "defender")
    _ball(node, 1.5, 0.0)
    node.advance(0.2)
    _role(node, "striker")
    _ball(node, 1.5, 0.0)
    node.advance(0.2)
    assert striker.state == "approach", _states(node)


def test_without_its_own_sighting_it_goes_for_the_teams_ball() -> None:
    node, striker = _striker(start_pose=[0.0, 0.0, 0.0], ball_lost_s=1.0)
    node.advance(0.2)
    assert striker.state == "search"
    _team_ball(node, 1.0, 0.5)
    node.advance(0.2)
    assert striker.state == "approach" and striker.ball == (1.0, 0.5), _states(node)
    node.advance(1.5)  # the team's ball is old now too
    assert striker.state == "search", _states(node)
