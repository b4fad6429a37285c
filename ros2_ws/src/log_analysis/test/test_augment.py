"""The augmented video: each robot's belief drawn where the calibration puts it, in its
colour, at the instant the frame was taken; event captions and a timeline under it."""

from __future__ import annotations

from pathlib import Path

import av
import numpy as np
import pytest

from log_analysis import Event, LogSourceError, TeamLog
from log_analysis.augment import augment_video, caption_text, robot_colour
from log_analysis.sync import fit_anchors
from log_analysis.testing import OVERHEAD, film_ball
from log_analysis.video import ExternalVideo


def _walker(t: float) -> tuple[float, float, float]:
    """blue1 walks along the field at 0.2 m/s, facing +x."""
    return -2.0 + 0.2 * t, -1.0, 0.0


def _frames(path: Path) -> list[np.ndarray]:
    with av.open(str(path)) as container:
        return [f.to_ndarray(format="rgb24") for f in container.decode(video=0)]


def test_beliefs_are_drawn_where_and_when_the_robot_had_them(tmp_path: Path) -> None:
    offset_s = 1.5
    log_path, video_path = film_ball(tmp_path, lambda t: (0.5, 0.5), seconds=8,
                                     offset_s=offset_s, drift_ppm=0,
                                     robots={"blue1": _walker})
    log, video = TeamLog(log_path), ExternalVideo(video_path)
    fit = fit_anchors([(video.start_ns, video.start_ns - round(offset_s * 1e9))],
                      start_ns=video.start_ns)
    events = [Event("fell", 3_000_000_000, 5_000_000_000, "blue1", "blue1 fell")]
    report = augment_video(log, video, fit, tmp_path / "aug.mp4", events=events)
    assert report.frames == 40 and report.robots == ["blue1"]
    assert (report.width, report.height) == (480, 270 + 24)
    frames = _frames(tmp_path / "aug.mp4")
    assert len(frames) == 40
    blue = np.array(robot_colour("blue1"), float)
    for k in (5, 20, 35):  # the frame at world k / 5 s shows the walker there
        u, v = OVERHEAD.project([(*_walker(k / 5)[:2], 0.0)])[0]
        patch = frames[k][int(v) - 1:int(v) + 2, int(u) - 1:int(u) + 2].reshape(-1, 3)
        assert np.linalg.norm(patch.mean(axis=0) - blue) < 60, (k, patch.mean(axis=0))
        # ... and not where it was two seconds earlier.
        u0, v0 = OVERHEAD.project([(*_walker(k / 5 - 2)[:2], 0.0)])[0]
        assert np.linalg.norm(frames[k][int(v0), int(u0)] - blue) > 60
    # The caption is there while the event lasts (top-left text in the robot's colour:
    # bluer than green, which the turf never is).
    caption = (slice(2, 18), slice(4, 120))
    assert _bluish(frames[20][caption]) > 10  # at 4 s
    assert _bluish(frames[35][caption]) == 0  # at 7 s, past its end and 2 s more
    # The timeline strip: dark, with the cursor moving right.
    strip = [f[270 + 14:, :, :].mean(axis=2) for f in (frames[5], frames[35])]  # below
    # the legend
    assert all(s.mean() < 90 for s in strip)
    cursors = [int(np.argmax(s.max(axis=0) > 200)) for s in strip]
    assert cursors[0] < cursors[1]


def _bluish(region: np.ndarray) -> int:
    return int((region[..., 2].astype(int) > region[..., 1].astype(int) + 20).sum())


def test_an_existing_output_is_never_overwritten(tmp_path: Path) -> None:
    log_path, video_path = film_ball(tmp_path, lambda t: (0.0, 0.0), seconds=1, offset_s=0,
                                     drift_ppm=0)
    video = ExternalVideo(video_path)
    (tmp_path / "taken.mp4").write_bytes(b"mine")
    with pytest.raises(LogSourceError, match="exists already"):
        augment_video(TeamLog(log_path), video, fit_anchors([(0, 0)], start_ns=0),
                      tmp_path / "taken.mp4")
    assert (tmp_path / "taken.mp4").read_bytes() == b"mine"


def test_captions_name_the_event_sit_on_a_dark_box_and_tell_a_length_only_when_known(
        tmp_path: Path) -> None:
    """The newcomer could not read captions over the turf (a dark outline ghosting), they
    lacked the event's name, and 3 s into a silence one said "for 9.0 s"."""
    silent = Event("team link silent", 10_000_000_000, 19_000_000_000, "blue1",
                   "blue1 heard no teammate for 9.0 s")
    assert caption_text(silent, 13_000_000_000) == "team link silent: blue1 for 3.0 s so far"
    assert caption_text(silent, 19_500_000_000) == \
        "team link silent: blue1 heard no teammate for 9.0 s"
    log_path, video_path = film_ball(tmp_path, lambda t: (0.5, 0.5), seconds=4,
                                     offset_s=0.0, drift_ppm=0, robots={"blue1": _walker})
    video = ExternalVideo(video_path)
    fit = fit_anchors([(video.start_ns, video.start_ns)], start_ns=video.start_ns)
    plain = augment_video(TeamLog(log_path), video, fit, tmp_path / "plain.mp4", events=[])
    captioned = augment_video(TeamLog(log_path), video, fit, tmp_path / "cap.mp4",
                              events=[Event("fell", 0, 4_000_000_000, "blue1", "blue1 fell")])
    before, after = _frames(plain.path)[10], _frames(captioned.path)[10]
    # Behind the caption (top left; the text is thin) the turf darkened as a whole, not
    # just around the letters: the median pixel is dark.
    box_before = before[4:18, 4:120].astype(int).sum(axis=2)
    box_after = after[4:18, 4:120].astype(int).sum(axis=2)
    assert np.median(box_after) < 0.5 * np.median(box_before), (np.median(box_after),
                                                                 np.median(box_before))
