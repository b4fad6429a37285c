"""Several robots in one MuJoCo world: names, colours, start poses, contacts, per-robot plants,
and the world component serving each robot's bus, sensors and ground truth (lockstep)."""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterator
from pathlib import Path

import mujoco
import numpy as np
import pytest
from geometry_msgs.msg import Point, PoseStamped, Quaternion
from sensor_msgs.msg import Image, Imu
from std_msgs.msg import String

from efficient_comm import Container, latched_qos
from efficient_comm.testing import TestHandle, test_container
from humanoid_sim.errors import SimConfigError
from humanoid_sim.joints import JOINTS
from humanoid_sim.soccer.arbiter import MotionArbiter
from humanoid_sim.soccer.fall import FallDetector
from humanoid_sim.world import (
    DEFAULT_START,
    ROBOT_NAMES,
    TEAM_COLOURS,
    Pose2D,
    World,
    build_model,
)
from humanoid_sim.world_simulator import WorldSimulator, add_team

NECK_YAW = next(i for i, name in JOINTS.items() if name == "neck_yaw")


def _robot_of(model: mujoco.MjModel, geom: int) -> str:
    """The robot a geom belongs to ('' for the field and the ball)."""
    robot, slash, _ = model.body(int(model.geom_bodyid[geom])).name.partition("/")
    return robot if slash else ""


def _penetration_between(world: World, a: str, b: str) -> float:
    """How deep robots ``a`` and ``b`` overlap (m; 0 if they do not touch)."""
    model, data = world.model, world.data
    return max((-c.dist for c in data.contact[: data.ncon]
                if {_robot_of(model, c.geom1), _robot_of(model, c.geom2)} == {a, b}),
               default=0.0)


def test_six_robots_have_prefixed_names_team_colours_and_their_start_poses() -> None:
    world = World(DEFAULT_START, ball=(0.5, -0.5))
    model = world.model
    assert list(world.robots) == list(ROBOT_NAMES)
    assert model.nu == 6 * len(JOINTS) and model.nsensor == 6 * 3
    for name, start in DEFAULT_START.items():
        for what, kind in (("torso", "body"), ("head_camera", "camera"), ("root", "joint"),
                           ("l_knee", "actuator"), ("imu_gyro", "sensor")):
            getattr(model, kind)(f"{name}/{what}")  # KeyError if missing
        torso = model.body(f"{name}/torso")
        colour = TEAM_COLOURS[name.rstrip("123")]
        assert model.geom_rgba[torso.geomadr[0]].tolist() == pytest.approx(colour)
        position, quat = world.torso_pose(name)
        assert position[:2] == pytest.approx([start.x, start.y])
        heading = math.atan2(2 * quat[0] * quat[3], 1 - 2 * quat[3] ** 2)
        assert math.cos(heading - start.heading) == pytest.approx(1.0)
    assert world.ball_pose()[0] == pytest.approx([0.5, -0.5, 0.07])
    # The field is the one-robot model's, unprefixed.
    model.geom("goal_line_opponent")
    assert model.opt.timestep == 0.002


@pytest.mark.parametrize(("robots", "match"), [
    ({"blue1": Pose2D(-1, 0, 0), "red2": Pose2D(5.0, 0.0, 0.0)}, r"robot red2: \(5, 0\) is not "
                                                                 r"on the field"),
    ({"blue1": Pose2D(0, -3.2, 0)}, "robot blue1: .* y within ±3 m"),
    ({"blue1": Pose2D(math.nan, 0, 0)}, "robot blue1: .* not finite"),
    ({"green1": Pose2D(0, 0, 0)}, "robot 'green1': robots are named blue1, .*red3"),
    ({"blue4": Pose2D(0, 0, 0)}, "robot 'blue4'"),
    ({}, "at least one robot"),
    ({"blue1": Pose2D(0, 0, 0), "red1": Pose2D(0.1, 0.1, 0)}, "robots blue1 and red1 start "
                                                              "0.14 m apart"),
])
def test_a_bad_start_is_refused_naming_the_robot(robots: dict[str, Pose2D], match: str) -> None:
    with pytest.raises(SimConfigError, match=match):
        build_model(robots)


