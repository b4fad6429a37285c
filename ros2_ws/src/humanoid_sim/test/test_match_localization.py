"""Localization in the team match: ``--localization`` per robot, each robot's plan (a red
robot's filter starts in its own half, +x), the filter following the referee's placement,
and the ground-truth source saying what it is. The match itself runs in
tests/test_match_localization_sil.py."""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import pytest
from geometry_msgs.msg import PoseStamped, PoseWithCovarianceStamped, Quaternion

from efficient_comm import to_msg
from efficient_comm.testing import TestHandle
from humanoid_sim.match import (
    Child,
    localization_choice,
    localization_plan,
    report,
    robot_plan,
    robot_seed,
)
from humanoid_sim.soccer.laws import kickoff_pose, parse_robot
from humanoid_sim.soccer.localization import (
    GROUND_TRUTH,
    NOISY_GROUND_TRUTH,
    PARTICLE_FILTER,
    Localization,
    TruthPose,
    wrap,
    yaw_of,
)
from soccer_interfaces.msg import GameState, PlayerInfo, TeamInfo


def test_the_localization_is_chosen_for_every_robot_or_per_robot() -> None:
    assert localization_choice("pf") == (PARTICLE_FILTER, {})
    assert localization_choice("blue1=pf,red1=noisy") == (
        None, {"blue1": PARTICLE_FILTER, "red1": NOISY_GROUND_TRUTH})
    assert localization_choice("truth, blue2=particle_filter") == (
        GROUND_TRUTH, {"blue2": PARTICLE_FILTER})
    for bad, says in (("gps", "'gps' is not a localization"), ("blue4=pf", "not a robot"),
                      ("", "need a localization")):
        with pytest.raises(argparse.ArgumentTypeError, match=says):
            localization_choice(bad)


def _plan(robot: str, source: str, start: tuple[float, float, float]) -> dict[str, object]:
    plan = robot_plan(robot, start=start, port="/dev/null", bridge_file=Path("b.yaml"),
                      bag_dir=Path("bags"), status_period_s=1.0, players=1,
                      localization=source, seed=7)
    localization = plan["localization"]
    assert isinstance(localization, dict)
    return localization


def test_each_robots_plan_names_its_source_and_a_red_filter_starts_in_the_plus_x_half(
        ) -> None:
    red = _plan("red1", PARTICLE_FILTER, (2.0, 1.0, math.pi))
    assert red == {"source": PARTICLE_FILTER, "parameters": {
        "initial_pose": [2.0, 1.0, math.pi], "own_half": "+x", "robot": "red1",
        "seed": robot_seed(7, "red1")}}
    blue = _plan("blue2", PARTICLE_FILTER, (-2.0, 1.0, 0.0))
    assert blue["parameters"] == {"initial_pose": [-2.0, 1.0, 0.0], "own_half": "-x",
                                  "robot": "blue2", "seed": robot_seed(7, "blue2")}
    # The truth-based sources read the world's truth as the robot's domain carries it.
    assert _plan("red1", NOISY_GROUND_TRUTH, (2.0, 1.0, 0.0))["parameters"] == {
        "truth_topic": "ground_truth/pose", "seed": robot_seed(7, "red1")}
    assert _plan("red1", GROUND_TRUTH, (2.0, 1.0, 0.0))["parameters"] == {
        "truth_topic": "ground_truth/pose"}


def _game_state(state: int, *, kicking: int) -> GameState:
    msg = GameState(game_state=state, kicking_team=kicking, first_half=True, players_per_team=1)
    msg.teams = [TeamInfo(team_number=number, team_colour=colour, players=[PlayerInfo()])
                 for number, colour in ((1, TeamInfo.COLOUR_BLUE), (2, TeamInfo.COLOUR_RED))]
    return msg


def _pose(node: TestHandle) -> tuple[float, float, float]:
    last = node.published("localization/pose")[-1]
    assert isinstance(last, PoseWithCovarianceStamped)
    p = last.pose.pose
    return p.position.x, p.position.y, yaw_of(p.orientation)


def test_a_red_robots_filter_takes_the_kickoff_spot_the_referee_placed_it_on() -> None:
    # red1 believes it is in blue's half when set begins (illegal for red at a kick-off),
    # so the referee placed it on its spot in the +x half, facing -x: the filter follows.
    node = TestHandle("localization", parameters={
        "robot": "red1", "own_half": "+x", "initial_pose": [-0.8, 1.0, 0.0],
        "initial_sigma": [0.05, 0.05], "seed": 3})
    localization = Localization(node)
    node.inject("game_state", _game_state(GameState.STATE_READY, kicking=1))
    node.advance(0.2)
    assert math.dist(_pose(node)[:2], (-0.8, 1.0)) < 0.1  # not placed yet
    node.inject("game_state", _game_state(GameState.STATE_SET, kicking=1))
    node.advance(0.2)
    spot = kickoff_pose(parse_robot("red1"), first_half=True, kicking=False)
    assert spot[0] > 0  # red defends +x in the first half
    x, y, heading = _pose(node)
    assert math.dist((x, y), spot[:2]) < 0.1, (x, y, spot)
    assert abs(wrap(heading - spot[2])) < 0.2
    node.advance(1.0)  # once per placement, not at every estimate
    assert localization.placements == 1


