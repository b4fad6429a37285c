"""Localization: the particle filter on synthetic observations, its component, the noisy
ground-truth stand-in and the error monitor, each on a TestHandle; the landmark detector's
camera pose against MuJoCo's kinematics."""

from __future__ import annotations

import math
import statistics

import mujoco
import numpy as np
import pytest
from geometry_msgs.msg import PoseStamped, PoseWithCovarianceStamped, Quaternion
from nav_msgs.msg import Odometry
from sensor_msgs.msg import Image, PointCloud2, PointField
from std_msgs.msg import Bool, String

from efficient_comm import from_msg, to_msg
from efficient_comm.testing import TestHandle, test_container
from humanoid_sim.errors import SimConfigError
from humanoid_sim.mujoco_plant import MujocoPlant
from humanoid_sim.soccer.landmarks import (
    CameraPose,
    LandmarkDetector,
    points_message,
    read_points,
)
from humanoid_sim.soccer.localization import (
    NOISY_GROUND_TRUTH,
    PARTICLE_FILTER,
    FieldModel,
    FilterParameters,
    Localization,
    NoisyTruthPose,
    ParticleFilter,
    add_localization,
    wrap,
    yaw_of,
)
from humanoid_sim.soccer.pose_error import PoseErrorMonitor
from soccer_field import KIDSIZE

FIELD = FieldModel()
#: What the synthetic camera sees: within this range (m) and bearing (rad) of the robot.
VIEW_RANGE, VIEW_BEARING = (0.3, 4.0), 0.75


def _yaw_quaternion(yaw: float) -> Quaternion:
    return Quaternion(w=math.cos(yaw / 2), x=0.0, y=0.0, z=math.sin(yaw / 2))


def _field_points() -> np.ndarray:
    """Points every 5 cm along every line of the field (KIDSIZE's lines)."""
    points = []
    for (ax, ay), (bx, by) in FIELD.segments:
        n = max(2, round(math.hypot(bx - ax, by - ay) / 0.05))
        t = np.linspace(0.0, 1.0, n)
        points.append(np.stack([ax + t * (bx - ax), ay + t * (by - ay)], axis=1))
    r = KIDSIZE.centre_circle_diameter / 2
    a = np.linspace(0, 2 * math.pi, round(2 * math.pi * r / 0.05), endpoint=False)
    points.append(np.stack([r * np.cos(a), r * np.sin(a)], axis=1))
    return np.concatenate(points)


LINE_POINTS = _field_points()


def _seen(points: np.ndarray, pose: tuple[float, float, float], *, max_range: float
          ) -> np.ndarray:
    x, y, h = pose
    dx, dy = points[:, 0] - x, points[:, 1] - y
    c, s = math.cos(h), math.sin(h)
    local = np.stack([c * dx + s * dy, -s * dx + c * dy], axis=1)
    r = np.hypot(local[:, 0], local[:, 1])
    bearing = np.arctan2(local[:, 1], local[:, 0])
    return local[(r >= VIEW_RANGE[0]) & (r <= max_range) & (np.abs(bearing) <= VIEW_BEARING)]


def observe(pose: tuple[float, float, float], rng: np.random.Generator
            ) -> tuple[np.ndarray, np.ndarray]:
    """What a camera at ``pose`` reports: up to 60 line points (2 cm noise) and the posts'
    feet within 7 m (2 % range, 1 degree bearing noise), robot frame."""
    lines = _seen(LINE_POINTS, pose, max_range=VIEW_RANGE[1])
    if len(lines) > 60:
        lines = lines[rng.choice(len(lines), 60, replace=False)]
    lines = lines + rng.normal(0.0, 0.02, lines.shape)
    posts = _seen(FIELD.posts, pose, max_range=7.0)
    r = np.hypot(posts[:, 0], posts[:, 1]) * (1 + rng.normal(0.0, 0.02, len(posts)))
    b = np.arctan2(posts[:, 1], posts[:, 0]) + rng.normal(0.0, math.radians(1), len(posts))
    return lines, np.stack([r * np.cos(b), r * np.sin(b)], axis=1)


def _error(pf: ParticleFilter, truth: tuple[float, float, float]) -> tuple[float, float]:
    e = pf.estimate()
    return math.hypot(e.x - truth[0], e.y - truth[1]), abs(wrap(e.heading - truth[2]))


