"""The team match's plan: who plays, where each robot and the ball start for a seed, the
team link's bridge file."""

from __future__ import annotations

import argparse
import math

import pytest

from humanoid_sim.match import (
    bridge_config,
    camera_line,
    robot_names,
    start_poses,
)
from humanoid_sim.world import DEFAULT_START
from soccer_field import KIDSIZE


def test_robots_name_one_team_or_two() -> None:
    assert robot_names("2") == ["blue1", "blue2"]
    assert robot_names("3v3") == ["blue1", "blue2", "blue3", "red1", "red2", "red3"]
    assert robot_names("1v2") == ["blue1", "red1", "red2"]
    for bad in ("4", "0v1", "3v4", "three", ""):
        with pytest.raises(argparse.ArgumentTypeError):
            robot_names(bad)


def test_the_seed_draws_legal_starts_and_seed_0_is_the_default() -> None:
    robots = robot_names("3v3")
    poses, ball = start_poses(robots, 0)
    assert ball == (0.0, 0.0)
    assert all(poses[r] == (DEFAULT_START[r].x, DEFAULT_START[r].y, DEFAULT_START[r].heading)
               for r in robots)
    drawn = [start_poses(robots, seed) for seed in range(1, 21)]
    assert len({(tuple(p.values()), b) for p, b in drawn}) == 20  # every seed its own game
    assert start_poses(robots, 7) == start_poses(robots, 7)
    for poses, ball in drawn:
        for robot, (x, y, heading) in poses.items():
            own_half = x < -0.5 if robot.startswith("blue") else x > 0.5
            assert own_half and abs(x) <= KIDSIZE.half_length - 0.5, (robot, x)
            assert abs(y) <= KIDSIZE.half_width - 0.5 and -math.pi <= heading <= math.pi
        spots = list(poses.values())
        assert all(math.dist(a[:2], b[:2]) >= 0.6 for i, a in enumerate(spots)
                   for b in spots[i + 1:])
        assert abs(ball[0]) <= 1.5 and abs(ball[1]) <= 1.5


def test_a_robots_bridge_file_listens_and_connects_to_its_teammates_within_budget() -> None:
    config = bridge_config("blue2", prefix="match_x_blue", port=7001, teammates=[7000])
    team = config["team"]
    assert team["robot_id"] == "blue2" and team["prefix"] == "match_x_blue"
    assert team["listen"] == ["tcp/127.0.0.1:7001"]
    assert team["connect"] == ["tcp/127.0.0.1:7000"]
    assert team["budget_bytes_per_s"] == 2048
    assert config["topics"][0]["ros2"] == "team/messages"


def test_the_report_says_how_the_camera_images_went() -> None:
    status = {"camera_traffic": {"blue1": [298, 10], "blue2": [301, 0]}}
    assert camera_line(status, "shm").endswith(": blue1 298 (10), blue2 301 (0).")
    assert camera_line(status, "dds") == "Camera images to the robots over DDS."
