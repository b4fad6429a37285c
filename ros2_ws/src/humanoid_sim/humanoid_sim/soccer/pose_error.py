"""How far the robot's pose estimate is from the truth: the localization's error, measured.

Whichever source publishes ``localization/pose`` (:mod:`.localization`), each estimate is
compared with the simulator's ground truth at the estimate's own stamp: the position error
on the ground and the heading error. The truth then is interpolated between the samples
either side of the stamp (at most :data:`MAX_TRUTH_GAP_NS` apart), else the nearest sample
within :data:`MAX_TRUTH_AGE_NS`; so an estimate waits until truth newer than its stamp has
arrived. Why: in the team match the truth comes from another process at 10 Hz of simulated
time, later than the robot's own estimate of the same moment, and with a world slower than
real time its samples are further apart than that window (with the nearest sample alone,
2 of a particle filter's estimates in 45 s were scored on a loaded machine).
``localization/source`` says which source it was, so a report names it.
Not the robot's: it reads ground truth, like :mod:`.monitor`.
"""

from __future__ import annotations

import bisect
import math
import statistics
from collections import deque
from dataclasses import dataclass, field

from geometry_msgs.msg import PoseStamped, PoseWithCovarianceStamped
from std_msgs.msg import String

from efficient_comm import from_msg, latched_qos
from efficient_comm.handle import NodeHandle

from .localization import wrap, yaw_of

#: Truth further from an estimate's stamp than this is not compared with it ...
MAX_TRUTH_AGE_NS = 50_000_000
#: ... unless truth samples either side of the stamp, at most this far apart, give it.
MAX_TRUTH_GAP_NS = 1_000_000_000


def _percentile(values: list[float], q: float) -> float:
    if not values:
        return math.nan
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, round(q * (len(ordered) - 1)))]


@dataclass
class PoseErrors:
    """The errors of the estimates compared so far; ``times_s`` from the monitor's start."""

    source: str = "none"
    times_s: list[float] = field(default_factory=list)
    position_m: list[float] = field(default_factory=list)
    heading_rad: list[float] = field(default_factory=list)

    def since(self, seconds: float) -> PoseErrors:
        """Only the estimates from ``seconds`` on (after the filter has had time to settle)."""
        start = bisect.bisect_left(self.times_s, seconds)
        return PoseErrors(self.source, self.times_s[start:], self.position_m[start:],
                          self.heading_rad[start:])

    def summary(self) -> dict[str, float]:
        """Mean, p95 and max of the errors (:attr:`source` says whose they are)."""
        heading_deg = [math.degrees(abs(h)) for h in self.heading_rad]
        return {
            "estimates": len(self.position_m),
            "position_error_mean_m": (statistics.fmean(self.position_m) if self.position_m
                                      else math.nan),
            "position_error_p95_m": _percentile(self.position_m, 0.95),
            "position_error_max_m": max(self.position_m, default=math.nan),
            "heading_error_mean_deg": (statistics.fmean(heading_deg) if heading_deg
                                       else math.nan),
            "heading_error_p95_deg": _percentile(heading_deg, 0.95),
        }


class PoseErrorMonitor:
    """Subscribes ``localization/pose``, ``localization/source`` and the truth
    (``truth_topic``, default ``ground_truth/robot``); :attr:`errors` grows with each
    estimate."""

    def __init__(self, node: NodeHandle) -> None:
        self.node = node
        topic = node.declare_parameter("truth_topic", "ground_truth/robot")
        self.started_ns = node.clock.now_ns()
        self.errors = PoseErrors()
        #: Recent truth: stamp (ns), x, y, heading.
        self._truth: deque[tuple[int, float, float, float]] = deque(maxlen=400)
        #: Estimates waiting for the truth after their stamp: stamp (ns), x, y, heading.
        self._pending: deque[tuple[int, float, float, float]] = deque(maxlen=400)
        node.create_subscription(PoseStamped, topic, self._on_truth, qos=10)
        node.create_subscription(String, "localization/source", self._on_source,
                                 qos=latched_qos())
        node.create_subscription(PoseWithCovarianceStamped, "localization/pose",
                                 self._on_estimate, qos=10)

    def _on_source(self, source: String) -> None:
        self.errors.source = source.data

    def _on_truth(self, truth: PoseStamped) -> None:
        p = truth.pose
        self._truth.append((from_msg(truth.header.stamp), p.position.x, p.position.y,
                            yaw_of(p.orientation)))
        self._score()

    def _on_estimate(self, estimate: PoseWithCovarianceStamped) -> None:
        p = estimate.pose.pose
        self._pending.append((from_msg(estimate.header.stamp), p.position.x, p.position.y,
                              yaw_of(p.orientation)))
        self._score()

    def _score(self) -> None:
        """Compare the waiting estimates whose truth has arrived (see the module docstring)."""
        while self._pending and self._truth and self._pending[0][0] <= self._truth[-1][0]:
            stamp, x, y, heading = self._pending.popleft()
            truth = self._truth_at(stamp)
            if truth is None:
                continue
            self.errors.times_s.append((stamp - self.started_ns) / 1e9)
            self.errors.position_m.append(math.hypot(x - truth[0], y - truth[1]))
            self.errors.heading_rad.append(wrap(heading - truth[2]))

    def _truth_at(self, stamp: int) -> tuple[float, float, float] | None:
        samples = list(self._truth)
        after = bisect.bisect_left([s[0] for s in samples], stamp)
        if 0 < after < len(samples):
            (t0, x0, y0, h0), (t1, x1, y1, h1) = samples[after - 1], samples[after]
            if t1 - t0 <= MAX_TRUTH_GAP_NS:
                f = (stamp - t0) / (t1 - t0) if t1 > t0 else 0.0
                return x0 + f * (x1 - x0), y0 + f * (y1 - y0), h0 + f * wrap(h1 - h0)
        near = [s for s in samples[max(0, after - 1):after + 1]
                if abs(s[0] - stamp) <= MAX_TRUTH_AGE_NS]
        if not near:
            return None
        best = min(near, key=lambda s: abs(s[0] - stamp))
        return best[1], best[2], best[3]