@pytest.mark.parametrize(("own_half", "found"), [
    (-1.0, (-2.0, 1.0, 0.3)),  # the truth
    (1.0, (2.0, -1.0, 0.3 + math.pi)),  # the field's mirror image: all the robot can tell
])
def test_the_filter_finds_the_robot_in_the_half_it_knows_it_is_in(
        own_half: float, found: tuple[float, float, float]) -> None:
    # Nothing known but the half: the robot turns on the spot, looking around.
    rng = np.random.default_rng(1)
    pf = ParticleFilter(FilterParameters(particles=3000), seed=1)
    pf.reset_in_half(own_half)
    x, y, heading = -2.0, 1.0, 0.3
    for _ in range(40):
        pf.predict(0.0, 0.0, 0.2)
        heading += 0.2
        lines, posts = observe((x, y, heading), rng)
        pf.update_lines(lines)
        pf.update_posts(posts)
    distance, turn = _error(pf, (found[0], found[1], heading + found[2] - 0.3))
    assert distance < 0.15, pf.estimate()
    assert turn < math.radians(5), pf.estimate()


def test_the_filter_tracks_a_walk_whose_odometry_drifts() -> None:
    # 20 s at 0.15 m/s and 3.4 degrees/s, odometry 30 times a second: it says 20 % more
    # than walked and turns 3 degrees a second too much. Dead reckoning ends far off; the
    # filter, seeing lines and posts ten times a second, stays close.
    rng = np.random.default_rng(2)
    pf = ParticleFilter(seed=2)
    truth = (-3.0, -1.5, 0.2)
    pf.reset_around(*truth, sigma_m=0.1, sigma_rad=0.05)
    reckoned = truth
    errors = []
    for step in range(600):
        forward, turn = 0.005, 0.002
        x, y, h = truth
        truth = (x + forward * math.cos(h), y + forward * math.sin(h), h + turn)
        said = (forward * 1.2, turn + math.radians(0.1))
        pf.predict(said[0], 0.0, said[1])
        x, y, h = reckoned
        reckoned = (x + said[0] * math.cos(h), y + said[0] * math.sin(h), h + said[1])
        if step % 3 == 0:
            lines, posts = observe(truth, rng)
            pf.update_lines(lines)
            pf.update_posts(posts)
        errors.append(_error(pf, truth))
    dead_reckoning = math.hypot(reckoned[0] - truth[0], reckoned[1] - truth[1])
    assert dead_reckoning > 0.6
    assert max(e[0] for e in errors) < 0.15
    assert statistics.fmean(e[0] for e in errors) < 0.06
    assert max(e[1] for e in errors) < math.radians(5)


def test_without_observations_the_filter_is_only_as_good_as_its_odometry() -> None:
    # The same walk, nothing seen: the estimate drifts with the odometry, its spread grows.
    pf = ParticleFilter(seed=3)
    pf.reset_around(0.0, 0.0, 0.0, sigma_m=0.05, sigma_rad=0.02)
    before = pf.estimate().covariance
    for _ in range(100):
        pf.predict(0.024, 0.0, 0.0)
    after = pf.estimate()
    assert after.x == pytest.approx(2.4, abs=0.1)
    assert after.covariance[0] > 4 * before[0]


def test_the_field_model_measures_from_the_lines_of_the_kidsize_field() -> None:
    on = np.array([KIDSIZE.half_length, 0.0, -KIDSIZE.half_length + KIDSIZE.goal_area_length,
                   KIDSIZE.centre_circle_diameter / 2])
    ys = np.array([2.0, KIDSIZE.half_width, 0.5, 0.0])
    assert FIELD.line_distance(on, ys) == pytest.approx(0.0, abs=0.015)
    # The penalty mark: 0.5 m before the penalty area's front line.
    mark = KIDSIZE.half_length - KIDSIZE.penalty_mark_distance
    assert FIELD.line_distance(np.array([mark]), np.array([0.0]))[0] == pytest.approx(
        KIDSIZE.penalty_area_length - KIDSIZE.penalty_mark_distance, abs=0.015)


def _points(points: np.ndarray, stamp_ns: int = 0) -> PointCloud2:
    return points_message(points, stamp=to_msg(stamp_ns))


