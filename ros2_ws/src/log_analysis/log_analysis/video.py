"""An external video of the field: its frames on the camera's clock, and the camera's
calibration (field metres -> pixels).

A video filmed beside a game is one more source with a clock of its own. Its sidecar
``<video>.json`` (format :data:`SIDECAR_FORMAT`; humanoid_sim's match camera writes it, a
real camera's would be written once by hand or by a calibration tool) says when its first
frame was taken **on the camera's clock**, the frames' time base, and the pinhole model of
the camera. Where the camera's clock stands against the log's is not in it: :mod:`.sync`
finds that from what both saw.
"""

from __future__ import annotations

import json
import os
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path
from typing import Any, TypedDict

import av
import numpy as np
import numpy.typing as npt

from .errors import LogSourceError

__all__ = ["SIDECAR_FORMAT", "Calibration", "ExternalVideo", "VideoFrames", "VideoSidecar",
           "read_video_sidecar", "video_sidecar_path"]

#: The sidecar's ``format`` field; a reader refuses other versions.
SIDECAR_FORMAT = "humanoid_sim.match_video/1"


@dataclass(frozen=True, slots=True)
class Calibration:
    """The overhead camera's pinhole model: field frame (metres) -> pixels.

    ``position`` is the optical centre, ``forward`` and ``up`` the unit view direction and
    the image's up direction, all in the field frame; ``fx = fy`` and ``(cx, cy)`` the
    intrinsics of the ``width`` x ``height`` frame (row 0 at the top, as decoded).
    """

    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float
    position: tuple[float, float, float]
    forward: tuple[float, float, float]
    up: tuple[float, float, float]

    def project(self, points: npt.ArrayLike) -> npt.NDArray[np.float64]:
        """Pixels ``(u, v)`` of field points (N x 3); NaN for points behind the camera."""
        p = np.atleast_2d(np.asarray(points, dtype=float)) - np.asarray(self.position)
        forward, up = np.asarray(self.forward), np.asarray(self.up)
        right = np.cross(forward, up)
        depth = p @ forward
        with np.errstate(divide="ignore", invalid="ignore"):
            u = self.cx + self.fx * (p @ right) / depth
            v = self.cy - self.fy * (p @ up) / depth
        out = np.stack([u, v], axis=1)
        out[depth <= 0] = np.nan
        return out


class VideoSidecar(TypedDict):
    """``<video>.json``: how to read the video's frames on the camera's clock."""

    format: str
    video: str
    #: Camera-clock time (ns) of presentation time 0, i.e. of the first frame.
    start_ns: int
    #: ``[num, den]`` seconds per unit of the frames' presentation times.
    time_base: list[int]
    fps: float
    frames: int
    width: int
    height: int
    view: dict[str, Any]
    calibration: dict[str, Any]


def video_sidecar_path(video: str | os.PathLike[str]) -> Path:
    """``match.mp4`` -> ``match.mp4.json``."""
    return Path(f"{os.fspath(video)}.json")


def _vec(v: Sequence[float]) -> tuple[float, float, float]:
    return (float(v[0]), float(v[1]), float(v[2]))


def read_video_sidecar(video: str | os.PathLike[str]) -> tuple[VideoSidecar, Calibration]:
    """The sidecar of ``video`` and its calibration; a missing, foreign or incomplete one
    raises :class:`LogSourceError` saying which."""
    path = video_sidecar_path(video)
    try:
        data = json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        raise LogSourceError(f"cannot read the video's sidecar {path}: {exc}") from exc
    if not isinstance(data, dict) or data.get("format") != SIDECAR_FORMAT:
        raise LogSourceError(f"{path} is not a {SIDECAR_FORMAT} sidecar")
    try:
        cal: dict[str, Any] = data["calibration"]
        calibration = Calibration(
            width=int(cal["width"]), height=int(cal["height"]), fx=float(cal["fx"]),
            fy=float(cal["fy"]), cx=float(cal["cx"]), cy=float(cal["cy"]),
            position=_vec(cal["position"]), forward=_vec(cal["forward"]), up=_vec(cal["up"]))
        int(data["start_ns"]), Fraction(*data["time_base"])
    except (KeyError, TypeError, ValueError, IndexError, ZeroDivisionError) as exc:
        raise LogSourceError(f"{path}: the camera's calibration or clock is incomplete "
                             f"({exc!r})") from exc
    return data, calibration  # type: ignore[return-value]


def _probe(path: Path) -> VideoSidecar:
    """What a video file says of itself (no sidecar): its clock starts at its first frame,
    and there is no calibration. Raises :class:`LogSourceError` for a file that is no video."""
    try:
        with av.open(str(path)) as container:
            if not container.streams.video:
                raise LogSourceError(f"{path} has no frames (no video stream)")
            stream = container.streams.video[0]
            base = Fraction(stream.time_base or Fraction(1, 90_000))
            rate = stream.average_rate or stream.guessed_rate
            return VideoSidecar(
                format="", video=path.name, start_ns=0,
                time_base=[base.numerator, base.denominator],
                fps=float(rate) if rate else 0.0, frames=int(stream.frames or 0),
                width=int(stream.codec_context.width), height=int(stream.codec_context.height),
                view={}, calibration={})
    except av.FFmpegError as exc:
        raise LogSourceError(f"{path} is not a video ffmpeg reads: {exc}") from exc