def test_each_robot_drives_only_its_own_servos() -> None:
    world = World({"blue1": Pose2D(-1, 0, 0), "red1": Pose2D(1, 0, math.pi)})
    blue, red = world.robots["blue1"], world.robots["red1"]
    blue.command(NECK_YAW, torque=True, goal_rad=0.8, max_speed_rad_s=4.0)
    red.command(NECK_YAW, torque=True, goal_rad=-0.5, max_speed_rad_s=4.0)
    world.step(0.5)
    assert blue.state(NECK_YAW).position_rad == pytest.approx(0.8, abs=0.05)
    assert red.state(NECK_YAW).position_rad == pytest.approx(-0.5, abs=0.05)
    assert blue.time_s == red.time_s == pytest.approx(0.5)
    blue.push((0.0, 0.0, 200.0), duration_s=0.1)  # only blue's torso is lifted
    world.step(0.05)
    assert blue.torso_height() > red.torso_height() + 0.005


def test_robots_collide_with_each_other_and_with_the_ball() -> None:
    world = World({"blue1": Pose2D(0.0, 0.0, 0.0), "red1": Pose2D(1.0, 0.0, math.pi)},
                  ball=(-1.0, 0.0))
    # Placed facing each other 0.12 m apart: their feet (0.07 m in front of the torso) overlap.
    world.place_robot("red1", Pose2D(0.12, 0.0, math.pi))
    world.step(0.01)
    assert _penetration_between(world, "blue1", "red1") > 0.005
    world.step(0.2)
    assert _penetration_between(world, "blue1", "red1") < 0.001  # contact forces resolved it
    gap = world.torso_pose("red1")[0][0] - world.torso_pose("blue1")[0][0]
    assert gap > 0.125  # pushed apart, not passing through each other
    # The ball rolled at blue1's back stops there instead of rolling through.
    world.place_ball(x=-0.6, y=0.0, velocity=(1.5, 0.0))
    blue_x = world.torso_pose("blue1")[0][0]
    for _ in range(100):
        world.step(0.01)
        assert world.ball_pose()[0][0] < blue_x
    assert world.ball_pose()[0][0] > -0.6  # it got there


def test_placements_are_checked_and_stand_a_robot_up() -> None:
    world = World({"blue1": Pose2D(-1, 0, 0)})
    world.robots["blue1"].push((0.0, 60.0, 0.0), duration_s=0.2)
    world.step(1.5)  # shoved sideways, limp: it falls
    assert world.robots["blue1"].torso_height() < 0.3
    world.place_robot("blue1", Pose2D(2.0, 3.5, math.pi / 2))  # the border strip counts
    position, quat = world.torso_pose("blue1")
    assert position == pytest.approx([2.0, 3.5, 0.4])
    assert quat == pytest.approx([math.cos(math.pi / 4), 0, 0, math.sin(math.pi / 4)])
    with pytest.raises(SimConfigError, match="no robot 'red1'"):
        world.place_robot("red1", Pose2D(0, 0, 0))
    with pytest.raises(SimConfigError, match=r"robot blue1: \(9, 0\) is not on the field or "
                                             "its border strip"):
        world.place_robot("blue1", Pose2D(9.0, 0.0, 0.0))
    with pytest.raises(SimConfigError, match="robot ball"):
        world.place_ball(x=0.0, y=-8.0)


# -- the world component ----------------------------------------------------------------------


@pytest.fixture
def container() -> Iterator[Container]:
    with test_container() as c:
        yield c


def _stand(container: Container, robots: list[str]) -> None:
    """Each robot's motion arbiter (its standing pose) and fall detector (from its IMU)."""
    for name in robots:
        container.add(FallDetector, name="fall_detector", namespace=f"/{name}")
        container.add(MotionArbiter, name="motion", namespace=f"/{name}")


def _heading_quat(heading: float) -> Quaternion:
    return Quaternion(w=math.cos(heading / 2), z=math.sin(heading / 2))


