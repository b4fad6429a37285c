"""The match's external video: an MP4 on the camera's own clock, its sidecar and calibration.

Lockstep runs of a couple of simulated seconds: the frames fall on exact simulated times, so
their count and presentation times are exact; the MP4 is read back with PyAV as an offline
tool reads it.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import av
import numpy as np
import numpy.typing as npt
import pytest

from efficient_comm.testing import TestHandle, test_container
from humanoid_sim.errors import HumanoidSimError, SimConfigError, VideoError
from humanoid_sim.match_video import MatchCamera, MatchVideo, read_sidecar, sidecar_path
from humanoid_sim.simulator import Simulator

SECONDS = 2.0
FPS = 12.5


def _decode(path: Path) -> list[Any]:
    with av.open(str(path)) as container:
        return list(container.decode(video=0))


def _world(**parameters: Any) -> tuple[Any, Simulator]:
    container = test_container()
    # The robot stands aside, so what moves in the picture is the ball.
    sim = Simulator(TestHandle("sim", container=container, parameters={
        "camera_hz": 0.0, "robot_pose": [-3.0, 2.0, 0.0], **parameters}))
    return container, sim


@pytest.mark.parametrize(("offset_s", "drift_ppm"), [(2.5, 0.0), (-1.25, 500.0)])
def test_the_video_has_a_frame_per_period_on_the_cameras_own_clock(
        tmp_path: Path, offset_s: float, drift_ppm: float) -> None:
    container, sim = _world()
    video, truth = tmp_path / "match.mp4", tmp_path / "truth.json"
    try:
        start_ns = container.executor.clock.now_ns()
        camera = MatchCamera(TestHandle("camera", container=container, parameters={
            "video_path": str(video), "truth_path": str(truth), "fps": FPS,
            "clock_offset_s": offset_s, "clock_drift_ppm": drift_ppm}),
            model=sim.model, data=sim.data, lock=sim.pty.lock)
        container.advance(SECONDS)
        camera.close()
    finally:
        sim.close()
    frames = _decode(video)
    expected = int(SECONDS * FPS) + 1  # one at the start, then one per period
    sidecar, calibration = read_sidecar(video)
    assert len(frames) == sidecar["frames"] == expected == camera.video.frames
    assert (frames[0].width, frames[0].height) == (640, 360) == (calibration.width,
                                                                 calibration.height)
    # Presentation times are the camera clock's, a period apart on it (whatever its drift).
    num, den = sidecar["time_base"]
    period = round(den / (FPS * num))
    assert [f.pts for f in frames] == [k * period for k in range(expected)]
    # The sidecar gives the first frame's camera time (world + offset), never the offset.
    assert sidecar["start_ns"] == start_ns + round(offset_s * 1e9)
    assert "offset" not in json.dumps(sidecar)
    held = json.loads(truth.read_text())
    assert (held["offset_ns"], held["drift_ppm"]) == (round(offset_s * 1e9), drift_ppm)
    # Frame k was taken at world time k·period/(1 + drift): the truth file maps it back.
    last_world = held["first_frame_world_ns"] + round((expected - 1) * 1e9 / FPS
                                                      / (1 + drift_ppm * 1e-6))
    camera_of_last = (last_world + held["offset_ns"]
                      + drift_ppm * 1e-6 * (last_world - held["first_frame_world_ns"]))
    assert sidecar["start_ns"] + frames[-1].pts * num * 1e9 / den == pytest.approx(
        camera_of_last, abs=1e9 * num / den)


def _rgb(frame: av.VideoFrame, uv: npt.NDArray[np.float64]) -> npt.NDArray[np.int64]:
    image = np.asarray(frame.to_ndarray(format="rgb24"), dtype=np.int64)
    u, v = (round(float(c)) for c in uv)
    return np.asarray(image[v - 1 : v + 2, u - 1 : u + 2].reshape(-1, 3).mean(axis=0),
                      dtype=np.int64)


def test_the_camera_sees_the_ball_move_where_its_calibration_says(tmp_path: Path) -> None:
    container, sim = _world(ball_position=[1.0, -1.0], ball_velocity=[1.5, 1.0])
    video = tmp_path / "match.mp4"
    try:
        match = MatchVideo(sim.model, sim.data, video, offset_ns=0, fps=FPS,
                           lock=sim.pty.lock)
        ball_at_start = sim.ball_position()
        match.offer(container.executor.clock.now_ns())
        container.advance(SECONDS)
        match.offer(container.executor.clock.now_ns())
        ball_at_end = sim.ball_position()
        match.close()
    finally:
        sim.close()
    assert np.linalg.norm(ball_at_end[:2] - ball_at_start[:2]) > 1.0  # it rolled
    first, last = _decode(video)
    _, calibration = read_sidecar(video)
    start_px, end_px = calibration.project([ball_at_start, ball_at_end])
    assert all(0 < u < 640 and 0 < v < 360 for u, v in (start_px, end_px))
    # The ball (orange: more red than green) is where the projection puts it, and the
    # field (green) where it has left.
    for frame, here, gone in ((first, start_px, end_px), (last, end_px, start_px)):
        r, g, _ = _rgb(frame, here)
        assert r > g + 40, (r, g)
        r, g, _ = _rgb(frame, gone)
        assert g > r + 40, (r, g)
    whole_first = first.to_ndarray(format="rgb24").astype(int)
    whole_last = last.to_ndarray(format="rgb24").astype(int)
    assert np.abs(whole_first - whole_last).max() > 100  # the frames differ


def test_frames_are_rendered_only_when_due(tmp_path: Path) -> None:
    container, sim = _world(ball_velocity=[1.0, 0.0])
    try:
        match = MatchVideo(sim.model, sim.data, tmp_path / "m.mp4", offset_ns=7, fps=5.0,
                           width=64, height=36, lock=sim.pty.lock)
        clock = container.executor.clock
        rendered = []
        for _ in range(100):  # offered at every physics step, 1 s
            rendered.append(match.offer(clock.now_ns()))
            container.advance(0.01)
        match.close()
        assert match.close() is None  # idempotent
    finally:
        sim.close()
    assert sum(rendered) == match.frames == 5  # 0, 0.2, ... 0.8 s
    assert [i for i, r in enumerate(rendered) if r] == [0, 20, 40, 60, 80]
    assert match.render_ns > 0 and match.encode_ns > 0
    with pytest.raises(VideoError, match="closed"):
        match.offer(clock.now_ns())


def test_bad_settings_and_paths_are_told_in_one_line(tmp_path: Path) -> None:
    container, sim = _world()
    try:
        with pytest.raises(SimConfigError, match="even width"):
            MatchVideo(sim.model, sim.data, tmp_path / "m.mp4", offset_ns=0, width=641)
        with pytest.raises(VideoError, match="cannot write the match video"):
            MatchVideo(sim.model, sim.data, tmp_path / "missing" / "m.mp4", offset_ns=0)
        (tmp_path / "earlier.mp4").write_bytes(b"an earlier match")
        with pytest.raises(VideoError, match="File exists"):
            MatchVideo(sim.model, sim.data, tmp_path / "earlier.mp4", offset_ns=0)
        assert (tmp_path / "earlier.mp4").read_bytes() == b"an earlier match"
        with pytest.raises(HumanoidSimError, match="offscreen buffer"):
            MatchVideo(sim.model, sim.data, tmp_path / "m.mp4", offset_ns=0, width=1920,
                       height=1080)
        with pytest.raises(SimConfigError, match="video_path"):
            MatchCamera(TestHandle("camera", container=container), model=sim.model,
                        data=sim.data)
    finally:
        sim.close()
    with pytest.raises(VideoError, match="sidecar"):
        read_sidecar(tmp_path / "none.mp4")
    sidecar_path(tmp_path / "x.mp4").write_text('{"format": "other"}')
    sidecar_path(tmp_path / "y.mp4").write_text(
        '{"format": "humanoid_sim.match_video/1", "calibration": {"width": 2}}')
    with pytest.raises(VideoError, match="calibration or clock is incomplete"):
        read_sidecar(tmp_path / "y.mp4")
    with pytest.raises(VideoError, match=r"not a humanoid_sim\.match_video/1 sidecar"):
        read_sidecar(tmp_path / "x.mp4")
