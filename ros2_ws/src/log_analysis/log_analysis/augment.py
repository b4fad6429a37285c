"""The augmented video: the external video with every robot's beliefs drawn in.

Whether a robot knew where it was and where the ball was is what its log says; whether it
was right is what the video shows. Drawn into the same frame (the dissertation's Fig.
5.12), the two are compared at a glance: each robot's estimated pose (a dot and its
heading), its field of view, where it believes the ball is (a dot joined to it) and its
role, one colour per robot, projected with the overhead camera's calibration; the events
of the moment as captions; and a timeline under the picture with every event and the
current instant.

The video is put on the log's time with a :class:`~.sync.VideoFit` (``sync-video``), so
each frame shows what each robot believed when the frame was taken.
"""

from __future__ import annotations

import bisect
import math
import os
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import av
import cv2
import numpy as np
import numpy.typing as npt

from .errors import LogSourceError
from .events import Event
from .source import TeamLog
from .sync import VideoFit
from .video import Calibration, ExternalVideo

__all__ = ["AugmentReport", "augment_video", "caption_text", "robot_colour"]

#: What a belief may be old and still be drawn (s): a robot that stopped publishing fades out.
FRESH_S = 1.5
#: Half the robot camera's horizontal field of view (deg) and how far it is drawn (m).
FOV_HALF_DEG, FOV_M = 30.0, 1.5
#: How long an instant event stays captioned (s).
CAPTION_S = 2.0
_TEAM_SHADES = {"blue": [(40, 90, 255), (0, 200, 255), (150, 60, 255)],
                "red": [(255, 40, 40), (255, 140, 0), (255, 60, 170)]}
_OTHERS = [(255, 255, 0), (255, 255, 255), (0, 0, 0)]


def robot_colour(robot: str, index: int = 0) -> tuple[int, int, int]:
    """An RGB colour per robot: shades of its team's colour for ``blue2`` or ``red1``."""
    for team, shades in _TEAM_SHADES.items():
        if robot.startswith(team) and robot[len(team):].isdigit():
            return shades[(int(robot[len(team):]) - 1) % len(shades)]
    return _OTHERS[index % len(_OTHERS)]


@dataclass
class _Series:
    """Timestamped values of one belief of one robot, looked up by time."""

    times: list[int] = field(default_factory=list)
    values: list[Any] = field(default_factory=list)

    def at(self, t: int, fresh_ns: int) -> Any:
        i = bisect.bisect_right(self.times, t) - 1
        if i < 0 or t - self.times[i] > fresh_ns:
            return None
        return self.values[i]


@dataclass
class _Robot:
    pose: _Series = field(default_factory=_Series)  # (x, y, yaw)
    ball: _Series = field(default_factory=_Series)  # (x, y) on the field
    role: _Series = field(default_factory=_Series)  # str


def _yaw(q: Any) -> float:
    return math.atan2(2 * (q.w * q.z + q.x * q.y), 1 - 2 * (q.y * q.y + q.z * q.z))


def _beliefs(log: TeamLog, start_ns: int, end_ns: int) -> dict[str, _Robot]:
    robots: dict[str, _Robot] = {}
    for m in log.messages(["localization/pose", "ball/position", "role"],
                          start_ns=start_ns, end_ns=end_ns):
        r = robots.setdefault(m.robot, _Robot())
        if m.topic == "localization/pose":
            p = m.message.pose.pose
            r.pose.times.append(m.log_time_ns)
            r.pose.values.append((p.position.x, p.position.y, _yaw(p.orientation)))
        elif m.topic == "role":
            r.role.times.append(m.log_time_ns)
            r.role.values.append(m.message.data)
        else:  # ball/position: robot-relative, placed with the pose of that moment
            pose = r.pose.at(m.log_time_ns, int(FRESH_S * 1e9))
            if pose is not None:
                x, y, yaw = pose
                bx, by = m.message.point.x, m.message.point.y
                r.ball.times.append(m.log_time_ns)
                r.ball.values.append((x + math.cos(yaw) * bx - math.sin(yaw) * by,
                                      y + math.sin(yaw) * bx + math.cos(yaw) * by))
    return robots


@dataclass(frozen=True)
class AugmentReport:
    """What was written: ``frames`` of ``width`` x ``height``, the robots drawn, and how
    fast (frames per second of work; real time is the video's own frame rate)."""

    path: Path
    frames: int
    width: int
    height: int
    robots: list[str]
    seconds: float
    video_fps: float

    @property
    def frames_per_s(self) -> float:
        return self.frames / self.seconds if self.seconds > 0 else float("inf")