def test_two_robots_each_on_its_own_bus_stand_in_lockstep_and_collide(
        container: Container, tmp_path: Path) -> None:
    robots = ["blue1", "red1"]
    sim, drivers = add_team(container, world={
        "robots": robots, "blue1.pose": [-1.0, 0.0, 0.0], "red1.pose": [1.0, 0.0, math.pi],
        "camera_hz": 0.0, "port_dir": str(tmp_path)})
    _stand(container, robots)
    referee = TestHandle("referee", container=container)
    falls: dict[str, list[String]] = {name: [] for name in robots}
    for name in robots:
        referee.create_subscription(String, f"/{name}/fall/state", falls[name].append,
                                    qos=latched_qos())
    imu: list[Imu] = []
    referee.create_subscription(Imu, "/red1/imu/data", imu.append)
    truth: list[PoseStamped] = []
    referee.create_subscription(PoseStamped, "/ground_truth/red1/pose", truth.append)
    try:
        ports = sim.ports
        assert ports == {name: str(tmp_path / name) for name in robots}
        assert len({Path(p).resolve() for p in ports.values()}) == 2  # a pty each
        container.advance(2.0)
        for name in robots:
            assert drivers[name].status()["present"] == list(JOINTS)
            assert sim.world.robots[name].torso_height() > 0.3  # stands in its stance
            assert falls[name] and falls[name][-1].data == "standing"
        assert len(imu) == 200 and truth[-1].header.frame_id == "field"
        assert truth[-1].pose.position.x == pytest.approx(1.0, abs=0.05)
        # red1's IMU is red1's: it sits square on red1's torso, which faces -x.
        assert imu[-1].header.stamp == truth[-1].header.stamp
        q, r = imu[-1].orientation, truth[-1].pose.orientation
        assert abs(q.w * r.w + q.x * r.x + q.y * r.y + q.z * r.z) == pytest.approx(1, abs=1e-6)
        assert abs(r.z) > 0.99  # heading pi
        # The referee puts red1 right in front of blue1: their feet overlap, they collide.
        place = PoseStamped()
        place.header.frame_id = "red1"
        place.pose.position = Point(x=-0.88, y=0.0, z=5.0)  # z is ignored
        place.pose.orientation = _heading_quat(math.pi)
        referee.inject("/place_robot", place)
        container.advance(0.01)
        assert _penetration_between(sim.world, "blue1", "red1") > 0.005
        container.advance(0.3)
        assert _penetration_between(sim.world, "blue1", "red1") < 0.001
        blue, red = (sim.world.torso_pose(name)[0] for name in robots)
        assert red[0] - blue[0] > 0.125  # pushed apart
        assert truth[-1].pose.position.x == pytest.approx(red[0])
    finally:
        for driver in drivers.values():
            driver.close()
        sim.close()
    assert not any(Path(p).is_symlink() for p in ports.values())


def test_bad_placements_are_logged_and_change_nothing(container: Container) -> None:
    node = TestHandle("world", container=container,
                      parameters={"robots": ["blue2"], "camera_hz": 0.0})
    sim = WorldSimulator(node)
    try:
        before = sim.world.torso_pose("blue2")[0]
        assert before[:2] == pytest.approx([DEFAULT_START["blue2"].x, DEFAULT_START["blue2"].y])
        for frame_id, x in (("red3", 0.0), ("blue2", 20.0), ("", 0.0)):
            place = PoseStamped()
            place.header.frame_id = frame_id
            place.pose.position.x = x
            node.inject("place_robot", place)
        node.inject("place_ball", Point(x=math.inf, y=0.0))
        errors = [m for level, m in node.records if level == "error"]
        assert len(errors) == 4 and all("ignored" in m for m in errors)
        assert "no robot 'red3'" in errors[0] and "robot blue2: (20, 0)" in errors[1]
        assert sim.world.torso_pose("blue2")[0] == pytest.approx(before)
        node.inject("place_ball", Point(x=1.0, y=2.0))
        assert sim.world.ball_pose()[0] == pytest.approx([1.0, 2.0, 0.07])
    finally:
        sim.close()


@pytest.mark.parametrize(("parameters", "match"), [
    ({"robots": ["blue1", "blue1"]}, "each name once"),
    ({"robots": ["blue1"], "blue1.pose": [0.0, 0.0]}, r"blue1.pose is \[x, y, heading\]"),
    ({"robots": ["blue1", "red1"], "red1.pose": [0.0, 9.0, 0.0]}, "robot red1: .* not on"),
    ({"robots": ["red7"]}, "robot 'red7'"),
])
def test_a_bad_world_is_refused_in_one_line(parameters: dict[str, object], match: str) -> None:
    with pytest.raises(SimConfigError, match=match):
        WorldSimulator(TestHandle("world", parameters={"camera_hz": 0.0, **parameters}))


