"""The match's external video: an MP4 from a fixed camera above the field, on its own clock.

A team is debugged with a video of the field beside the robots' logs (issue 21 aligns them),
and a camera by the field has a clock of its own, set by hand: its frames' times are off
from the robots' and the world's by an offset, and drift. So is this one. Each frame is
rendered from a MuJoCo free camera (an ``mjvCamera`` with lookat, distance, elevation and
azimuth, so no model file changes) at the moment it is due and stamped with the **camera
clock**: the world's (ground-truth) time plus ``offset_ns``, running ``drift_ppm`` fast
(team_clock's :class:`~team_clock.SkewedClock`, from the moment the video starts).

Written beside ``match.mp4``:

* ``match.mp4.json`` (:func:`read_sidecar`): what a reader needs to put frames on the
  camera's clock (the first frame's camera time, the stream's time base, fps, frames) and
  the camera's calibration to draw field points into the frames (:class:`Calibration`).
  Not the offset: an offline tool must find it, as it would for a real camera.
* optionally ``truth_path`` (tests only): the offset, drift and the world time of the first
  frame, to check an offline fit against.

The frame is rendered on the caller's thread (the GL context is used there) and encoded
with PyAV (H.264) in a writer thread of its own, so the world's loop pays for the
rendering only. A world process adds :class:`MatchCamera` to its container (a timer at the
frame rate, nothing rendered between frames); :class:`MatchVideo` is the same without the
node handle. Both take a model and data, not a simulator, so the one-robot
:class:`~humanoid_sim.simulator.Simulator` (``sim.model``, ``sim.data``, ``sim.pty.lock``)
and a world of several robots can use it alike.
"""

from __future__ import annotations

import json
import math
import os
import queue
import threading
import time
from collections.abc import Sequence
from contextlib import AbstractContextManager, ExitStack, nullcontext
from dataclasses import asdict, dataclass
from fractions import Fraction
from pathlib import Path
from typing import Any

import av
import mujoco
import numpy as np
import numpy.typing as npt

from efficient_comm.handle import NodeHandle
from log_analysis import LogSourceError
from log_analysis.video import (
    SIDECAR_FORMAT,
    Calibration,
    VideoSidecar,
    read_video_sidecar,
    video_sidecar_path,
)
from soccer_field import KIDSIZE, FieldDimensions
from team_clock import SkewedClock

from .errors import SimConfigError, VideoError
from .render import OffscreenRenderer

__all__ = ["SIDECAR_FORMAT", "Calibration", "MatchCamera", "MatchVideo", "OverheadView",
           "VideoSidecar", "read_sidecar", "sidecar_path"]

#: Frame times in the MP4 are kept to 1/90000 s (MPEG's usual clock), not to the frame grid,
#: so a frame rendered late says when it was taken.
TIME_BASE = Fraction(1, 90_000)
#: How early a frame may be offered and still count as due (timer periods are rounded to
#: whole nanoseconds, so the k-th tick may land a few ns before the k-th frame's time).
DUE_SLACK_NS = 1_000_000


@dataclass(frozen=True, slots=True)
class OverheadView:
    """Where the camera by the field stands: a MuJoCo free camera (degrees, metres).

    ``elevation`` below zero looks down; ``azimuth`` 90 looks along +y, so the field's
    length runs across the frame.
    """

    lookat: tuple[float, float, float] = (0.0, 0.0, 0.0)
    distance: float = 9.0
    elevation: float = -65.0
    azimuth: float = 90.0

    @classmethod
    def over(cls, field: FieldDimensions = KIDSIZE, *, aspect: float = 16 / 9,
             fovy_deg: float = 45.0, elevation: float = -65.0) -> OverheadView:
        """A view that holds the whole field with its border strip in a frame of ``aspect``."""
        half_x = field.half_length + field.border_strip_width
        half_y = field.half_width + field.border_strip_width
        tan_y = math.tan(math.radians(fovy_deg) / 2)
        # Across: the length at the lookat's depth; up the frame: the width, foreshortened.
        seen_y = half_y * math.sin(math.radians(-elevation))
        distance = max(half_x / (tan_y * aspect), seen_y / tan_y) * 1.1
        return cls(distance=round(distance, 3), elevation=elevation)

    def camera(self) -> mujoco.MjvCamera:
        cam = mujoco.MjvCamera()
        cam.type = mujoco.mjtCamera.mjCAMERA_FREE
        cam.lookat[:] = self.lookat
        cam.distance, cam.elevation, cam.azimuth = self.distance, self.elevation, self.azimuth
        return cam


