"""VideoFrames: the frame at a camera time, for a player whose cursor jumps about."""

from __future__ import annotations

from pathlib import Path

from log_analysis import ExternalVideo, VideoFrames
from log_analysis.testing import film_ball


def test_the_frame_at_a_camera_time_forward_back_and_far(tmp_path: Path) -> None:
    _, path = film_ball(tmp_path, lambda t: (t * 0.5 - 1.0, 0.0), seconds=4.0, offset_s=2.0,
                        drift_ppm=0.0, fps=5)
    video = ExternalVideo(path)
    every = list(video.frames())
    times = [t for t, _ in every]
    with VideoFrames(video) as frames:
        for wanted in [times[3] + 1, times[4], times[1], times[-1] + 10**9, times[0] - 10**9,
                       times[10] + 5, times[2]]:
            found = frames.at(wanted)
            assert found is not None
            expected = max([i for i, t in enumerate(times) if t <= wanted], default=0)
            assert found[0] == times[expected], wanted
            assert (found[1] == every[expected][1]).all()