def test_cameras_share_one_context_and_render_only_when_asked(container: Container) -> None:
    node = TestHandle("world", container=container, parameters={
        "robots": ["blue1", "red1"], "camera_hz": 10.0, "camera_width": 64,
        "camera_height": 48})
    sim = WorldSimulator(node)
    try:
        container.advance(0.5)
        assert sim.frames == 0 and sim.frames_skipped >= 8  # nobody wants a frame (2 robots)
        got: list[Image] = []
        TestHandle("viewer", container=container).create_subscription(
            Image, "/blue1/camera/image_raw", got.append)
        container.advance(1.0)
        assert sim.renderer is not None
        assert sim.renderer.frames == {"blue1/head_camera": 10}  # red1's camera never drawn
        assert len(got) == 10 and (got[-1].width, got[-1].height) == (64, 48)
        image = np.frombuffer(got[-1].data, dtype=np.uint8)
        assert 20 < image.mean() < 200  # a lit scene, not black
        (info,) = node.published("red1/camera/camera_info")
        assert (info.width, info.height) == (64, 48)
    finally:
        sim.close()


@pytest.mark.parametrize("latency_s", [0.03, 0.0])
def test_a_frame_arrives_camera_latency_after_the_instant_it_shows(
        container: Container, latency_s: float) -> None:
    """The world steps on while its render thread draws: a frame is published
    ``camera_latency_s`` after the instant it shows (at a step, so in lockstep at the same
    step of every run), stamped with that instant; 0 publishes it in the tick that took it."""
    sim = WorldSimulator(TestHandle("world", container=container, parameters={
        "robots": ["blue1"], "camera_hz": 10.0, "camera_width": 64, "camera_height": 48,
        "camera_latency_s": latency_s}))
    arrivals: list[tuple[int, int]] = []

    def on_image(msg: Image) -> None:
        stamp = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
        arrivals.append((stamp, container.executor.clock.now_ns()))

    TestHandle("viewer", container=container).create_subscription(
        Image, "/blue1/camera/image_raw", on_image)
    try:
        container.advance(0.5)
        assert len(arrivals) >= 4, arrivals
        assert {arrived - stamp for stamp, arrived in arrivals} == {round(latency_s * 1e9)}
        assert all(b[0] - a[0] == 100_000_000 for a, b in itertools.pairwise(arrivals))
    finally:
        sim.close()


def test_a_camera_latency_beyond_a_second_is_refused() -> None:
    with pytest.raises(SimConfigError, match=r"camera_latency_s is 0\.\.1 s, got 2\.0"):
        WorldSimulator(TestHandle("world", parameters={"robots": ["blue1"],
                                                       "camera_latency_s": 2.0}))


def test_a_robot_camera_without_multisampling_finds_the_ball_straight_ahead() -> None:
    """The team's world renders without multisampling (a software-rendered frame cost twice
    as much with MuJoCo's 4 samples): the ball detector still finds the ball ahead of
    blue1, where it is with the samples, to the pixel."""
    from humanoid_sim.render import OffscreenRenderer
    from humanoid_sim.soccer.vision import BallDetector

    world = World({"blue1": Pose2D(-1.5, 0.0, 0.0)}, ball=(0.0, 0.0))
    assert world.model.vis.quality.offsamples == 0
    mujoco.mj_forward(world.model, world.data)
    found = []
    for samples in (0, 4):
        world.model.vis.quality.offsamples = samples
        renderer = OffscreenRenderer(world.model, width=320, height=240)
        image = np.zeros((240, 320, 3), dtype=np.uint8)
        renderer.render(world.data, image, camera="blue1/head_camera")
        renderer.close()
        found.append(BallDetector(TestHandle("detector")).find(image))
    plain, sampled = found
    assert plain is not None and sampled is not None
    u, v, r = plain
    assert abs(u - 160) < 2 and v > 120 and r > 3  # straight ahead, on the ground
    assert plain == pytest.approx(sampled, abs=1.0)


def test_the_ground_truth_fingerprint_is_the_poses_equal_for_equal_starts() -> None:
    """The fingerprint the seeded match tests compare (``GroundTruthLog``): equal for two
    worlds started alike, different when one robot starts elsewhere (a fingerprint that
    ignored the poses would make every run "the same game")."""
    from humanoid_sim.match_world import GroundTruthLog

    def fingerprint(red1: list[float]) -> str:
        sim = WorldSimulator(TestHandle("world", parameters={
            "robots": ["blue1", "red1"], "camera_hz": 0.0, "red1.pose": red1}))
        try:
            log = GroundTruthLog(["blue1", "red1"])
            log.sample(sim, 0)
            return log.digest()
        finally:
            sim.close()

    assert fingerprint([1.0, 0.0, math.pi]) == fingerprint([1.0, 0.0, math.pi])
    assert fingerprint([1.0, 0.0, math.pi]) != fingerprint([0.3, 0.2, math.pi])