def _odom(x: float, y: float, yaw: float) -> Odometry:
    odom = Odometry()
    odom.pose.pose.position.x, odom.pose.pose.position.y = x, y
    odom.pose.pose.orientation = _yaw_quaternion(yaw)
    return odom


def test_the_component_corrects_a_wrong_start_from_what_it_sees_and_says_it_is_the_filter(
        ) -> None:
    node = TestHandle("localization", parameters={
        "initial_pose": [-1.6, 0.6, 0.1], "initial_sigma": [0.5, 0.2], "seed": 4,
        "heading_from_imu": False})
    Localization(node)
    assert [m.data for m in node.published("localization/source")] == [PARTICLE_FILTER]
    truth = (-2.0, 1.0, 0.0)
    rng = np.random.default_rng(4)
    node.inject("odom", _odom(0.0, 0.0, 0.0))
    for k in range(1, 31):
        node.inject("odom", _odom(0.0, 0.0, 0.02 * k))  # turning slowly on the spot
        lines, posts = observe((truth[0], truth[1], truth[2] + 0.02 * k), rng)
        node.inject("landmarks/lines", _points(lines))
        node.inject("landmarks/posts", _points(posts))
        node.advance(0.1)
    last = node.published("localization/pose")[-1]
    assert isinstance(last, PoseWithCovarianceStamped)
    assert last.header.frame_id == "field"
    p = last.pose.pose
    assert math.hypot(p.position.x - truth[0], p.position.y - truth[1]) < 0.15
    assert abs(wrap(yaw_of(p.orientation) - 0.6)) < math.radians(5)
    assert 0 < last.pose.covariance[0] < 0.05 and last.pose.covariance[35] > 0
    assert len(node.published("localization/pose")) == 30  # rate_hz 10 over 3 s


def test_landmark_points_round_trip_and_a_message_of_other_points_is_refused_not_fatal(
        ) -> None:
    points = np.array([[1.25, -0.5], [3.0, 0.75]])
    assert read_points(points_message(points, stamp=to_msg(0))) == pytest.approx(points)
    assert read_points(points_message(np.zeros((0, 2)), stamp=to_msg(0))).shape == (0, 2)
    node = TestHandle("localization")
    localization = Localization(node)
    other = PointCloud2(height=1, width=1, point_step=4, row_step=4, data=[0, 0, 0, 0],
                        fields=[PointField(name="intensity", offset=0,
                                           datatype=PointField.FLOAT32, count=1)])
    node.inject("landmarks/lines", other)
    node.inject("landmarks/posts", other)
    assert localization.lines_used == localization.posts_used == 0
    errors = [text for level, text in node.records if level == "error"]
    assert len(errors) == 2 and "need x, y, z float32" in errors[0]
    node.inject("landmarks/lines", _points(points))
    assert localization.lines_used == 2


def test_nothing_seen_while_kicking_getting_up_or_down_is_weighed() -> None:
    # The landmarks assume the walk's crouch: on one leg, on the ground, they are wrong.
    node = TestHandle("localization")
    localization = Localization(node)
    points = _points(np.array([[1.0, 0.0], [1.5, 0.5]]))
    for topic, message in [("motion/kick/active", Bool(data=True)),
                           ("motion/getup/active", Bool(data=True)),
                           ("motion/kick/active", Bool(data=False)),
                           ("fall/state", String(data="fallen"))]:
        node.inject(topic, message)
        node.inject("landmarks/lines", points)
        assert localization.lines_used == 0, topic
    node.inject("motion/getup/active", Bool(data=False))
    node.inject("fall/state", String(data="standing"))
    node.inject("landmarks/lines", points)
    assert localization.lines_used == 2


@pytest.mark.parametrize("parameters", [
    {"initial_pose": [1.0, 2.0]}, {"own_half": "left"}, {"initial_sigma": [-1.0, 0.1]},
    {"particles": 3}, {"line_sigma_m": 0.0}])
def test_the_component_refuses_parameters_it_cannot_use(parameters: dict[str, object]) -> None:
    with pytest.raises(SimConfigError):
        Localization(TestHandle("localization", parameters=parameters))


