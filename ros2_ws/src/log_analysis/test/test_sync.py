"""A video's clock fitted to a log's from the ball: an H.264 video of a ball that rolls and
is placed, filmed by a camera whose clock is off by a known offset and drift, with a red
robot's orange-ish edges beside it; the fit must find that clock within one frame."""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable
from pathlib import Path

import pytest

from log_analysis import LogSourceError, TeamLog
from log_analysis.sync import SyncError, check_fit, fit_anchors, fit_video_clock
from log_analysis.testing import film_ball
from log_analysis.video import ExternalVideo


def rolling(t: float) -> tuple[float, float]:
    """A ball kicked every 20 s from a spot the referee places it on: it rolls 2 m in 2 s."""
    k, s = divmod(t, 20.0)
    start = (-2.0 + 0.5 * (k % 4), -1.0 + 0.6 * (k % 3))  # placed at each k-th spot
    if s < 5.0:
        return start
    along = min(s - 5.0, 2.0)
    d = 2.0 * along - 0.5 * along * along  # 2 m/s, slowing 1 m/s²: 2 m in 2 s
    return start[0] + d * 0.8, start[1] + d * 0.6


def placed(t: float) -> tuple[float, float]:
    """A ball that never rolls: placed from spot to spot every 7 s."""
    return (-1.0, 0.0) if int(t // 7) % 2 else (1.0, 0.5)


def _film(folder: Path, track: Callable[[float], tuple[float, float]], *, seconds: float,
          offset_s: float, drift_ppm: float) -> tuple[Path, Path, int]:
    log, video = film_ball(folder, track, seconds=seconds, offset_s=offset_s,
                           drift_ppm=drift_ppm)
    return log, video, round(1e9 / 5)


def test_a_rolling_ball_gives_offset_and_drift_well_within_a_frame(tmp_path: Path) -> None:
    log, video, frame = _film(tmp_path, rolling, seconds=80, offset_s=-7.3, drift_ppm=800)
    fit = fit_video_clock(TeamLog(log), ExternalVideo(video))
    assert fit.method == "ball track" and len(fit.stretches) >= 4
    # A tenth of a frame or so: yuv420p halves the colour resolution, which shifts the
    # ball's orange by a pixel fraction, and the ball moves ~80 px/s.
    assert abs(fit.offset_ns - (-7.3e9)) < frame / 4, fit
    assert abs(fit.drift_ppm - 800) < 150, fit
    # Four stretches over 60 s: the drift is fitted, with its uncertainty (a few hundred
    # ppm: each stretch is good to ~10 ms, 60 s apart).
    assert fit.drift_fitted and 0 < fit.drift_sigma_ppm < 400, fit
    assert abs(fit.drift_ppm - 800) < 3 * fit.drift_sigma_ppm, fit
    check_fit(fit)
    assert fit.residual_ns < frame / 4
    assert fit.pixel_error_px < 2
    # The fit maps frames onto the log's time: a frame taken at world 70 s.
    camera_70 = round(-7.3e9 + 70e9 * (1 + 800e-6))
    assert abs(fit.to_log(camera_70) - 70e9) < frame / 4
    assert abs(fit.to_camera(fit.to_log(camera_70)) - camera_70) < 1000


def test_a_ball_only_placed_gives_the_offset_to_the_frame(tmp_path: Path) -> None:
    log, video, frame = _film(tmp_path, placed, seconds=30, offset_s=4.05, drift_ppm=0)
    fit = fit_video_clock(TeamLog(log), ExternalVideo(video))
    assert abs(fit.offset_ns - 4.05e9) <= frame / 2, fit
    # What a jump cannot tell apart is said: about half a frame either way.
    assert frame / 4 <= fit.residual_ns <= frame / 2 + 10_000_000, fit


def test_nothing_to_fit_on_and_bad_videos_are_told(tmp_path: Path) -> None:
    log, video, _ = _film(tmp_path, lambda t: (0.5, 0.5), seconds=5, offset_s=1.0,
                           drift_ppm=0)
    with pytest.raises(SyncError, match="carries no timing"):
        fit_video_clock(TeamLog(log), ExternalVideo(video))
    with pytest.raises(SyncError, match="no ball track on /world/elsewhere"):
        fit_video_clock(TeamLog(log), ExternalVideo(video), ball_topic="/world/elsewhere")
    with pytest.raises(LogSourceError, match="no video at"):
        ExternalVideo(tmp_path / "none.mp4")
    junk = tmp_path / "junk.mp4"
    junk.write_bytes(b"\x00" * 1000)
    Path(f"{junk}.json").write_text(Path(f"{video}.json").read_text())
    with pytest.raises(LogSourceError, match=r"junk\.mp4"):
        list(ExternalVideo(junk).frames())
    Path(f"{junk}.json").write_text('{"format": "something else"}')
    with pytest.raises(LogSourceError, match=r"is not a humanoid_sim\.match_video/1 sidecar"):
        ExternalVideo(junk)


def test_a_video_without_its_sidecar_is_read_on_its_own_clock_and_fitted_by_hand(
        tmp_path: Path) -> None:
    """A phone's or a camera's video has no sidecar: its frames are read from 0 on its own
    clock, a fit from the ball (which needs the calibration) is refused saying so and what
    to do instead, and anchors fit it."""
    log, video, _ = _film(tmp_path, lambda t: (t / 3 - 1, 0.5), seconds=3, offset_s=1.0,
                          drift_ppm=0)
    plain = tmp_path / "phone.mp4"
    plain.write_bytes(Path(video).read_bytes())
    with_sidecar = [t for t, _ in ExternalVideo(video).frames()]
    bare = ExternalVideo(plain)
    assert bare.calibration is None and bare.start_ns == 0
    times = [t for t, _ in bare.frames()]
    assert len(times) == len(with_sidecar) > 5 and times[0] == 0
    assert [b - a for a, b in itertools.pairwise(times)] == \
        [b - a for a, b in itertools.pairwise(with_sidecar)]
    assert bare.frame_period_ns == ExternalVideo(video).frame_period_ns > 0
    with pytest.raises(LogSourceError, match=r"needs the camera's calibration.*--anchor"):
        fit_video_clock(TeamLog(log), bare)
    fit = fit_anchors([(0, 3_000_000_000)], start_ns=bare.start_ns,
                      frame_period_ns=bare.frame_period_ns)
    assert fit.to_log(times[1]) == 3_000_000_000 + times[1]
    text = tmp_path / "notes.mp4"
    text.write_text("not a video")
    with pytest.raises(LogSourceError, match=r"notes\.mp4 is not a video"):
        ExternalVideo(text)


def test_anchors_picked_by_hand_fit_offset_and_drift() -> None:
    start = 5_000_000_000
    truth = [(start + round(c * 1e9), round((c + 5 - 2.5) * 1e9 / (1 + 100e-6)))
             for c in (0.0, 40.0, 80.0)]
    fit = fit_anchors(truth, start_ns=start)
    assert fit.method == "anchors"
    for camera, log in truth:
        assert abs(fit.to_log(camera) - log) < 1000
    assert math.isclose(fit.drift_ppm, 100, rel_tol=0.01)
    assert fit.drift_fitted and fit.drift_sigma_ppm > 0
    check_fit(fit)
    wild = fit_anchors([(start, 0), (start + 8_000_000_000, 7_500_000_000)], start_ns=start)
    with pytest.raises(SyncError, match="implausible"):
        check_fit(wild)
    check_fit(wild, allow_drift=True)
    with pytest.raises(SyncError):
        fit_anchors([], start_ns=start)
