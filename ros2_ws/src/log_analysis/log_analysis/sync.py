"""An external video's clock against the log's: offset and drift fitted from what both saw.

A camera by the field keeps its own time, set by hand: its frames are off from the robots'
logs by an offset (seconds, often) and drift (a few ppm). The fit needs moments seen both
in the video and in the log. The one every game has is the **ball in motion**: the log's
ground truth (or a robot's own belief) says where it was at each instant, the video shows
where it was in each frame, and the camera's calibration maps one into the other. So:

1. the ball's candidates are found in each frame by their colour (small orange blobs on
   green; a red robot's edges against the turf can pass for one, so a frame keeps several);
2. for a candidate clock, the logged ball is projected into each frame at the log time the
   frame's camera time maps to; the fit is the clock whose projections fall on a candidate
   (the mean distance to the nearest, each capped, so a robot hiding the ball costs a
   frame little and a stray blob nothing);
3. a coarse search over ``±max_offset_s`` in half-frame steps finds the offset, then each
   stretch of the video in which the logged ball moved (rolled, or was placed by the
   referee) is refined on its own at 1 ms steps, and a line through those stretches'
   offsets gives offset and drift. A rolling ball pins the offset below a frame (it moves
   between frames); a ball placed from one spot to another only to the frame, so a
   stretch's offset is the middle of the offsets that fit equally well. The residual is
   the scatter of the stretches about the line (with fewer than three, half the widest
   such range: what the video cannot tell apart).

A stationary ball carries no timing, so a video in which the ball never moves is refused
with that reason. Anchors picked by hand (``camera time = log time`` pairs, e.g. in the
GUI) fit the same line without the video's pixels.

A fit is only as good as what it saw, and a log and a video of different matches still
have a "best" offset: :func:`check_fit` refuses one the data does not support (too few
frames matched, the projected ball far from the seen one, stretches that disagree by more
than a frame). Drift is fitted only from :data:`MIN_DRIFT_STRETCHES` stretches spread over
:data:`MIN_DRIFT_SPAN_S` (two 20 s stretches pin it to no better than about a thousand ppm
at 5 fps); otherwise the fit is the offset alone, drift 0, and says so. A real camera's
clock drifts by tens of ppm, so one beyond :data:`MAX_DRIFT_PPM` is refused unless
allowed. The fit records the log it was made on (path and time range), so that a tool
given another log can refuse it (:meth:`VideoFit.check_log`).

The model: ``log_ns = camera_ns - offset_ns - drift_ppm * 1e-6 * (camera_ns - start_ns)``,
``start_ns`` the first frame's camera time (to first order, the camera runs ``drift_ppm``
fast and ``offset_ns`` ahead of the log).
"""

from __future__ import annotations

import itertools
import json
import os
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field, replace
from functools import partial
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import numpy.typing as npt

from .errors import SyncError
from .source import TeamLog
from .video import Calibration, ExternalVideo