def _truth(x: float, y: float, yaw: float, stamp_ns: int) -> PoseStamped:
    truth = PoseStamped()
    truth.header.stamp = to_msg(stamp_ns)
    truth.header.frame_id = "field"
    truth.pose.position.x, truth.pose.position.y = x, y
    truth.pose.orientation = _yaw_quaternion(yaw)
    return truth


def _noisy_run(seed: int, *, truth_clock_off_s: float = 0.0
               ) -> list[PoseWithCovarianceStamped]:
    off_ns = round(truth_clock_off_s * 1e9)
    node = TestHandle("localization", parameters={"seed": seed, "sigma_m": 0.05,
                                                  "sigma_rad": 0.02, "delay_s": 0.2})
    NoisyTruthPose(node)
    assert [m.data for m in node.published("localization/source")] == [NOISY_GROUND_TRUTH]
    for _ in range(2000):  # 20 s of truth at 100 Hz: the robot at (1, -2) facing 0.5 rad
        node.inject("ground_truth/robot", _truth(1.0, -2.0, 0.5, node.now_ns() + off_ns))
        node.advance(0.01)
        for published in node.published("localization/pose")[-1:]:
            # Each pose is the truth of delay_s ago (stamped with that moment), not newer.
            assert from_msg(published.header.stamp) <= node.now_ns() + off_ns - 200_000_000
    return node.published("localization/pose")


def test_noisy_ground_truth_adds_seeded_noise_and_delay() -> None:
    first = _noisy_run(seed=5)
    assert 195 <= len(first) <= 200  # 10 Hz, none until the first truth is delay_s old
    xs = [m.pose.pose.position.x for m in first]
    headings = [yaw_of(m.pose.pose.orientation) for m in first]
    assert statistics.fmean(xs) == pytest.approx(1.0, abs=0.015)
    assert statistics.stdev(xs) == pytest.approx(0.05, rel=0.25)
    assert statistics.stdev(headings) == pytest.approx(0.02, rel=0.25)
    assert first[0].pose.covariance[0] == pytest.approx(0.05 ** 2)
    again, other = _noisy_run(seed=5), _noisy_run(seed=6)
    assert [m.pose.pose.position.x for m in again] == xs
    assert [m.pose.pose.position.x for m in other] != xs


@pytest.mark.parametrize("off_s", [-0.8, 0.8])
def test_noisy_ground_truth_keeps_its_rate_when_the_truths_clock_is_not_the_robots(
        off_s: float) -> None:
    """The match's robots run on clocks off the world's by up to 0.8 s: the delay counts
    from arrival, the stamp stays the world's."""
    poses = _noisy_run(seed=5, truth_clock_off_s=off_s)
    assert 195 <= len(poses) <= 200
    assert [m.pose.pose.position.x for m in poses] == [
        m.pose.pose.position.x for m in _noisy_run(seed=5)]


def test_the_error_monitor_compares_each_estimate_with_the_truth_at_its_stamp() -> None:
    node = TestHandle("pose_error")
    monitor = PoseErrorMonitor(node)
    node.inject("ground_truth/robot", *[_truth(0.1 * k, 0.0, 0.0, k * 10_000_000)
                                        for k in range(10)])
    estimate = PoseWithCovarianceStamped()
    estimate.header.stamp = to_msg(50_000_000)  # the truth then: (0.5, 0)
    estimate.pose.pose.position.x, estimate.pose.pose.position.y = 0.8, 0.4
    estimate.pose.pose.orientation = _yaw_quaternion(0.1)
    node.inject("localization/pose", estimate)
    node.inject("localization/source", String(data=NOISY_GROUND_TRUTH))
    summary = monitor.errors.summary()
    assert monitor.errors.source == NOISY_GROUND_TRUTH
    assert summary["estimates"] == 1
    assert summary["position_error_mean_m"] == pytest.approx(0.5)
    assert summary["heading_error_mean_deg"] == pytest.approx(math.degrees(0.1))
    estimate.header.stamp = to_msg(900_000_000)  # no truth near that moment: not scored
    node.inject("localization/pose", estimate)
    assert monitor.errors.summary()["estimates"] == 1


