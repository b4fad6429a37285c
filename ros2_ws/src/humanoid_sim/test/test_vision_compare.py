"""The two ball detectors compared on one log (log_analysis's A/B replay): the colour
detector takes the largest orange blob, so an orange bar bigger than the ball fools it;
the blob detector takes the roundest and is not fooled. The comparison must say so."""

from __future__ import annotations

from pathlib import Path

import pytest

from log_analysis import CompareError, TeamLog
from log_analysis.compare import Variant, compare_components, write_report
from log_analysis.testing import seen_ball

COLOUR = Variant("colour", "humanoid_sim::BallDetector")
BLOB = Variant("blob", "humanoid_sim::BlobBallDetector")
#: 40 images at 2 Hz: the ball sweeps from 20° right to 19° left; a bar in images 10-19;
#: images 30-34 with the ball behind the robot.
FRAMES = [(1.0 + k / 2, None if 30 <= k < 35 else -20.0 + k, 10 <= k < 20) for k in range(40)]


@pytest.fixture(scope="module")
def log(tmp_path_factory: pytest.TempPathFactory) -> TeamLog:
    return TeamLog(seen_ball(tmp_path_factory.mktemp("ab") / "log", robot="blue1",
                             frames=FRAMES))


def test_the_comparison_finds_where_the_bar_fools_the_colour_detector(log: TeamLog) -> None:
    c = compare_components(log, COLOUR, BLOB, robot="blue1")
    assert len(c.frames) == 40
    s = c.summary()
    assert s["both"]["in_view"] == 35 and s["both"]["agreement"] == 30 / 40
    # A hit is a detection within the agreement's tolerance of the truth: the colour
    # detector's 10 images fooled by the bar (all with the ball in view) are no hits.
    assert s["colour"]["hit_rate"] == 25 / 35 and s["blob"]["hit_rate"] == 1.0
    assert s["colour"]["false_rate"] == 0.0 and s["blob"]["false_rate"] == 0.0
    assert s["blob"]["error_p95_deg"] < 1.0
    assert s["colour"]["error_p95_deg"] > 10.0  # the bar, far left of the ball
    assert s["colour"]["error_median_deg"] < 1.0  # otherwise as good
    assert s["colour"]["callback_median_ms"] > 0 and s["blob"]["callback_median_ms"] > 0
    worst = c.disagreements(worst=20)
    assert [round(e.start_ns / 1e9, 1) for e in worst] == [1.0 + k / 2 for k in range(10, 20)]
    assert all(e.robot == "blue1" and float(e.metadata["apart_deg"]) > 10 for e in worst)


def test_the_report_has_the_figures_the_plots_and_the_worst_frames(
        log: TeamLog, tmp_path: Path) -> None:
    c = compare_components(log, COLOUR, BLOB, robot="blue1", start_ns=5_000_000_000,
                           end_ns=11_000_000_000)
    assert len(c.frames) == 12
    report = write_report(c, tmp_path / "r")
    text = report.read_text()
    s = c.summary()
    assert s["colour"]["hit_rate"] < 1.0 == s["blob"]["hit_rate"]  # the bar fools colour
    assert (f"| hits (ball in view, within {c.agree_deg:g}°) | "
            f"{s['colour']['hit_rate']:.0%} | 100% |") in text
    assert "## Where they disagree most" in text and "colour +" in text
    for plot in ("yaw.png", "callbacks.png"):
        assert (tmp_path / "r" / plot).stat().st_size > 1000


def test_a_variant_that_cannot_run_is_told(log: TeamLog) -> None:
    with pytest.raises(CompareError, match="nowhere::Detector"):
        compare_components(log, COLOUR, Variant("x", "nowhere::Detector"), robot="blue1")
    with pytest.raises(CompareError, match="min_saturation"):
        compare_components(log, COLOUR, Variant("x", "humanoid_sim::BallDetector",
                                                {"min_saturation": 999}), robot="blue1")
    with pytest.raises(CompareError, match="no images of red9"):
        compare_components(log, COLOUR, BLOB, robot="red9")
    with pytest.raises(CompareError, match="different labels"):
        compare_components(log, COLOUR, COLOUR, robot="blue1")
