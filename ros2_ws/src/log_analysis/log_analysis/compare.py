"""Two variants of a component on the same log, side by side (A/B).

Whether a new ball detector is better than today's is a question one log can answer: the
same images go through both, frame by frame, in lockstep, and what each reports is put
beside the other and beside the ground truth where the log has it (the dissertation's
Fig. 6.14-6.16). Each variant is the unchanged component (by entry point or
``module:Class``, with parameters) on a test node handle of efficient_comm: the log's
images are injected on its input topic at their logged times (a manual clock advanced in
step), what it publishes on its output topic is collected, and the time of each callback
is measured.

For ball detectors (``ball/detection``: x the ball's yaw from the image centre, left
positive, in radians), the ground truth is the bearing of the true ball from the robot's
true pose (``ground_truth/pose``, ``ground_truth/ball``) less the neck's yaw
(``joint_states``); a ball is in view when that bearing is within the camera's half
field of view. Per frame: whether each variant saw the ball, where, and whether they agree
(both nothing, or both within ``agree_deg``). Summed up: detection rate, hits and false
detections against the truth, the angular error, the callback time, and the frames where
the variants disagree most, as events.
"""

from __future__ import annotations

import bisect
import math
import os
import statistics
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from sensor_msgs.msg import Image

from efficient_comm import ComponentSpec, EfficientCommError, resolve_factory
from efficient_comm.testing import TestHandle, test_container

from .errors import CompareError
from .events import Event
from .source import LogMessage, TeamLog

__all__ = ["Comparison", "FrameResult", "Variant", "compare_components", "write_report"]