def test_an_estimate_newer_than_the_truth_waits_for_it_and_is_scored_between_samples(
        ) -> None:
    # As in the team match: the robot's estimate of a moment arrives before the world's
    # truth of it, whose samples (10 Hz of a world slower than real time) lie 0.2 s apart.
    node = TestHandle("pose_error")
    monitor = PoseErrorMonitor(node)
    node.inject("ground_truth/robot", _truth(0.0, 0.0, 0.0, 0), _truth(0.2, 0.0, 0.2, 200_000_000))
    estimate = PoseWithCovarianceStamped()
    estimate.header.stamp = to_msg(300_000_000)  # the truth then: (0.3, 0), heading 0.3
    estimate.pose.pose.position.x, estimate.pose.pose.position.y = 0.3, 0.4
    estimate.pose.pose.orientation = _yaw_quaternion(0.2)
    node.inject("localization/pose", estimate)
    assert monitor.errors.summary()["estimates"] == 0  # its truth is still on the way
    node.inject("ground_truth/robot", _truth(0.4, 0.0, 0.4, 400_000_000))
    summary = monitor.errors.summary()
    assert summary["estimates"] == 1
    assert summary["position_error_mean_m"] == pytest.approx(0.4)
    assert summary["heading_error_mean_deg"] == pytest.approx(math.degrees(0.1))


@pytest.mark.parametrize(("neck_yaw", "neck_pitch", "roll", "pitch", "yaw"), [
    (0.0, 0.45, 0.0, 0.0, 0.0), (0.6, 0.9, 0.05, 0.08, 1.0), (-0.8, 0.3, -0.04, 0.12, -2.5)])
def test_the_camera_pose_from_the_neck_and_imu_matches_the_robots_kinematics(
        neck_yaw: float, neck_pitch: float, roll: float, pitch: float, yaw: float) -> None:
    plant = MujocoPlant()
    model, data = plant.model, plant.data
    torso_height = 0.37
    cr, sr, cp, sp = math.cos(roll / 2), math.sin(roll / 2), math.cos(pitch / 2), math.sin(
        pitch / 2)
    cy, sy = math.cos(yaw / 2), math.sin(yaw / 2)
    q = Quaternion(w=cr * cp * cy + sr * sp * sy, x=sr * cp * cy - cr * sp * sy,
                   y=cr * sp * cy + sr * cp * sy, z=cr * cp * sy - sr * sp * cy)
    data.qpos[0:7] = [0.3, -0.2, torso_height, q.w, q.x, q.y, q.z]
    data.qpos[model.joint("neck_yaw").qposadr[0]] = neck_yaw
    data.qpos[model.joint("neck_pitch").qposadr[0]] = neck_pitch
    mujoco.mj_forward(model, data)
    camera = CameraPose.from_kinematics(neck_yaw=neck_yaw, neck_pitch=neck_pitch,
                                        orientation=q, torso_height=torso_height)
    # MuJoCo's camera in the level frame under the torso, turned to the torso's heading.
    torso = data.xmat[model.body("torso").id].reshape(3, 3)
    heading = math.atan2(torso[1, 0], torso[0, 0])
    c, s = math.cos(heading), math.sin(heading)
    to_level = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])
    cam = model.camera("head_camera").id
    position = to_level @ (data.cam_xpos[cam] - np.array([0.3, -0.2, 0.0]))
    assert camera.position == pytest.approx(position, abs=1e-9)
    # MuJoCo's camera looks along its -z with y up: forward, left, up = -z, -x, y.
    axes = to_level @ data.cam_xmat[cam].reshape(3, 3)
    expected = np.stack([-axes[:, 2], -axes[:, 0], axes[:, 1]], axis=1)
    assert camera.rotation == pytest.approx(expected, abs=1e-9)


def test_the_landmark_detector_skips_an_image_it_cannot_read_and_says_why() -> None:
    node = TestHandle("landmarks")
    detector = LandmarkDetector(node)
    node.inject("camera/image_raw", Image(height=2, width=2, encoding="bgr8", step=6,
                                          data=[0] * 12))
    assert detector.rejected == 1 and detector.frames == 0
    assert node.published("landmarks/lines") == []
    assert any("need rgb8" in text for level, text in node.records if level == "warning")


def test_an_unknown_localization_source_is_refused_with_the_choices() -> None:
    with test_container() as container, pytest.raises(SimConfigError, match="particle_filter"):
        add_localization(container, namespace="/robot", source="gps")