__all__ = ["SyncError", "VideoFit", "ball_pixels", "check_fit", "fit_anchors",
           "fit_video_clock"]

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class VideoFit:
    """A video's clock against the log's (see the module's model), how well it fits
    (``residual_ns``: RMS scatter of the stretches or anchors about the fit;
    ``pixel_error_px``: median distance of the projected ball from the detected one), and
    what it was fitted on."""

    offset_ns: int
    drift_ppm: float
    start_ns: int
    residual_ns: int
    method: str
    frame_period_ns: int = 0
    #: Mean distance (px) from each used frame's projected ball to the nearest candidate.
    pixel_error_px: float = float("nan")
    frames_used: int = 0
    stretches: list[tuple[int, int]] = field(default_factory=list)
    #: Whether the drift was fitted (else 0 by assumption), and its standard error.
    drift_fitted: bool = False
    drift_sigma_ppm: float = 0.0
    #: The log it was fitted on: its path and first and last log time (ns).
    log_path: str = ""
    log_start_ns: int = 0
    log_end_ns: int = 0

    def on_log(self, log: TeamLog) -> VideoFit:
        """This fit, recording that it was made on ``log``."""
        first, last = log.time_range()
        return replace(self, log_path=str(Path(log.path).resolve()), log_start_ns=first,
                       log_end_ns=last)

    def check_log(self, log: TeamLog) -> None:
        """Raise :class:`SyncError` when this fit was made on another log than ``log``
        (another time range: a path can move, a match's times do not)."""
        if not self.log_path:
            return  # a fit from before fits recorded their log: nothing to check
        if (self.log_start_ns, self.log_end_ns) != log.time_range():
            raise SyncError(f"the fit was made on another log ({self.log_path}), not on "
                            f"{log.path}: run sync-video on this log and video again")

    def describe_drift(self) -> str:
        """``drift +12.0 ± 3.0 ppm``, or that it was not fitted."""
        if not self.drift_fitted:
            return "drift 0 (not fitted: too few stretches or too short a span)"
        return f"drift {self.drift_ppm:+.1f} ± {self.drift_sigma_ppm:.1f} ppm"

    def to_log(self, camera_ns: int) -> int:
        """The log time of a frame taken at ``camera_ns``."""
        return camera_ns - self.offset_ns - round(self.drift_ppm * 1e-6
                                                  * (camera_ns - self.start_ns))

    def to_camera(self, log_ns: int) -> int:
        """The camera time at which the log's ``log_ns`` was filmed."""
        d = self.drift_ppm * 1e-6
        return round((log_ns + self.offset_ns - d * self.start_ns) / (1 - d))

    @property
    def residual_frames(self) -> float:
        return self.residual_ns / self.frame_period_ns if self.frame_period_ns else 0.0

    def save(self, path: str | os.PathLike[str]) -> Path:
        target = Path(path)
        target.write_text(json.dumps(asdict(self), indent=1) + "\n")
        return target

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> VideoFit:
        """A fit :meth:`save` wrote (``sync-video``'s ``<video>.sync.json``)."""
        try:
            data = json.loads(Path(path).read_text())
            data["stretches"] = [tuple(s) for s in data.get("stretches", [])]
            return cls(**data)
        except (OSError, ValueError, TypeError) as exc:
            raise SyncError(f"cannot read a video fit from {path}: {exc}") from exc


#: Candidates kept per frame, and the blob sizes (px) a ball may have in a frame.
MAX_CANDIDATES = 4
BLOB_PX = (2, 80)


def ball_pixels(video: ExternalVideo, *, progress: Callable[[int], None] | None = None
                ) -> tuple[npt.NDArray[np.int64], FloatArray]:
    """Camera times of every frame and up to :data:`MAX_CANDIDATES` pixels ``(u, v)`` per
    frame where the ball may be (N x K x 2, NaN where fewer): the centres of small orange
    blobs (red well above green, green well above blue, as the ball's orange is and the
    turf, lines and team colours are not), largest first."""
    times, found = [], []
    for i, (camera_ns, rgb) in enumerate(video.frames()):
        c = rgb.astype(np.int16)
        r, g, b = c[..., 0], c[..., 1], c[..., 2]
        mask = ((r > 150) & (r - b > 90) & (r - g > 30) & (g - b > 40)).astype(np.uint8)
        count, _, stats, centres = cv2.connectedComponentsWithStats(mask, connectivity=8)
        blobs = sorted(((int(stats[k, cv2.CC_STAT_AREA]), k) for k in range(1, count)
                        if BLOB_PX[0] <= stats[k, cv2.CC_STAT_AREA] <= BLOB_PX[1]),
                       reverse=True)[:MAX_CANDIDATES]
        row = np.full((MAX_CANDIDATES, 2), np.nan)
        for j, (_, k) in enumerate(blobs):
            row[j] = centres[k] + 0.5  # pixel centres, as the projection counts
        found.append(row)
        times.append(camera_ns)
        if progress is not None and i % 50 == 0:
            progress(i)
    return np.asarray(times, dtype=np.int64), np.asarray(found, dtype=float)


#: The ball's message types a track is read from, and where each has the position.
BALL_TYPES: dict[str, Callable[[Any], Any]] = {
    "geometry_msgs/msg/PointStamped": lambda m: m.point,
    "geometry_msgs/msg/PoseStamped": lambda m: m.pose.position,
    "geometry_msgs/msg/PoseWithCovarianceStamped": lambda m: m.pose.pose.position,
}
#: Frames that are the field's (an empty frame_id, as a test double writes, is taken so).
FIELD_FRAMES = ("field", "map", "world", "")