def sidecar_path(video: str | os.PathLike[str]) -> Path:
    """``match.mp4`` -> ``match.mp4.json`` (log_analysis owns the sidecar's format)."""
    return video_sidecar_path(video)


def read_sidecar(video: str | os.PathLike[str]) -> tuple[VideoSidecar, Calibration]:
    """The sidecar of ``video`` and its calibration; a missing or foreign one is a VideoError."""
    try:
        return read_video_sidecar(video)
    except LogSourceError as exc:
        raise VideoError(str(exc)) from exc


class _OverheadRenderer:
    """The overhead view on an :class:`~.render.OffscreenRenderer` of its own (a context
    with the video's multisampling; the robots' cameras keep theirs), and the
    calibration of that view."""

    def __init__(self, model: mujoco.MjModel, view: OverheadView, width: int,
                 height: int, *, samples: int) -> None:
        self._renderer = OffscreenRenderer(model, width=width, height=height,
                                           samples=samples, maxgeom=4000)
        self._camera = view.camera()

    def render(self, data: mujoco.MjData, out: npt.NDArray[np.uint8]) -> None:
        self._renderer.render(data, out, camera=self._camera)

    def calibration(self) -> Calibration:
        """The pinhole model of the last rendered scene's camera (the view never moves)."""
        # The scene holds a stereo pair (eyes half the model's ipd apart): their average
        # is the camera a monoscopic frame is drawn from.
        scene = self._renderer.scene
        gl_cam = mujoco.mjv_averageCamera(scene.camera[0], scene.camera[1])
        near, top = float(gl_cam.frustum_near), float(gl_cam.frustum_top)
        width, height = self._renderer.width, self._renderer.height
        f = (height / 2) * near / top
        return Calibration(width=width, height=height, fx=f, fy=f, cx=width / 2,
                           cy=height / 2, position=_vec(gl_cam.pos),
                           forward=_vec(gl_cam.forward), up=_vec(gl_cam.up))

    def close(self) -> None:
        """Free the GL context; a second call does nothing (a double free would crash)."""
        self._renderer.close()


def _vec(v: Sequence[float]) -> tuple[float, float, float]:
    return (float(v[0]), float(v[1]), float(v[2]))