class _Painter:
    def __init__(self, calibration: Calibration, robots: Sequence[str], events: Sequence[Event],
                 span: tuple[int, int], timeline_px: int) -> None:
        self.cal, self.events, self.span = calibration, events, span
        self.colours = {r: robot_colour(r, i) for i, r in enumerate(robots)}
        self.timeline_px = timeline_px

    def _pixels(self, points: Sequence[tuple[float, float]]) -> list[tuple[int, int] | None]:
        """Pixels of field points (on the ground), None for one the camera cannot see; one
        projection for all of a robot's points (a call per point cost more than the
        drawing)."""
        uv = self.cal.project([(x, y, 0.0) for x, y in points])
        return [(round(float(u)), round(float(v))) if np.isfinite(u) and np.isfinite(v)
                else None for u, v in uv]

    def robot(self, img: npt.NDArray[np.uint8], name: str, pose: tuple[float, float, float],
              ball: tuple[float, float] | None, role: str | None) -> None:
        colour = self.colours.get(name, (255, 255, 255))
        x, y, yaw = pose
        half = math.radians(FOV_HALF_DEG)
        at, left, right, nose, seen = self._pixels([
            (x, y), *((x + FOV_M * math.cos(yaw + a), y + FOV_M * math.sin(yaw + a))
                      for a in (-half, half)),
            (x + 0.35 * math.cos(yaw), y + 0.35 * math.sin(yaw)), ball or (x, y)])
        if at is None:
            return
        if left is not None and right is not None:
            self._wedge(img, np.array([at, left, right], np.int32), colour)
        if nose is not None:
            cv2.line(img, at, nose, colour, 2, cv2.LINE_AA)
        cv2.circle(img, at, 5, colour, -1, cv2.LINE_AA)
        cv2.circle(img, at, 5, (0, 0, 0), 1, cv2.LINE_AA)
        if ball is not None and seen is not None:
            cv2.line(img, at, seen, colour, 1, cv2.LINE_AA)
            cv2.circle(img, seen, 4, colour, 2, cv2.LINE_AA)
        label = f"{name} {role}" if role else name
        cv2.putText(img, label, (at[0] + 7, at[1] - 7), cv2.FONT_HERSHEY_SIMPLEX, 0.35,
                    (0, 0, 0), 2, cv2.LINE_AA)
        cv2.putText(img, label, (at[0] + 7, at[1] - 7), cv2.FONT_HERSHEY_SIMPLEX, 0.35,
                    colour, 1, cv2.LINE_AA)

    @staticmethod
    def _wedge(img: npt.NDArray[np.uint8], corners: npt.NDArray[np.int32],
               colour: tuple[int, int, int]) -> None:
        """A quarter-opaque triangle, blended only within its bounding box (blending the
        whole frame per robot cost more than decoding it)."""
        h, w = img.shape[:2]
        x0, y0 = np.clip(corners.min(axis=0), 0, (w, h))
        x1, y1 = np.clip(corners.max(axis=0) + 1, 0, (w, h))
        if x1 <= x0 or y1 <= y0:
            return
        box = img[y0:y1, x0:x1]
        overlay = box.copy()
        cv2.fillPoly(overlay, [corners - (x0, y0)], colour)
        cv2.addWeighted(overlay, 0.25, box, 0.75, 0, dst=box)

    def captions(self, img: npt.NDArray[np.uint8], t: int) -> None:
        """The events of the moment, newest first, each on a dark semi-transparent box
        (text with a dark outline ghosted over the turf and the robots)."""
        now = [e for e in self.events
               if e.start_ns <= t <= max(e.end_ns, e.start_ns + int(CAPTION_S * 1e9))]
        now.sort(key=lambda e: -e.start_ns)  # the newest first
        for row, e in enumerate(now[:4]):
            text = caption_text(e, t)
            colour = self.colours.get(e.robot, (255, 255, 255))
            y = 14 + 16 * row
            (w, h), base = cv2.getTextSize(text, cv2.FONT_HERSHEY_SIMPLEX, 0.4, 1)
            _shade(img, (2, y - h - 3, 10 + w, y + base + 1))
            cv2.putText(img, text, (6, y), cv2.FONT_HERSHEY_SIMPLEX, 0.4, colour, 1,
                        cv2.LINE_AA)

    def timeline(self, img: npt.NDArray[np.uint8], t: int) -> None:
        h, w = img.shape[:2]
        top = h - self.timeline_px
        img[top:] = (30, 30, 30)
        first, last = self.span
        scale = (w - 12) / max(last - first, 1)

        def x_of(ns: int) -> int:
            return 6 + int((min(max(ns, first), last) - first) * scale)

        mid = top + self.timeline_px // 2
        cv2.line(img, (6, mid), (w - 6, mid), (120, 120, 120), 1)
        for e in self.events:
            colour = self.colours.get(e.robot, (255, 255, 255))
            x0, x1 = x_of(e.start_ns), x_of(e.end_ns)
            cv2.rectangle(img, (x0, mid - 4), (max(x1, x0 + 1), mid + 4), colour, -1)
        cv2.line(img, (x_of(t), top + 1), (x_of(t), h - 2), (255, 255, 255), 2)
        seconds = (t - first) / 1e9
        cv2.putText(img, f"{seconds:7.2f} s", (w - 70, top + 11), cv2.FONT_HERSHEY_SIMPLEX,
                    0.35, (255, 255, 255), 1, cv2.LINE_AA)
        # The legend: whose colour an event's bar has.
        x = 6
        for name, colour in [*self.colours.items(), ("team", (255, 255, 255))]:
            cv2.putText(img, name, (x, top + 9), cv2.FONT_HERSHEY_SIMPLEX, 0.3, colour, 1,
                        cv2.LINE_AA)
            x += cv2.getTextSize(name, cv2.FONT_HERSHEY_SIMPLEX, 0.3, 1)[0][0] + 8