def _track(log: TeamLog, topic: str) -> tuple[npt.NDArray[np.int64], FloatArray]:
    """The ball's field positions on ``topic``; :class:`SyncError` for a type that has no
    position or a frame that is not the field's (a robot's own ``ball/position`` is in its
    ``base_footprint``: projected as field coordinates, it fits a wrong clock)."""
    kind = log.topics.get(topic, "")
    if kind and kind not in BALL_TYPES:
        raise SyncError(f"{topic} is a {kind}, not a ball position ("
                        f"{', '.join(t.rsplit('/', 1)[1] for t in BALL_TYPES)} in the field "
                        "frame)")
    where = BALL_TYPES.get(kind, BALL_TYPES["geometry_msgs/msg/PoseStamped"])
    times, points = [], []
    for m in log.messages([topic]):
        frame = m.message.header.frame_id
        if frame not in FIELD_FRAMES:
            raise SyncError(f"{topic} is in the frame {frame!r}, not the field's: the ball "
                            "must be in field coordinates (the world's ground truth, or a "
                            "robot's field-frame belief such as /ROBOT/team_ball)")
        p = where(m.message)
        times.append(m.log_time_ns)
        points.append((p.x, p.y, p.z))
    if len(times) < 2:
        raise SyncError(f"the log has no ball track on {topic} (found {len(times)} "
                        "messages)")
    return np.asarray(times, dtype=np.int64), np.asarray(points, dtype=float)


#: A frame's distance counts up to this (px): a hidden ball costs a frame no more.
CAP_PX = 12.0


class _Cost:
    """Mean (capped) pixel distance between the projected logged ball and the nearest
    candidate of each frame."""

    def __init__(self, cam: npt.NDArray[np.int64], seen: FloatArray,
                 track_t: npt.NDArray[np.int64], track_p: FloatArray,
                 calibration: Calibration, start_ns: int) -> None:
        ok = ~np.isnan(seen[:, 0, 0])
        self.cam, self.seen = cam[ok].astype(float), seen[ok]
        self.t = track_t.astype(float)
        self.p, self.cal, self.start = track_p, calibration, float(start_ns)

    def errors(self, offset: float, drift_ppm: float = 0.0,
               pick: npt.NDArray[np.bool_] | None = None) -> FloatArray:
        """Per frame (of ``pick``), the distance to the nearest candidate; NaN for a frame
        whose time falls outside the log."""
        cam = self.cam if pick is None else self.cam[pick]
        seen = self.seen if pick is None else self.seen[pick]
        log_t = cam - offset - drift_ppm * 1e-6 * (cam - self.start)
        inside = (log_t >= self.t[0]) & (log_t <= self.t[-1])
        out = np.full(len(cam), np.nan)
        if inside.any():
            pts = np.stack([np.interp(log_t[inside], self.t, self.p[:, k]) for k in range(3)],
                           axis=1)
            gaps = np.linalg.norm(seen[inside] - self.cal.project(pts)[:, None, :], axis=2)
            out[inside] = np.nanmin(gaps, axis=1)
        return out

    def __call__(self, offset: float, drift_ppm: float = 0.0,
                 pick: npt.NDArray[np.bool_] | None = None) -> float:
        """The mean capped distance over the same frames for every offset: a frame outside
        the log counts as a miss, so no offset wins by leaving the hard frames out."""
        err = self.errors(offset, drift_ppm, pick)
        if not len(err) or np.isnan(err).all():
            return float("inf")
        return float(np.mean(np.minimum(np.nan_to_num(err, nan=CAP_PX), CAP_PX)))


def _plateau(f: Callable[[float], float], centre: float, frame: float, step: float
             ) -> tuple[float, float]:
    """The middle and half-width of the offsets within two frames of ``centre`` that fit
    about as well as the best: within a tenth of the way from the best to one frame off
    it. A ball placed from one spot to another fits every offset that keeps the same
    frames on each side of the jump about equally well; a rolling ball few. Searched at
    ten steps, then each edge at one step."""
    coarse = step * 10
    grid = np.arange(centre - 2 * frame, centre + 2 * frame + coarse / 2, coarse)
    values = np.asarray([f(o) for o in grid])
    at = int(np.argmin(values))
    near = [v for v in (f(grid[at] - frame), f(grid[at] + frame)) if np.isfinite(v)]
    limit = values[at] + 0.1 * max(float(np.mean(near or [values[at]])) - values[at], 0.0)
    good = np.flatnonzero(values <= limit)
    lo, hi = float(grid[good[0]]), float(grid[good[-1]])
    for edge, direction in ((lo, -1), (hi, 1)):
        for k in range(1, 10):  # the edge to a step: how far beyond it still fits
            if f(edge + direction * k * step) > limit:
                break
            lo, hi = min(lo, edge - k * step), max(hi, edge + k * step)
    return (lo + hi) / 2, (hi - lo) / 2