def test_the_ground_truth_source_passes_the_truth_on_and_says_what_it_is() -> None:
    node = TestHandle("localization", parameters={"truth_topic": "ground_truth/pose",
                                                  "pose_sigma_m": 0.2})
    TruthPose(node)
    assert [m.data for m in node.published("localization/source")] == [GROUND_TRUTH]
    truth = PoseStamped()
    truth.header.stamp = to_msg(123_000_000)
    truth.pose.position.x, truth.pose.position.y = 1.5, -0.5
    truth.pose.position.z = 0.36
    truth.pose.orientation = Quaternion(w=math.cos(1.0), z=math.sin(1.0))
    node.inject("ground_truth/pose", truth)
    out = node.published("localization/pose")[-1]
    assert isinstance(out, PoseWithCovarianceStamped)
    assert out.header.stamp == truth.header.stamp and out.header.frame_id == "field"
    assert _pose(node) == pytest.approx((1.5, -0.5, 2.0))
    assert out.pose.pose.position.z == 0.0
    assert out.pose.covariance[0] == pytest.approx(0.04)


def test_the_report_gives_each_robots_source_and_errors() -> None:
    def child(name: str, status: dict[str, object]) -> Child:
        return Child(name, proc=None, log=Path(f"{name}.log"), status=status)  # type: ignore[arg-type]

    figures = {"estimates": 12, "position_error_mean_m": 0.5, "position_error_p95_m": 0.7,
               "position_error_max_m": 0.9, "heading_error_mean_deg": 3.0,
               "heading_error_p95_deg": 5.0}
    robots = {"blue1": child("blue1", {"localization": {"source": PARTICLE_FILTER,
                                                        "errors": figures}}),
              "red1": child("red1", {"localization": {"source": NOISY_GROUND_TRUTH,
                                                      "errors": {"estimates": 0,
                                                                 "position_error_mean_m":
                                                                 math.nan}}})}
    args = argparse.Namespace(seed=0, out_dir=Path("out"), lockstep=False,
                              team_link="on", camera_transport="shm")
    text = report(["blue1", "red1"], args,
                  child("world", {}), robots, 10.0)
    assert ("- blue1: particle_filter, 12 estimates; position error mean 0.500 m, p95 "
            "0.700 m, max 0.900 m; heading error mean 3.0°, p95 5.0°") in text
    assert "- red1: noisy_ground_truth, 0 estimates; position error mean - m" in text


def test_the_roles_hysteresis_reaches_each_robots_team_layer_only_when_given() -> None:
    def team(margin: float | None = None, hold: float | None = None) -> object:
        return robot_plan("blue2", start=(0.0, 0.0, 0.0), port="/dev/null",
                          bridge_file=Path("b.yaml"), bag_dir=Path("bags"), status_period_s=1.0,
                          players=2, role_margin_s=margin, role_min_hold_s=hold)["team"]

    assert team() == {"team_number": 1, "player_number": 2, "goalie_number": 0}
    assert team(0.0, 0.0) == {
        "team_number": 1, "player_number": 2, "goalie_number": 0, "role_margin_s": 0.0,
        "role_min_hold_s": 0.0}


def test_each_robots_localization_noise_has_a_seed_of_its_own_that_repeats() -> None:
    """Teammates given the match's one seed drew identical noise, sample for sample (the
    newcomer's blue1 and blue2 noisy_ground_truth errors): each robot's seed is its own,
    and the same (seed, robot) gives the same seed in every run."""
    seeds = {robot: localization_plan(robot, NOISY_GROUND_TRUTH, start=(0.0, 0.0, 0.0),
                                      seed=7)["parameters"]["seed"]
             for robot in ("blue1", "blue2", "red1")}
    assert len(set(seeds.values())) == 3, seeds
    assert seeds["blue1"] == robot_seed(7, "blue1") == 823673908  # in every process
    assert robot_seed(8, "blue1") != seeds["blue1"]
    filters = {robot: localization_plan(robot, PARTICLE_FILTER, start=(0.0, 0.0, 0.0),
                                        seed=7)["parameters"]["seed"]
               for robot in ("blue1", "blue2")}
    assert filters["blue1"] != filters["blue2"]