class _Encoder:
    """The MP4 writer thread: frames in through a bounded queue, H.264 out through PyAV.

    A full queue blocks the caller rather than dropping a frame: the video is evidence
    and must hold every frame its sidecar counts (the benchmark says what encoding costs).
    """

    def __init__(self, path: Path, *, width: int, height: int, fps: float, crf: int,
                 preset: str, depth: int) -> None:
        # Opened here, not by FFmpeg at the first frame: a bad path is said at once, and an
        # earlier match's video is never overwritten.
        try:
            self._file = open(path, "xb")  # noqa: SIM115 (closed in close())
        except OSError as exc:
            raise VideoError(f"cannot write the match video {path}: {exc.strerror}") from exc
        try:
            self._container: Any = av.open(self._file, "w", format="mp4")
        except (OSError, av.FFmpegError) as exc:
            self._file.close()
            raise VideoError(f"cannot write the match video {path}: {exc}") from exc
        rate = Fraction(fps).limit_denominator(1000)
        stream: Any = self._container.add_stream("libx264", rate=rate)
        stream.width, stream.height, stream.pix_fmt = width, height, "yuv420p"
        stream.codec_context.time_base = TIME_BASE
        stream.time_base = TIME_BASE
        stream.codec_context.thread_count = 1  # a 2-core machine runs the robots too
        stream.options = {"preset": preset, "crf": str(crf)}
        self._stream = stream
        self._queue: queue.Queue[tuple[int, npt.NDArray[np.uint8]] | None] = queue.Queue(depth)
        self.encode_ns = 0
        self.error: BaseException | None = None
        self._thread = threading.Thread(target=self._run, name="match_video", daemon=True)
        self._thread.start()

    def put(self, pts: int, frame: npt.NDArray[np.uint8]) -> None:
        if self.error is not None:
            raise VideoError(f"the match video's encoder failed: {self.error}") from self.error
        self._queue.put((pts, frame))

    def _run(self) -> None:
        while (item := self._queue.get()) is not None:
            if self.error is not None:
                continue  # drain, so a blocked put() returns and close() can join
            pts, image = item
            started = time.thread_time_ns()
            try:
                frame = av.VideoFrame.from_ndarray(image, format="rgb24")
                frame.pts, frame.time_base = pts, TIME_BASE
                for packet in self._stream.encode(frame):
                    self._container.mux(packet)
            except (av.FFmpegError, ValueError, OSError) as exc:
                self.error = exc
            self.encode_ns += time.thread_time_ns() - started

    def close(self) -> None:
        self._queue.put(None)
        self._thread.join()
        started = time.thread_time_ns()
        try:
            if self.error is None:
                for packet in self._stream.encode():  # flush the encoder's delayed frames
                    self._container.mux(packet)
        except (av.FFmpegError, ValueError, OSError) as exc:
            self.error = exc
        finally:
            self._container.close()
            self._file.close()
        self.encode_ns += time.thread_time_ns() - started
        if self.error is not None:
            raise VideoError(f"the match video's encoder failed: {self.error}") from self.error