def _line(x: FloatArray, y: FloatArray) -> tuple[float, float, float]:
    """Intercept, slope and RMS residual of y over x (slope 0 for one point)."""
    if len(x) == 1:
        return float(y[0]), 0.0, 0.0
    slope, intercept = np.polyfit(x, y, 1)
    rms = float(np.sqrt(np.mean((y - (intercept + slope * x)) ** 2)))
    return float(intercept), float(slope), rms


def fit_anchors(anchors: Sequence[tuple[int, int]], *, start_ns: int,
                frame_period_ns: int = 0) -> VideoFit:
    """The clock through ``(camera_ns, log_ns)`` pairs picked by hand: one gives the offset,
    two or more the drift too."""
    if not anchors:
        raise SyncError("no anchors to fit the video's clock on")
    cam = np.asarray([a[0] for a in anchors], dtype=float)
    offsets = np.asarray([a[0] - a[1] for a in anchors], dtype=float)
    intercept, slope, rms = _line(cam - start_ns, offsets)
    # A moment picked by hand is right to the frame: half a frame either way.
    pick = (frame_period_ns or 40_000_000) / 2 / np.sqrt(3)
    sigma = _slope_sigma(cam - start_ns, offsets, floor=pick) if len(anchors) > 1 else 0.0
    return VideoFit(round(intercept), slope * 1e6, start_ns, round(rms), "anchors",
                    frame_period_ns, drift_fitted=len(anchors) > 1,
                    drift_sigma_ppm=sigma * 1e6)


def _slope_sigma(x: FloatArray, y: FloatArray, *, floor: float) -> float:
    """Standard error of the slope of y over x, each y known to ``floor`` at best."""
    sxx = float(np.sum((x - x.mean()) ** 2))
    if sxx <= 0:
        return float("inf")
    sigma = floor
    if len(x) > 2:
        slope, intercept = np.polyfit(x, y, 1)
        rss = float(np.sum((y - (intercept + slope * x)) ** 2))
        sigma = max(sigma, float(np.sqrt(rss / (len(x) - 2))))
    return float(sigma / np.sqrt(sxx))


#: What a fit must show to be believed: frames matched, their mean distance (px) from the
#: projected ball, the stretches' residual (frames), and a camera clock's plausible drift.
MIN_FRAMES = 20
MAX_PIXEL_ERROR_PX = 3.0
MAX_RESIDUAL_FRAMES = 1.0
MAX_DRIFT_PPM = 1000.0
#: Drift is fitted from at least this many stretches whose middles span this long.
MIN_DRIFT_STRETCHES = 3
MIN_DRIFT_SPAN_S = 40.0

_HELP = ("check that the log and the video are of the same match, or give moments picked "
         "by hand (--anchor CAMERA=LOG)")


def check_fit(fit: VideoFit, *, allow_drift: bool = False) -> None:
    """Raise :class:`SyncError` (one line, saying what would help) for a fit the data does
    not support: matched on too few frames, the ball projected far from where the video
    shows it, stretches more than a frame apart, or a drift no camera clock has."""
    if fit.method == "ball track":
        if fit.frames_used < MIN_FRAMES:
            raise SyncError(f"the fit matched the ball in {fit.frames_used} frames (at least "
                            f"{MIN_FRAMES} needed): {_HELP}")
        if not fit.pixel_error_px <= MAX_PIXEL_ERROR_PX:
            raise SyncError(f"the logged ball falls {fit.pixel_error_px:.1f} px from the "
                            f"video's on average (at most {MAX_PIXEL_ERROR_PX:g}): {_HELP}")
        if fit.frame_period_ns and fit.residual_frames > MAX_RESIDUAL_FRAMES:
            raise SyncError(f"the video's stretches disagree by {fit.residual_frames:.2f} "
                            f"frames (at most {MAX_RESIDUAL_FRAMES:g}): {_HELP}")
    if abs(fit.drift_ppm) > MAX_DRIFT_PPM and not allow_drift:
        raise SyncError(f"a drift of {fit.drift_ppm:+.0f} ppm is implausible for a camera's "
                        f"clock (tens of ppm; at most {MAX_DRIFT_PPM:g} taken): check the "
                        "anchors or the log, or --allow-drift to keep it")


