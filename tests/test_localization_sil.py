"""Software in the loop: landmarks in rendered images and localization on the whole robot.

The robot runs composed in lockstep (simulator, real servo driver on the emulated bus,
vision, head behaviour, walk engine, ...); ground truth judges what its localization
believes, which never sees the truth (except the noisy stand-in, which is made of it).
"""

from __future__ import annotations

import math
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from geometry_msgs.msg import Twist
from sensor_msgs.msg import PointCloud2

from efficient_comm.testing import TestHandle, test_container
from humanoid_sim.soccer.compose import compose
from humanoid_sim.soccer.landmarks import read_points
from humanoid_sim.soccer.localization import (
    NOISY_GROUND_TRUTH,
    PARTICLE_FILTER,
    FieldModel,
    Localization,
)
from humanoid_sim.soccer.pose_error import PoseErrorMonitor

NAMESPACE = "/robot"


def _torso(robot: object) -> tuple[float, float, float]:
    sim = robot.simulator  # type: ignore[attr-defined]
    body = sim.model.body("torso").id
    x, y = (float(v) for v in sim.data.xpos[body][:2])
    m = sim.data.xmat[body].reshape(3, 3)
    return x, y, math.atan2(m[1, 0], m[0, 0])


def _on_field(points: PointCloud2, pose: tuple[float, float, float]) -> np.ndarray:
    x, y, h = pose
    c, s = math.cos(h), math.sin(h)
    local = read_points(points)
    return np.stack([x + c * local[:, 0] - s * local[:, 1],
                     y + s * local[:, 0] + c * local[:, 1]], axis=1)


@pytest.mark.parametrize(("robot_pose", "ball", "posts"), [
    ([2.0, 0.3, 0.1], [3.0, 0.0], 2),  # before the opponent goal, both posts in view
    ([-2.0, 1.0, 0.3], [-0.5, 1.2], 2),  # the same goal from 6.5 m, over the centre circle
    ([-3.0, -1.0, 2.8], [-3.8, -0.6], 1),  # the own goal, its other post out of the image
])
def test_landmarks_seen_in_rendered_images_lie_where_the_field_has_them(
        robot_pose: list[float], ball: list[float], posts: int) -> None:
    field = FieldModel()
    with test_container(guard_mutation=False) as container:
        robot = compose(container, simulator={"robot_pose": robot_pose, "ball_position": ball},
                        play=False, localization=PARTICLE_FILTER)
        probe = TestHandle("probe", namespace=NAMESPACE, container=container)
        seen: dict[str, list[PointCloud2]] = {"posts": [], "lines": []}
        for kind, store in seen.items():
            probe.create_subscription(PointCloud2, f"landmarks/{kind}", store.append)
        container.advance(1.0)  # the head has turned to the ball; about 30 images
        truth = _torso(robot)
        assert len(seen["lines"]) >= 25
        # The last image: line points on the lines, post feet at the posts.
        lines = _on_field(seen["lines"][-1], truth)
        assert len(lines) >= 40
        distance = field.line_distance(lines[:, 0], lines[:, 1])
        assert np.median(distance) < 0.04 and np.percentile(distance, 80) < 0.06
        feet = _on_field(seen["posts"][-1], truth)
        assert len(feet) == posts
        for foot in feet:  # the posts' axes are 5 cm outside the goal's clear width
            assert np.min(np.hypot(*(field.posts - foot).T)) < 0.15, feet


#: Where the robot stands, and where its filter is told it stands: 0.7 m and 14 degrees
#: off, as if misplaced. Odometry alone can never remove that offset.
START = (-2.0, 1.0, 0.3)
TOLD = [-1.5, 0.5, 0.55]
#: The filter must be within this of the truth once it has seen the field for a few
#: seconds: a fifth of the offset, twice a walking robot's sway, about what the line points'
#: scatter (2-4 cm at 1-3 m) allows a filter of 300 particles.
BOUND_M, BOUND_DEG = 0.15, 5.0
SETTLE_S, RUN_S = 4.0, 7.0