class MatchVideo:
    """Renders ``data`` from an overhead camera into an MP4 on the camera's own clock.

    ``offer(world_ns)`` renders a frame only when one is due at ``fps`` on the camera
    clock (``world + offset_ns``, gaining ``drift_ppm`` from the first offer on), so it
    may be called at every physics step; ``close()`` finishes the file and writes the
    sidecar. ``lock`` is held while the scene is read (the simulator's bus lock: the
    servo thread writes into ``data``).

    ``samples`` is the multisampling (antialiasing) of the frames: 0 by default, since 4
    (MuJoCo's default) triples the CPU of a frame in Mesa's software rasteriser (29 ms
    against 9.5 ms at 640x360, bench/match_video_bench.py). ``crf`` and ``preset`` are
    libx264's quality and speed.
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        data: mujoco.MjData,
        path: str | os.PathLike[str],
        *,
        offset_ns: int,
        drift_ppm: float = 0.0,
        fps: float = 12.5,
        width: int = 640,
        height: int = 360,
        view: OverheadView | None = None,
        lock: AbstractContextManager[Any] | None = None,
        truth_path: str | os.PathLike[str] | None = None,
        samples: int = 0,
        crf: int = 28,
        preset: str = "veryfast",
        queue_frames: int = 8,
    ) -> None:
        if not (0 < fps <= 120 and width > 0 and height > 0 and width % 2 == 0
                and height % 2 == 0 and abs(drift_ppm) < 1e5 and 0 <= samples <= 16):
            raise SimConfigError(
                f"match video: need 0 < fps <= 120, even width and height > 0, a drift "
                f"under 1e5 ppm and 0..16 samples; got {fps} fps, {width}x{height}, "
                f"{drift_ppm} ppm, {samples} samples")
        self.path = Path(path)
        self.fps = fps
        self.offset_ns, self.drift_ppm = int(offset_ns), float(drift_ppm)
        self.view = view or OverheadView.over(aspect=width / height,
                                              fovy_deg=float(model.vis.global_.fovy))
        self._model, self._data = model, data
        self._lock: AbstractContextManager[Any] = lock if lock is not None else nullcontext()
        self._truth_path = Path(truth_path) if truth_path is not None else None
        self._period_ns = round(1e9 / fps)
        self._clock: SkewedClock | None = None  # set at the first offer: its epoch
        self._next_due_ns = 0  # camera time
        self._start_ns = 0  # camera time of the first frame (presentation time 0)
        self._first_world_ns = 0
        self._calibration: Calibration | None = None
        self.frames = 0
        #: Wall time spent rendering (not CPU: Mesa's llvmpipe rasterises in threads of
        #: its own, so the caller's thread time would miss most of it; the benchmark
        #: measures the process's CPU).
        self.render_ns = 0
        with ExitStack() as opened:
            self._renderer = _OverheadRenderer(model, self.view, width, height,
                                               samples=samples)
            opened.callback(self._renderer.close)
            self._encoder = _Encoder(self.path, width=width, height=height, fps=fps, crf=crf,
                                     preset=preset, depth=queue_frames)
            self._opened = opened.pop_all()
        self.width, self.height = width, height
        self._closed = False

    @property
    def period_s(self) -> float:
        """Seconds of world time between frames (the camera's period, seen from the world)."""
        return self._period_ns / 1e9 / (1.0 + self.drift_ppm * 1e-6)

    @property
    def encode_ns(self) -> int:
        """CPU time spent encoding so far, in the writer thread (libx264 runs in it: one
        thread)."""
        return self._encoder.encode_ns

    def camera_ns(self, world_ns: int) -> int:
        """The camera clock's reading at world time ``world_ns`` (after the first offer)."""
        if self._clock is None:
            raise VideoError("the camera clock starts with the first frame")
        return self._clock.local_ns(world_ns)

    def offer(self, world_ns: int) -> bool:
        """Render and queue a frame if one is due at world time ``world_ns``; say if it did.

        A frame is due every ``1/fps`` s of camera time; after a stall the next one is
        taken at once and the grid moves on from there, with no burst of catch-up frames.
        """
        if self._closed:
            raise VideoError(f"the match video {self.path} is closed")
        if self._clock is None:
            self._clock = SkewedClock(_FixedClock(), offset_ns=self.offset_ns,
                                      drift_ppm=self.drift_ppm, epoch_ns=world_ns)
            self._first_world_ns = world_ns
            self._start_ns = self._next_due_ns = self._clock.local_ns(world_ns)
        camera = self._clock.local_ns(world_ns)
        if camera < self._next_due_ns - DUE_SLACK_NS:
            return False
        self._next_due_ns = max(self._next_due_ns + self._period_ns, camera + DUE_SLACK_NS)
        image = np.empty((self.height, self.width, 3), dtype=np.uint8)
        started = time.perf_counter_ns()
        with self._lock:
            self._renderer.render(self._data, image)
        self.render_ns += time.perf_counter_ns() - started
        if self._calibration is None:
            self._calibration = self._renderer.calibration()
        pts = round((camera - self._start_ns) * TIME_BASE.denominator
                    / (1_000_000_000 * TIME_BASE.numerator))
        self._encoder.put(pts, image)
        self.frames += 1
        return True

    def close(self) -> VideoSidecar | None:
        """Finish the MP4, write its sidecar (and the truth file, if asked); idempotent.

        Returns the sidecar, None when no frame was ever offered (then no sidecar is
        written: there is no first frame whose time it could give).
        """
        if self._closed:
            return None
        self._closed = True
        try:
            self._encoder.close()
        finally:
            self._opened.close()
        if self._calibration is None:
            return None
        sidecar: VideoSidecar = {
            "format": SIDECAR_FORMAT, "video": self.path.name, "start_ns": self._start_ns,
            "time_base": [TIME_BASE.numerator, TIME_BASE.denominator], "fps": self.fps,
            "frames": self.frames, "width": self.width, "height": self.height,
            "view": asdict(self.view), "calibration": asdict(self._calibration),
        }
        _write_json(sidecar_path(self.path), dict(sidecar))
        if self._truth_path is not None:
            _write_json(self._truth_path, {
                "video": self.path.name, "offset_ns": self.offset_ns,
                "drift_ppm": self.drift_ppm, "first_frame_world_ns": self._first_world_ns,
                "doc": "camera = world + offset_ns + drift_ppm*1e-6*(world - "
                       "first_frame_world_ns)"})
        return sidecar


class _FixedClock:
    """A base clock for :class:`SkewedClock` that is never read: the video maps world
    times it is given (``local_ns``), it does not read a clock of its own."""

    def now_ns(self) -> int:
        raise VideoError("the match video maps given world times; it reads no clock")


def _write_json(path: Path, content: dict[str, Any]) -> None:
    staging = path.with_name(path.name + ".part")
    try:
        staging.write_text(json.dumps(content, indent=1) + "\n")
        staging.replace(path)  # a reader never sees half a sidecar
    except OSError as exc:
        raise VideoError(f"cannot write {path}: {exc}") from exc


class MatchCamera:
    """The match video as a component of the world's container: one frame per timer tick.

    Parameters: ``video_path`` (required), ``fps`` (12.5), ``width`` x ``height``
    (640 x 360), ``clock_offset_s`` (2.5: the camera's clock is off, as one set by hand
    is; the offline tools must find it), ``clock_drift_ppm`` (0), ``truth_path`` ("" for
    none: the offset and drift, for tests of those tools). The world's model, data and
    lock are given when the component is made (``functools.partial``), as they are not
    parameters. The timer runs on the node's clock, so in lockstep the frames fall on
    exact simulated times, and in real time on the world's wall clock, the one its ground
    truth is stamped with.
    """

    def __init__(self, node: NodeHandle, *, model: mujoco.MjModel, data: mujoco.MjData,
                 lock: AbstractContextManager[Any] | None = None,
                 view: OverheadView | None = None) -> None:
        self.node = node
        path = node.declare_parameter("video_path", "")
        fps = node.declare_parameter("fps", 12.5)
        width = node.declare_parameter("width", 640)
        height = node.declare_parameter("height", 360)
        offset_s = node.declare_parameter("clock_offset_s", 2.5)
        drift_ppm = node.declare_parameter("clock_drift_ppm", 0.0)
        truth = node.declare_parameter("truth_path", "")
        if not path:
            raise SimConfigError("match camera: the video_path parameter names the MP4 to write")
        if not math.isfinite(offset_s):
            raise SimConfigError(f"match camera: clock_offset_s must be finite, got {offset_s}")
        self.video = MatchVideo(model, data, path, offset_ns=round(offset_s * 1e9),
                                drift_ppm=drift_ppm, fps=fps, width=width, height=height,
                                view=view, lock=lock, truth_path=truth or None)
        try:
            self.video.offer(node.clock.now_ns())  # the first frame: the world as it starts
            node.create_timer(self.video.period_s, self._tick)
        except BaseException:
            self.video.close()  # the container never sees a half-made component
            raise
        node.logger.info(f"match video {path}: {fps:g} fps {width}x{height}, camera clock "
                         f"{offset_s:+g} s off the world's")

    def _tick(self) -> None:
        self.video.offer(self.node.clock.now_ns())

    def close(self) -> None:
        """Finish the video and its sidecar (the container calls this on unload)."""
        sidecar = self.video.close()
        if sidecar is not None:
            self.node.logger.info(f"match video {self.video.path}: {sidecar['frames']} frames")