def caption_text(event: Event, t_ns: int) -> str:
    """An event's caption at ``t_ns``: its name and description once it has ended; while
    it is still going on, its name and its length so far (the description tells its final
    length, which the moment does not know yet)."""
    who = f"{event.robot} " if event.robot else ""
    if t_ns < event.end_ns:
        return f"{event.name}: {who}for {(t_ns - event.start_ns) / 1e9:.1f} s so far"
    return f"{event.name}: {event.description or who.strip()}"


def _shade(img: npt.NDArray[np.uint8], box: tuple[int, int, int, int]) -> None:
    """Darken ``box`` (x0, y0, x1, y1) to a third, blended within the box only."""
    h, w = img.shape[:2]
    x0, y0, x1, y1 = max(box[0], 0), max(box[1], 0), min(box[2], w), min(box[3], h)
    if x1 > x0 and y1 > y0:
        region = img[y0:y1, x0:x1]
        region[:] = (region.astype(np.uint16) * 85 // 256).astype(np.uint8)


def augment_video(
    log: TeamLog,
    video: ExternalVideo,
    fit: VideoFit,
    output: str | os.PathLike[str],
    *,
    events: Sequence[Event] = (),
    timeline_px: int = 24,
    progress: Callable[[int], None] | None = None,
) -> AugmentReport:
    """Write ``output`` (MP4, H.264): ``video``'s frames with every robot's beliefs of the
    moment (``fit`` maps a frame's camera time to the log's), ``events`` as captions and a
    timeline strip of ``timeline_px`` under the picture. ``progress`` gets the frame count.

    Raises :class:`LogSourceError` when the video cannot be read or the output written.
    """
    target = Path(output)
    cal = video.need_calibration("drawing the robots' beliefs into the video")
    timeline_px += (cal.height + timeline_px) % 2  # H.264: even sizes
    if target.exists():
        raise LogSourceError(f"{target} exists already; refusing to overwrite it")
    first, last = log.time_range()
    beliefs = _beliefs(log, first, last + 1)
    robots = sorted(beliefs)
    painter = _Painter(cal, robots, sorted(events, key=lambda e: e.start_ns), (first, last),
                       timeline_px)
    fresh = int(FRESH_S * 1e9)
    frames, started = 0, time.perf_counter()
    fps = float(video.sidecar.get("fps") or 5)
    partial = target.with_name(f".{target.name}.partial.mp4")
    try:
        with av.open(str(partial), "w") as out:
            stream: Any = out.add_stream("libx264", rate=round(fps) or 5)
            width = cal.width + cal.width % 2
            stream.width, stream.height = width, cal.height + timeline_px
            stream.pix_fmt = "yuv420p"
            stream.options = {"preset": "veryfast", "crf": "23"}
            for camera_ns, rgb in video.frames():
                t = fit.to_log(camera_ns)
                img = np.zeros((cal.height + timeline_px, width, 3), np.uint8)
                img[:cal.height] = rgb[:cal.height, :cal.width]
                picture = img[:cal.height]
                for name in robots:
                    b = beliefs[name]
                    pose = b.pose.at(t, fresh)
                    if pose is not None:
                        painter.robot(picture, name, pose, b.ball.at(t, fresh),
                                      b.role.at(t, 10**18))
                painter.captions(picture, t)
                painter.timeline(img, t)
                frame = av.VideoFrame.from_ndarray(img, format="rgb24")
                frame.pts = frames
                for packet in stream.encode(frame):
                    out.mux(packet)
                frames += 1
                if progress is not None and frames % 25 == 0:
                    progress(frames)
            for packet in stream.encode():
                out.mux(packet)
        partial.replace(target)
    except LogSourceError:  # the video's own (no frames, undecodable): said as it is
        partial.unlink(missing_ok=True)
        raise
    except (OSError, av.FFmpegError) as exc:
        partial.unlink(missing_ok=True)
        raise LogSourceError(f"cannot write {target}: {exc}") from exc
    except BaseException:
        partial.unlink(missing_ok=True)
        raise
    return AugmentReport(target, frames, width, cal.height + timeline_px, robots,
                         time.perf_counter() - started, fps)