@pytest.mark.timeout(300)
def test_the_filter_finds_a_walking_robot_that_odometry_alone_cannot() -> None:
    with test_container(guard_mutation=False) as container:
        robot = compose(container, simulator={"robot_pose": list(START),
                                              "ball_position": [-0.5, 1.2]},
                        play=False, localization=PARTICLE_FILTER,
                        localization_parameters={"initial_pose": TOLD,
                                                 "initial_sigma": [0.5, 0.25]})
        # The same filter, the same wrong start, blind: odometry only.
        blind = {"landmarks/lines": "blind/lines", "landmarks/posts": "blind/posts",
                 "localization/pose": "odometry_only/pose",
                 "localization/source": "odometry_only/source"}
        container.add(Localization, name="odometry_only", namespace=NAMESPACE,
                      remappings=blind, parameters={"initial_pose": TOLD,
                                                    "initial_sigma": [0.5, 0.25]})
        odometry_only: PoseErrorMonitor = container.add(
            PoseErrorMonitor, name="odometry_only_error", namespace=NAMESPACE,
            remappings={"localization/pose": "odometry_only/pose",
                        "localization/source": "odometry_only/source"})
        probe = TestHandle("probe", namespace=NAMESPACE, container=container)
        cmd_vel = probe.create_publisher(Twist, "cmd_vel")
        container.advance(1.0)
        walk = Twist()
        walk.linear.x, walk.angular.z = 0.15, 0.15  # an arc to the left
        cmd_vel.publish(walk)
        container.advance(RUN_S - 1.0)
        assert robot.pose_error is not None
        errors = robot.pose_error.errors
        walked = math.dist(_torso(robot)[:2], START[:2])
    assert errors.source == PARTICLE_FILTER
    assert walked > 0.5
    assert odometry_only.errors.position_m[0] > 0.6  # both started that far off
    settled = errors.since(SETTLE_S).summary()
    blind_settled = odometry_only.errors.since(SETTLE_S).summary()
    assert settled["estimates"] >= 25
    assert settled["position_error_p95_m"] < BOUND_M, settled
    assert settled["heading_error_p95_deg"] < BOUND_DEG, settled
    assert blind_settled["position_error_mean_m"] > 3 * BOUND_M, blind_settled


@pytest.mark.timeout(120)
def test_noisy_ground_truth_stands_in_on_the_same_topic_and_says_so() -> None:
    with test_container(guard_mutation=False) as container:
        robot = compose(container, simulator={"robot_pose": list(START)}, play=False,
                        localization=NOISY_GROUND_TRUTH,
                        localization_parameters={"sigma_m": 0.05, "sigma_rad": 0.02,
                                                 "seed": 3})
        container.advance(2.0)
        assert robot.pose_error is not None
        errors = robot.pose_error.errors
        summary = errors.summary()
    assert errors.source == NOISY_GROUND_TRUTH
    assert summary["estimates"] >= 15
    # Two-dimensional Gaussian noise of 5 cm: 6.3 cm on average (the robot stands still,
    # so the delay adds nothing).
    assert 0.03 < summary["position_error_mean_m"] < 0.1, summary
    assert summary["heading_error_mean_deg"] < 3.0, summary


@pytest.mark.timeout(180)
@pytest.mark.parametrize("source", [PARTICLE_FILTER, NOISY_GROUND_TRUTH])
def test_the_demo_report_says_which_localization_ran_and_its_error(tmp_path: Path,
                                                                   source: str) -> None:
    report = tmp_path / "report.md"
    result = subprocess.run(
        [sys.executable, "-m", "humanoid_sim.demo", "--lockstep", "--no-dds", "--duration", "3",
         "--localization", source, "--report", str(report)],
        capture_output=True, text=True, timeout=150, check=False,
    )
    assert result.returncode == 0, result.stdout + result.stderr
    row = next(line for line in report.read_text().splitlines()
               if line.startswith("| localization (vs ground truth) |"))
    found = re.search(rf"\| {source}: (\d+) estimates, position error mean ([\d.]+) m", row)
    assert found is not None, row
    assert int(found[1]) >= 25 and float(found[2]) < 0.2, row  # 10 Hz; a settled filter


def test_the_demo_refuses_an_unknown_localization_in_one_line(tmp_path: Path) -> None:
    result = subprocess.run(
        [sys.executable, "-m", "humanoid_sim.demo", "--localization", "gps", "--report",
         str(tmp_path / "report.md")],
        capture_output=True, text=True, timeout=60, check=False,
    )
    assert result.returncode == 2
    assert len(result.stderr.strip().splitlines()) == 1, result.stderr
    assert "particle_filter" in result.stderr


@pytest.mark.timeout(300)
@pytest.mark.parametrize(("own_half", "mirrored"), [("-x", False), ("+x", True)])
def test_knowing_only_its_half_the_robot_finds_itself_or_the_fields_mirror_image(
        own_half: str, mirrored: bool) -> None:
    # Standing at START, looking at the ball and the opponent goal beyond it. Told only
    # its half, the filter finds the truth; told the wrong half, the point-symmetric image
    # of the truth, which looks the same on this field: the half is what decides.
    with test_container(guard_mutation=False) as container:
        robot = compose(container, simulator={"robot_pose": list(START),
                                              "ball_position": [-0.5, 1.2]},
                        play=False, localization=PARTICLE_FILTER,
                        localization_parameters={"initial_pose": [0.0], "own_half": own_half,
                                                 "particles": 2000})
        container.advance(5.0)
        assert isinstance(robot.localization, Localization)
        estimate = robot.localization.filter.estimate()
    x, y, heading = START
    if mirrored:
        x, y, heading = -x, -y, heading + math.pi
    assert math.hypot(estimate.x - x, estimate.y - y) < 0.2, estimate
    assert abs(math.remainder(estimate.heading - heading, 2 * math.pi)) < math.radians(5)