@dataclass(frozen=True)
class Variant:
    """One side of the comparison: a ``label``, the ``component`` (an entry point of
    ``efficient_comm.components`` such as ``humanoid_sim::BallDetector``, or
    ``module:Class``) and its ``parameters``."""

    label: str
    component: str
    parameters: Mapping[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class FrameResult:
    """One image: its log time, each variant's detection (yaw, pitch, radius in rad, or
    None) and callback time (ms), the true yaw (rad; None where the log has no truth) and
    whether the ball was in view."""

    t_ns: int
    a: tuple[float, float, float] | None
    b: tuple[float, float, float] | None
    a_ms: float
    b_ms: float
    truth_yaw: float | None
    in_view: bool


def _deg(rad: float) -> float:
    return math.degrees(rad)


@dataclass
class Comparison:
    """The frames, the variants, and the figures of :meth:`summary`."""

    robot: str
    a: Variant
    b: Variant
    frames: list[FrameResult]
    agree_deg: float
    seconds: float

    def agrees(self, f: FrameResult) -> bool:
        if f.a is None or f.b is None:
            return f.a is None and f.b is None
        return abs(_deg(f.a[0] - f.b[0])) <= self.agree_deg

    def hit(self, d: tuple[float, float, float] | None, f: FrameResult) -> bool:
        """A detection within ``agree_deg`` of the true bearing (a detection of something
        else, 35° off, is no hit)."""
        return (d is not None and f.truth_yaw is not None
                and abs(_deg(math.remainder(d[0] - f.truth_yaw, math.tau))) <= self.agree_deg)

    def disagreement(self, f: FrameResult) -> float:
        """Degrees between the two (180 when only one saw a ball)."""
        if f.a is None or f.b is None:
            return 0.0 if f.a is None and f.b is None else 180.0
        return abs(_deg(f.a[0] - f.b[0]))

    def summary(self) -> dict[str, dict[str, float]]:
        """Per variant: detection rate, hit rate and false detections against the truth,
        median and p95 yaw error (deg), median and p95 callback time (ms); and the
        agreement."""
        out: dict[str, dict[str, float]] = {}
        judged = [f for f in self.frames if f.truth_yaw is not None]
        in_view = [f for f in judged if f.in_view]
        out_view = [f for f in judged if not f.in_view]
        for side, variant in (("a", self.a), ("b", self.b)):
            seen = [getattr(f, side) for f in self.frames]
            errors = sorted(abs(_deg(getattr(f, side)[0] - f.truth_yaw)) for f in in_view
                            if getattr(f, side) is not None and f.truth_yaw is not None)
            times = sorted(getattr(f, f"{side}_ms") for f in self.frames)
            out[variant.label] = {
                "detection_rate": sum(s is not None for s in seen) / max(len(seen), 1),
                "hit_rate": (sum(self.hit(getattr(f, side), f) for f in in_view)
                             / len(in_view)) if in_view else float("nan"),
                "false_rate": (sum(getattr(f, side) is not None for f in out_view)
                               / len(out_view)) if out_view else float("nan"),
                "error_median_deg": statistics.median(errors) if errors else float("nan"),
                "error_p95_deg": _p95(errors),
                "callback_median_ms": statistics.median(times) if times else float("nan"),
                "callback_p95_ms": _p95(times),
            }
        out["both"] = {"agreement": sum(map(self.agrees, self.frames)) / max(len(self.frames), 1),
                       "frames": float(len(self.frames)), "judged": float(len(judged)),
                       "in_view": float(len(in_view)), "out_view": float(len(out_view))}
        return out

    def disagreements(self, worst: int = 10) -> list[Event]:
        """The ``worst`` frames where the variants disagree most, as events."""
        ranked = sorted((f for f in self.frames if not self.agrees(f)),
                        key=lambda f: (-self.disagreement(f), f.t_ns))[:worst]
        return [Event("detectors disagree", f.t_ns, f.t_ns, self.robot,
                      f"{self.a.label} {_said(f.a)}, {self.b.label} {_said(f.b)}, truth "
                      f"{_said_yaw(f.truth_yaw, f.in_view)}",
                      {"apart_deg": f"{self.disagreement(f):.1f}", "a": _said(f.a),
                       "b": _said(f.b), "truth": _said_yaw(f.truth_yaw, f.in_view)})
                for f in sorted(ranked, key=lambda f: f.t_ns)]


def _p95(sorted_values: Sequence[float]) -> float:
    if not sorted_values:
        return float("nan")
    return float(sorted_values[min(len(sorted_values) - 1, round(0.95 * (len(sorted_values) - 1)))])


def _said(d: tuple[float, float, float] | None) -> str:
    return "nothing" if d is None else f"{_deg(d[0]):+.1f}°"


def _said_yaw(yaw: float | None, in_view: bool) -> str:
    if yaw is None:
        return "unknown"
    return f"{_deg(yaw):+.1f}°" + ("" if in_view else " (out of view)")


class _Runner:
    """One variant on a test handle: an image in, what it published and how long it took."""

    def __init__(self, variant: Variant, *, robot: str, input_topic: str, output_topic: str
                 ) -> None:
        spec = ComponentSpec(variant.component, name=variant.label, source=variant.label)
        try:
            factory = resolve_factory(spec)
            parameters = _checked_parameters(variant, factory, robot)
            # No mutation guard (a test handle's default): it fingerprints every message
            # before and after each callback, which cost more than the detectors and was
            # counted in their callback times; no statistics publisher either.
            self.handle = TestHandle(variant.label, namespace=f"/{robot}",
                                     parameters=parameters,
                                     container=test_container(guard_mutation=False,
                                                              stats_period_s=0))
            self.component = factory(self.handle)
            self.handle.published(output_topic)  # it must publish there
        except CompareError:
            raise
        except (EfficientCommError, LookupError) as exc:
            raise CompareError(f"variant {variant.label} ({variant.component}): {exc}") from exc
        except Exception as exc:  # the component's constructor: its own error, told
            raise CompareError(f"variant {variant.label} ({variant.component}) does not "
                               f"start: {type(exc).__name__}: {exc}") from exc
        self.input_topic, self.output_topic = input_topic, output_topic
        self.last_ns: int | None = None

    def run(self, image: Image, t_ns: int) -> tuple[Any, float]:
        if self.last_ns is not None and t_ns > self.last_ns:
            self.handle.advance((t_ns - self.last_ns) * 1e-9)
        self.last_ns = t_ns
        self.handle.clear_published()
        start = time.perf_counter()
        self.handle.inject(self.input_topic, image)
        took = (time.perf_counter() - start) * 1e3
        out = self.handle.published(self.output_topic)
        return (out[-1] if out else None), took


class _Probe(TestHandle):
    """A test handle that notes what the component declares (name -> default)."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.declared: dict[str, Any] = {}

    def declare_parameter(self, name: str, default: Any, **kwargs: Any) -> Any:
        self.declared[name] = default
        return super().declare_parameter(name, default, **kwargs)


def _checked_parameters(variant: Variant, factory: Callable[[Any], Any], robot: str
                        ) -> dict[str, Any]:
    """``variant``'s parameters checked against those its component declares (made once
    on a probe handle): one it does not declare is refused naming those it does, and an
    int given for a double is converted, as ``ros2 param set`` takes ``5`` for ``5.0``."""
    if not variant.parameters:
        return {}
    probe = _Probe(variant.label, namespace=f"/{robot}",
                   container=test_container(guard_mutation=False, stats_period_s=0))
    factory(probe)
    if unknown := sorted(set(variant.parameters) - set(probe.declared)):
        raise CompareError(f"variant {variant.label} ({variant.component}) has no parameter "
                           f"{', '.join(unknown)}; its parameters: "
                           f"{', '.join(sorted(probe.declared)) or 'none'}")
    return {name: float(value) if isinstance(probe.declared[name], float)
            and isinstance(value, int) and not isinstance(value, bool) else value
            for name, value in variant.parameters.items()}


def _image(m: LogMessage) -> Image | None:
    """An rgb8 Image of a logged Image or CompressedImage (JPEG, PNG)."""
    msg = m.message
    if m.type == "sensor_msgs/msg/Image":
        return msg
    rgb = cv2.imdecode(np.frombuffer(bytes(msg.data), np.uint8), cv2.IMREAD_COLOR_RGB)
    if rgb is None:
        return None
    out = Image(header=msg.header, height=rgb.shape[0], width=rgb.shape[1], encoding="rgb8",
                step=rgb.shape[1] * 3)
    out.data = rgb.tobytes()
    return out


@dataclass
class _Truth:
    times: list[int] = field(default_factory=list)
    values: list[Any] = field(default_factory=list)

    def at(self, t: int, fresh_ns: int = 500_000_000) -> Any:
        i = bisect.bisect_right(self.times, t) - 1
        return self.values[i] if i >= 0 and t - self.times[i] <= fresh_ns else None


def _yaw(q: Any) -> float:
    return math.atan2(2 * (q.w * q.z + q.x * q.y), 1 - 2 * (q.y * q.y + q.z * q.z))


def compare_components(
    log: TeamLog,
    a: Variant,
    b: Variant,
    *,
    robot: str,
    image_topic: str = "camera/image_raw/compressed",
    input_topic: str = "camera/image_raw",
    output_topic: str = "ball/detection",
    vfov_deg: float = 70.0,
    agree_deg: float = 2.0,
    start_ns: int | None = None,
    end_ns: int | None = None,
    progress: Callable[[int], None] | None = None,
) -> Comparison:
    """Replay ``robot``'s images of ``log`` through variants ``a`` and ``b`` (the module
    says how); ``vfov_deg`` is the robot camera's vertical field of view (the images'
    aspect gives the horizontal one).

    Raises :class:`CompareError` for a variant that cannot be made or a log without that
    robot's images.
    """
    if a.label == b.label:
        raise CompareError(f"the two variants need different labels, not both {a.label!r}")
    runners = [_Runner(v, robot=robot, input_topic=input_topic, output_topic=output_topic)
               for v in (a, b)]
    truth_pose, truth_ball, neck = _Truth(), _Truth(), _Truth()
    frames: list[FrameResult] = []
    images = 0
    started = time.perf_counter()
    topics = [f"/{robot}/{t}" for t in (image_topic, "ground_truth/pose", "ground_truth/ball",
                                         "joint_states")]
    for m in log.messages(topics, start_ns=start_ns, end_ns=end_ns):
        if m.topic == "ground_truth/pose":
            p = m.message.pose
            truth_pose.times.append(m.log_time_ns)
            truth_pose.values.append((p.position.x, p.position.y, _yaw(p.orientation)))
        elif m.topic == "ground_truth/ball":
            p = m.message.pose.position
            truth_ball.times.append(m.log_time_ns)
            truth_ball.values.append((p.x, p.y))
        elif m.topic == "joint_states":
            names = list(m.message.name)
            if "neck_yaw" in names:
                neck.times.append(m.log_time_ns)
                neck.values.append(float(m.message.position[names.index("neck_yaw")]))
        else:
            image = _image(m)
            if image is None:
                continue
            images += 1
            (da, ta), (db, tb) = (r.run(image, m.log_time_ns) for r in runners)
            yaw, in_view = _truth_yaw(truth_pose.at(m.log_time_ns), truth_ball.at(m.log_time_ns),
                                      neck.at(m.log_time_ns, 1_000_000_000), image, vfov_deg)
            frames.append(FrameResult(m.log_time_ns, _point(da), _point(db), ta, tb, yaw,
                                      in_view))
            if progress is not None and images % 20 == 0:
                progress(m.log_time_ns)
    if not frames:
        raise CompareError(f"{log.path} has no images of {robot} on {image_topic}")
    return Comparison(robot, a, b, frames, agree_deg, time.perf_counter() - started)


def _point(msg: Any) -> tuple[float, float, float] | None:
    return None if msg is None else (msg.point.x, msg.point.y, msg.point.z)


def _truth_yaw(pose: tuple[float, float, float] | None, ball: tuple[float, float] | None,
               neck_yaw: float | None, image: Image, vfov_deg: float
               ) -> tuple[float | None, bool]:
    if pose is None or ball is None:
        return None, False
    x, y, yaw = pose
    bearing = math.atan2(ball[1] - y, ball[0] - x) - yaw - (neck_yaw or 0.0)
    bearing = math.remainder(bearing, math.tau)
    half_h = math.atan(math.tan(math.radians(vfov_deg) / 2) * image.width / image.height)
    return bearing, abs(bearing) < half_h


def write_report(comparison: Comparison, folder: str | os.PathLike[str]) -> Path:
    """``folder/report.md`` with the figures, two plots (yaw over time with the truth;
    callback times) and the worst disagreements; returns the report's path."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(folder)
    out.mkdir(parents=True, exist_ok=True)
    c = comparison
    t0 = c.frames[0].t_ns
    ts = [(f.t_ns - t0) / 1e9 for f in c.frames]
    fig, ax = plt.subplots(figsize=(9, 3.2))
    for side, variant, marker in (("a", c.a, "o"), ("b", c.b, "x")):
        pts = [(t, _deg(getattr(f, side)[0])) for t, f in zip(ts, c.frames, strict=True)
               if getattr(f, side) is not None]
        if pts:
            ax.plot(*zip(*pts, strict=True), marker, ms=3, label=variant.label)
    truth = [(t, _deg(f.truth_yaw)) for t, f in zip(ts, c.frames, strict=True)
             if f.truth_yaw is not None and f.in_view]
    if truth:
        ax.plot(*zip(*truth, strict=True), "-", lw=1, color="grey", label="truth (in view)")
    ax.set_xlabel("s from the first image")
    ax.set_ylabel("ball yaw (deg, left +)")
    ax.legend(loc="upper right", fontsize=8)
    fig.tight_layout()
    fig.savefig(out / "yaw.png", dpi=100)
    plt.close(fig)
    fig, ax = plt.subplots(figsize=(5, 3))
    ax.boxplot([[f.a_ms for f in c.frames], [f.b_ms for f in c.frames]])
    ax.set_xticks([1, 2], [c.a.label, c.b.label])
    ax.set_ylabel("callback time (ms)")
    fig.tight_layout()
    fig.savefig(out / "callbacks.png", dpi=100)
    plt.close(fig)
    s = c.summary()
    rows = [("detection rate", "detection_rate", "{:.0%}"),
            (f"hits (ball in view, within {c.agree_deg:g}°)", "hit_rate", "{:.0%}"),
            ("false detections (out of view)", "false_rate", "{:.0%}"),
            ("yaw error median (deg)", "error_median_deg", "{:.2f}"),
            ("yaw error p95 (deg)", "error_p95_deg", "{:.2f}"),
            ("callback median (ms)", "callback_median_ms", "{:.2f}"),
            ("callback p95 (ms)", "callback_p95_ms", "{:.2f}")]
    lines = [f"# {c.a.label} vs {c.b.label} on {c.robot}'s images", "",
             f"{_named(c.a)} against {_named(c.b)}: {len(c.frames)} images "
             f"({int(s['both']['in_view'])} with the ball in view by the ground truth, "
             f"{int(s['both']['out_view'])} out of view, "
             f"{int(s['both']['frames'] - s['both']['judged'])} without ground truth), "
             f"replayed in {c.seconds:.1f} s. They agree (both nothing, or within "
             f"{c.agree_deg:g}°) on {s['both']['agreement']:.0%} of the images. A hit is "
             f"a detection within {c.agree_deg:g}° of the true bearing. Callback times are "
             "single-shot (one call per image, no warm-up: the first calls may include "
             "first-use costs).", "",
             f"| | {c.a.label} | {c.b.label} |", "|---|---|---|"]
    for title, key, fmt in rows:
        lines.append(f"| {title} | {_fmt(fmt, s[c.a.label][key])} | "
                     f"{_fmt(fmt, s[c.b.label][key])} |")
    lines += ["", "![ball yaw over time](yaw.png)", "", "![callback times](callbacks.png)",
              "", "## Where they disagree most", ""]
    worst = c.disagreements()
    lines += [f"- {(e.start_ns - t0) / 1e9:7.2f} s: {e.description}" for e in worst] or [
        "none: they agree on every image"]
    path = out / "report.md"
    path.write_text("\n".join(lines) + "\n")
    return path


def _named(v: Variant) -> str:
    settings = ", ".join(f"{k}={val!r}" for k, val in v.parameters.items())
    return f"`{v.component}`" + (f" ({settings})" if settings else "")


def _fmt(fmt: str, value: float) -> str:
    return "n/a" if math.isnan(value) else fmt.format(value)