class ExternalVideo:
    """A video file with its sidecar: frames as RGB arrays stamped on the camera's clock.

    A video without a sidecar (a phone's, a camera's) is read too: its clock starts at
    its first frame (0), and it has no :attr:`calibration`, so its clock is fitted by hand
    (anchors) and nothing is drawn into it; :meth:`need_calibration` says so.
    """

    def __init__(self, path: str | os.PathLike[str]) -> None:
        self.path = Path(path)
        if not self.path.is_file():
            raise LogSourceError(f"no video at {self.path}")
        self.calibration: Calibration | None
        if video_sidecar_path(self.path).exists():
            self.sidecar, self.calibration = read_video_sidecar(self.path)
            try:  # a sidecar beside a file that is no video: said now (one without frames
                av.open(str(self.path)).close()  # keeps its clock: anchors still fit it)
            except av.FFmpegError as exc:
                raise LogSourceError(f"{self.path} is not a video ffmpeg reads: {exc}") from exc
        else:
            self.sidecar, self.calibration = _probe(self.path), None
        self.start_ns = int(self.sidecar["start_ns"])
        self._time_base = Fraction(*self.sidecar["time_base"])

    def need_calibration(self, what: str) -> Calibration:
        """The camera's calibration, or :class:`LogSourceError` saying that ``what`` needs
        one (a video without its sidecar ``VIDEO.json``)."""
        if self.calibration is None:
            raise LogSourceError(
                f"{what} needs the camera's calibration, and {self.path} has no sidecar "
                f"{video_sidecar_path(self.path).name}; fit its clock by hand (--anchor "
                "CAMERA_S=LOG_S) to watch it beside the log")
        return self.calibration

    @property
    def frame_period_ns(self) -> int:
        fps = float(self.sidecar.get("fps") or 0)
        return round(1e9 / fps) if fps > 0 else 0

    def frames(self) -> Iterator[tuple[int, npt.NDArray[np.uint8]]]:
        """``(camera_ns, rgb)`` of every frame in order; a video that cannot be decoded, or
        has no frames, raises :class:`LogSourceError`."""
        count = 0
        try:
            with av.open(str(self.path)) as container:
                if not container.streams.video:
                    raise LogSourceError(f"{self.path} has no frames (no video stream)")
                for frame in container.decode(video=0):
                    if frame.pts is None:
                        continue
                    count += 1
                    # The stream's own time base (the sidecar's says what the writer
                    # meant; a remuxed file may have another).
                    base = frame.time_base or self._time_base
                    yield (self.start_ns + round(frame.pts * Fraction(base) * 1_000_000_000),
                           np.asarray(frame.to_ndarray(format="rgb24"), dtype=np.uint8))
        except av.FFmpegError as exc:
            raise LogSourceError(f"cannot decode {self.path}: {exc}") from exc
        if count == 0:
            raise LogSourceError(f"{self.path} has no frames")


class VideoFrames:
    """The frame of an :class:`ExternalVideo` shown at a camera time, for a player that
    jumps about (the GUI's cursor): the file stays open, a jump back or far ahead seeks
    to the key frame before, a step forward decodes on from the last frame. Not
    thread-safe: one reader per thread. A context manager (closes the file)."""

    #: Further ahead than this (ns), a seek is cheaper than decoding on.
    SEEK_AHEAD_NS = 2_000_000_000

    def __init__(self, video: ExternalVideo) -> None:
        self.video = video
        try:
            self._container: Any = av.open(str(video.path))
            if not self._container.streams.video:
                raise LogSourceError(f"{video.path} holds no video stream")
        except av.FFmpegError as exc:
            raise LogSourceError(f"cannot decode {video.path}: {exc}") from exc
        self._stream = self._container.streams.video[0]
        self._decoded: Iterator[Any] | None = None
        self._last: tuple[int, npt.NDArray[np.uint8]] | None = None
        self._next: tuple[int, npt.NDArray[np.uint8]] | None = None

    def _camera_ns(self, frame: Any) -> int:
        base = frame.time_base or self.video._time_base
        return int(self.video.start_ns + round(frame.pts * Fraction(base) * 1_000_000_000))

    def _pull(self) -> tuple[int, npt.NDArray[np.uint8]] | None:
        assert self._decoded is not None
        for frame in self._decoded:
            if frame.pts is not None:
                return (self._camera_ns(frame),
                        np.asarray(frame.to_ndarray(format="rgb24"), dtype=np.uint8))
        return None

    def at(self, camera_ns: int) -> tuple[int, npt.NDArray[np.uint8]] | None:
        """``(camera_ns, rgb)`` of the last frame taken at or before ``camera_ns`` (the
        first frame before the video starts); None for a video without frames. Raises
        :class:`LogSourceError` for one that cannot be decoded."""
        try:
            last = self._last
            if (self._decoded is None or last is None or camera_ns < last[0]
                    or camera_ns - last[0] > self.SEEK_AHEAD_NS):
                seconds = max(0, camera_ns - self.video.start_ns) * 1e-9
                pts = int(seconds / float(self._stream.time_base or self.video._time_base))
                self._container.seek(pts, stream=self._stream, backward=True, any_frame=False)
                self._decoded = self._container.decode(self._stream)
                self._last, self._next = None, self._pull()
            while self._next is not None and (self._last is None or self._next[0] <= camera_ns):
                self._last, self._next = self._next, self._pull()
        except av.FFmpegError as exc:
            raise LogSourceError(f"cannot decode {self.video.path}: {exc}") from exc
        return self._last

    def close(self) -> None:
        self._container.close()

    def __enter__(self) -> VideoFrames:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
