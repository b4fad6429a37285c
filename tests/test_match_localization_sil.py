"""Localization in the team match, as a user starts it: each robot runs the source
``--localization`` names for it, says so on ``localization/source``, and the report prints,
per robot, which source ran and its error against ground truth.

One short match (two teammates, real time, cameras at 5 Hz): blue1 runs the particle filter,
blue2 noisy ground truth. A ``--localization`` naming a robot that is not in the match is
one line and exit status 2.
"""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

from efficient_comm.testing import isolated_domain_id, ros_env

from ._match import MatchProcess


def test_a_localization_for_a_robot_not_in_the_match_is_one_line_and_status_2() -> None:
    done = subprocess.run([sys.executable, "-m", "humanoid_sim.match", "--robots", "2",
                           "--localization", "noisy,red1=pf"],
                          capture_output=True, text=True, timeout=60,
                          env=ros_env(isolated_domain_id()))
    assert done.returncode == 2, done
    assert done.stdout == "" and len(done.stderr.splitlines()) == 1, done.stderr
    assert "--localization names red1, not in this match" in done.stderr, done.stderr


@pytest.mark.timeout(240)
def test_each_robot_runs_the_localization_chosen_for_it_and_the_report_measures_it(
        tmp_path: Path) -> None:
    report = tmp_path / "report.md"
    with MatchProcess(["--robots", "2", "--duration", "45", "--ready-s", "4",
                       "--camera-hz", "5", "--stats-period", "1",
                       "--localization", "blue1=pf,blue2=noisy",
                       "--out-dir", str(tmp_path / "out"), "--report", str(report)],
                      cwd=tmp_path) as match:
        match.wait(200)
    assert "localization: blue1 particle_filter, blue2 noisy_ground_truth" in (
        match.output()), match.tail()
    text = report.read_text()
    rows = {m["robot"]: m for m in re.finditer(
        r"^- (?P<robot>blue[12]): (?P<source>\w+), (?P<estimates>\d+) estimates; "
        r"position error mean (?P<mean>[\d.]+) m, p95 [\d.]+ m, max [\d.]+ m; "
        r"heading error mean (?P<heading>[\d.]+)°, p95 [\d.]+°$", text, re.MULTILINE)}
    assert set(rows) == {"blue1", "blue2"}, text
    # Each source said which it was on localization/source, and its estimates were
    # compared with the world's ground truth (each robot ran for tens of seconds).
    assert rows["blue1"]["source"] == "particle_filter", text
    assert rows["blue2"]["source"] == "noisy_ground_truth", text
    assert int(rows["blue1"]["estimates"]) >= 20 and int(rows["blue2"]["estimates"]) >= 20, text
    # Noisy ground truth is the truth with 5 cm of noise and 0.1 s of delay: its error is
    # that small, whatever the robot does (the filter's is what the docs measure).
    assert float(rows["blue2"]["mean"]) < 0.2, text
    assert float(rows["blue2"]["heading"]) < 10, text