def fit_video_clock(
    log: TeamLog,
    video: ExternalVideo,
    *,
    ball_topic: str = "/world/ground_truth/ball",
    max_offset_s: float = 30.0,
    stretch_s: float = 20.0,
    progress: Callable[[int], None] | None = None,
) -> VideoFit:
    """Fit ``video``'s clock to ``log``'s from the ball's motion (the module explains how).

    Raises :class:`SyncError` when there is nothing to fit on (no ball track in the log,
    no frame that shows the ball, a ball that never moved) and :class:`LogSourceError` for a
    video that cannot be read.
    """
    if max_offset_s <= 0 or stretch_s <= 0:
        raise ValueError("max_offset_s and stretch_s must be positive")
    track_t, track_p = _track(log, ball_topic)
    moved = float(np.max(np.ptp(track_p[:, :2], axis=0)))
    if moved < 0.1:
        raise SyncError(f"the ball moved {moved:.2f} m in the log: a ball at rest carries "
                        "no timing (give anchors picked by hand instead)")
    cam, seen = ball_pixels(video, progress=progress)
    period = video.frame_period_ns
    if not period and len(cam) > 1:
        period = int(np.median(np.diff(cam)))
    cost = _Cost(cam, seen, track_t, track_p,
                 video.need_calibration("a fit from the ball"), video.start_ns)
    if len(cost.cam) < 3:
        raise SyncError(f"the ball was found in {len(cost.cam)} of {len(cam)} frames of "
                        f"{video.path}: too few to fit on")
    # Coarse: half-frame steps over the whole range, around the offset that lines up the
    # video's start with the log's.
    step = max(period // 2, 10_000_000)
    guess = video.start_ns - int(track_t[0])
    span = int(max_offset_s * 1e9)
    grid = np.arange(guess - span, guess + span + 1, step, dtype=float)
    costs = np.asarray([cost(o) for o in grid])
    if not np.isfinite(costs).any():
        raise SyncError(f"no offset within ±{max_offset_s:g} s puts the video's frames "
                        "inside the log")
    best = float(grid[int(np.argmin(costs))])
    # Fine: each stretch in which the logged ball moved, on its own.
    t_log = cost.cam - best
    speed = np.hypot(*np.gradient(track_p[:, :2], track_t.astype(float) * 1e-9, axis=0).T)
    moving_t = track_t[speed > 0.05].astype(float)
    stretches: list[tuple[int, int]] = []
    widest = 0.0
    edges = np.arange(cost.cam[0], cost.cam[-1] + stretch_s * 1e9, stretch_s * 1e9)
    for lo, hi in itertools.pairwise(edges):
        pick = (cost.cam >= lo) & (cost.cam < hi)
        if pick.sum() < 5 or not ((moving_t >= t_log[pick][0])
                                  & (moving_t <= t_log[pick][-1])).any():
            continue
        fine, half = _plateau(partial(cost, drift_ppm=0.0, pick=pick), best, float(period),
                              1e6)
        widest = max(widest, half)
        stretches.append((int(np.mean(cost.cam[pick])), round(fine)))
    if not stretches:
        raise SyncError("the ball never moved while the video showed it: a ball at rest "
                        "carries no timing (give anchors picked by hand instead)")
    x = np.asarray([s[0] - video.start_ns for s in stretches], dtype=float)
    y = np.asarray([s[1] for s in stretches], dtype=float)
    drift_fitted = (len(stretches) >= MIN_DRIFT_STRETCHES
                    and float(np.ptp(x)) >= MIN_DRIFT_SPAN_S * 1e9)
    sigma = 0.0
    if drift_fitted:
        intercept, slope, rms = _line(x, y)
        sigma = _slope_sigma(x, y, floor=widest / np.sqrt(3))
    else:  # the offset alone: the stretches' mean, drift 0
        intercept, slope = float(np.mean(y)), 0.0
        rms = float(np.sqrt(np.mean((y - intercept) ** 2))) if len(y) >= 3 else 0.0
    rms = max(rms, widest)  # never better than what a stretch could tell apart
    drift = slope * 1e6
    err = cost.errors(intercept, drift)
    err = err[~np.isnan(err)]
    return VideoFit(round(intercept), drift, video.start_ns, round(rms), "ball track", period,
                    float(np.mean(np.minimum(err, CAP_PX))) if len(err) else float("nan"),
                    len(err), stretches, drift_fitted=drift_fitted,
                    drift_sigma_ppm=sigma * 1e6)

