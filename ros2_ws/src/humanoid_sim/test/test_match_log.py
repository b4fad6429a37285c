"""The match's merged log: robots' bags on their own clocks and the world's ground truth.

Two robots whose clocks are off by +250 ms and -400 ms (and drift) synchronise to the world
over a lossy simulated link (team_clock's SimTeam, a manual clock) and log, on their own
clocks, events every robot sees at one true instant; the world logs the ground truth of
each instant on its clock, with no clock estimate (the reference measures nothing).
Merged, the robots' events and the ground truth line up within 1 ms.
"""

from __future__ import annotations

import subprocess
from pathlib import Path

import pytest
from geometry_msgs.msg import PoseStamped
from rclpy.serialization import deserialize_message, serialize_message

from efficient_comm import from_msg, to_msg
from humanoid_sim.match_log import main, merge_match
from rosbag2_layout import BagReader, BagWriter
from team_clock import MergeError, NoEstimateError
from team_clock.testing import SimDelay, SimTeam, flash_times

MS = 1_000_000
SKEWS = {"world": (0, 0.0), "blue1": (250 * MS, 50.0), "red1": (-400 * MS, -30.0)}
POSE = "geometry_msgs/msg/PoseStamped"


def _ground_truth(path: Path, truth: dict[str, int]) -> Path:
    """The world's bag: the ball's pose at each true instant, on the world's clock."""
    with BagWriter(path, min_free_bytes=0) as writer:
        for name, t in sorted(truth.items(), key=lambda item: item[1]):
            pose = PoseStamped()
            pose.header.stamp, pose.header.frame_id = to_msg(t), "field"
            pose.pose.position.x = float(name.removeprefix("e"))
            writer.write("/ground_truth/ball", POSE, serialize_message(pose), t)
    return path


@pytest.fixture(scope="module")
def match(tmp_path_factory: pytest.TempPathFactory) -> tuple[dict[str, Path], Path, dict[str, int]]:
    directory = tmp_path_factory.mktemp("match")
    team = SimTeam(SKEWS, reference="world", links=[("world", "blue1"), ("world", "red1")],
                   loss=0.2, seed=4, delay=SimDelay(min_s=0.001, jitter_s=0.002))
    paths, truth = team.record_flashes(directory, events=20, seed=4)
    world = _ground_truth(directory / "world_truth", truth)
    return {robot: paths[robot] for robot in ("blue1", "red1")}, world, truth


def _truth_in(merged: Path) -> dict[str, tuple[int, int]]:
    """``{event: (log time, header stamp)}`` of the merged ground truth."""
    out = {}
    for message in BagReader(merged).messages():
        if message.topic == "/world/ground_truth/ball":
            pose = deserialize_message(message.data, PoseStamped)
            out[f"e{round(pose.pose.position.x)}"] = (message.log_time_ns,
                                                      from_msg(pose.header.stamp))
    return out


def test_robots_and_ground_truth_line_up_within_1ms(match, tmp_path: Path) -> None:
    robots, world, truth = match
    unmerged = flash_times(robots["blue1"])[""]
    assert all(abs(unmerged[e][0] - t - 250 * MS) < 5 * MS for e, t in truth.items())
    report = merge_match(robots, world, tmp_path / "merged")
    assert [r.namespace for r in report.robots] == ["world", "blue1", "red1"]
    assert {r.model.reference for r in report.robots} == {"world"}
    events, ground_truth = flash_times(tmp_path / "merged"), _truth_in(tmp_path / "merged")
    assert set(ground_truth) == set(truth) == set(events["blue1"]) == set(events["red1"])
    for event, (gt_log, gt_stamp) in ground_truth.items():
        assert gt_log == gt_stamp == truth[event]  # the world's clock is the reference
        for robot in ("blue1", "red1"):
            log_time, stamp = events[robot][event]
            assert abs(log_time - gt_log) < 1 * MS, (robot, event, (log_time - gt_log) / MS)
            assert abs(stamp - gt_stamp) < 1 * MS  # header stamps moved as well


def test_a_world_that_recorded_its_own_estimates_merges_alike(tmp_path: Path) -> None:
    team = SimTeam(SKEWS, reference="world", links=[("world", "blue1"), ("world", "red1")],
                   loss=0.0, seed=2)
    paths, truth = team.record_flashes(tmp_path, events=5, seed=2)
    report = merge_match({"blue1": paths["blue1"]}, paths["world"], tmp_path / "merged")
    assert report.robots[0].model.robot == "world"
    assert len(report.robots[0].model.knots) > 1  # its recorded estimates, not the identity
    events = flash_times(tmp_path / "merged")
    for event, t in truth.items():
        assert abs(events["world"][event][0] - t) < 1 * MS
        assert abs(events["blue1"][event][0] - t) < 1 * MS


def test_robots_aligned_to_another_reference_or_none_are_refused(match, tmp_path) -> None:
    robots, world, _ = match
    # The world named otherwise than the reference the robots synchronised to.
    with pytest.raises(MergeError, match=r"different reference robots \['arena', 'world'\]"):
        merge_match(robots, world, tmp_path / "m1", world_name="arena")
    assert not (tmp_path / "m1").exists()
    with pytest.raises(NoEstimateError):
        merge_match({"blue1": world}, world, tmp_path / "m2")  # a bag without estimates
    assert not (tmp_path / "m2").exists()


def test_the_command_merges_and_says_bad_input_in_one_line(match, tmp_path, capsys) -> None:
    robots, world, _ = match
    args = [f"{name}={path}" for name, path in robots.items()]
    assert main(["-o", str(tmp_path / "m"), "--world", str(world), *args]) == 0
    assert "merged" in capsys.readouterr().out
    assert main(["-o", str(tmp_path / "m"), "--world", str(world), *args]) == 1
    assert capsys.readouterr().err.startswith("match_log: error: ")  # exists: not overwritten
    assert main(["-o", str(tmp_path / "m3"), "--world", str(tmp_path / "none"), *args]) == 1
    assert "match_log: error: " in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["-o", str(tmp_path / "m4"), "--world", str(world), "blue1"])
    assert "ROBOT=BAG" in capsys.readouterr().err


def test_the_installed_command_runs_as_typed(match, tmp_path) -> None:
    robots, world, _ = match
    install = Path(__file__).resolve().parents[3] / "install" / "humanoid_sim" / "lib"
    done = subprocess.run([str(install / "humanoid_sim" / "match_log"), "-o",
                           str(tmp_path / "m"), "--world", str(world),
                           *(f"{name}={path}" for name, path in robots.items())],
                          capture_output=True, text=True, timeout=60, check=False)
    assert done.returncode == 0, done.stderr
    assert "/blue1:" in done.stdout and "/world:" in done.stdout


def test_a_lockstep_robot_on_the_worlds_time_merges_as_it_is(match, tmp_path) -> None:
    """In lockstep every process runs on the world's simulated time: a robot's bag needs no
    estimate (its clock sync has no offset to find) and keeps its times."""
    _, world, truth = match
    merge_match({"blue1": world}, world, tmp_path / "m", on_world_time=["blue1"])
    times = sorted(m.log_time_ns for m in BagReader(tmp_path / "m").messages()
                   if m.topic == "/blue1/ground_truth/ball")
    assert times == sorted(truth.values())
