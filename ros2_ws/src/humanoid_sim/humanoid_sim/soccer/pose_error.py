"""How far the robot's pose estimate is from the truth: the localization's error, measured.

Whichever source publishes ``localization/pose`` (:mod:`.localization`), each estimate is
compared with the simulator's ground truth at the estimate's own stamp (the truth sample
nearest in time, within :data:`MAX_TRUTH_AGE_NS`): the position error on the ground and
the heading error. ``localization/source`` says which source it was, so a report names it.
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

#: Truth further from an estimate's stamp than this is not compared with it.
MAX_TRUTH_AGE_NS = 50_000_000


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

    def _on_estimate(self, estimate: PoseWithCovarianceStamped) -> None:
        if not self._truth:
            return
        stamp = from_msg(estimate.header.stamp)
        nearest = min(self._truth, key=lambda sample: abs(sample[0] - stamp))
        if abs(nearest[0] - stamp) > MAX_TRUTH_AGE_NS:
            return
        p = estimate.pose.pose
        self.errors.times_s.append((stamp - self.started_ns) / 1e9)
        self.errors.position_m.append(math.hypot(p.position.x - nearest[1],
                                                 p.position.y - nearest[2]))
        self.errors.heading_rad.append(wrap(yaw_of(p.orientation) - nearest[3]))
