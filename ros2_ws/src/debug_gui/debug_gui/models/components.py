"""The components view's data: every callback of a robot with its figures and history.

Fed by the robot's ``<namespace>/efficient_comm/stats`` topic (ExecutorStats, one message
per process and period: a robot may run several containers and standalone nodes). Rows are
keyed by process and callback, so two processes with a node of the same name stay apart;
a process not heard from for :data:`STALE_AFTER_S` drops out (it ended). Ages go by the
messages' stamps on the source's clock (:mod:`.ages`): a paused playback keeps its rows, a
seek (``reset``) forgets them.

A callback is flagged when its own time exceeds its period: for a timer, its p95 longer
than the timer's period; for anything else, its mean longer than the interval between its
calls (``1 / rate``), i.e. it is busy more than all of the time and falls behind.
"""

from __future__ import annotations

import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from efficient_comm import from_msg

from ..errors import DebugGuiError, InvalidInput
from ..robots import STATS_SUFFIX, RobotId
from ..source import Source, Stream
from .ages import StampAges

#: How many past values each row keeps (one per stats message: 30 s at the default 1 s).
HISTORY = 30
#: A process whose stats stopped this long ago is gone.
STALE_AFTER_S = 10.0
#: The robot's clock counts as real time while it runs within this factor of the GUI's.
REAL_TIME_TOLERANCE = 0.1
#: ... and its stamps lie within this of the GUI's wall clock (s): a manual clock in
#: lockstep counts from its own start, far from the epoch.
WALL_CLOCK_TOLERANCE_S = 3600.0
#: The clock's rate is judged over at least this much of the GUI's time (s).
CLOCK_SPAN_S = 3.0
#: Columns rows can be sorted by.
SORT_KEYS = (
    "node", "kind", "name", "process", "calls", "exceptions", "drops", "rate_hz",
    "mean_ns", "p95_ns", "max_ns", "period_ns", "over_period",
)


@dataclass(slots=True)
class Row:
    """One callback of one process, as the view shows it."""

    process: str
    node: str
    kind: str
    name: str
    calls: int = 0
    exceptions: int = 0
    drops: int = 0
    rate_hz: float = 0.0
    mean_ns: int = 0
    p95_ns: int = 0
    max_ns: int = 0
    period_ns: int = 0
    #: Past mean own times (ns), oldest first.
    history: list[int] = field(default_factory=list)

    @property
    def key(self) -> tuple[str, str, str, str]:
        return (self.process, self.node, self.kind, self.name)

    @property
    def over_period(self) -> bool:
        """The callback's own time exceeds its period (it cannot keep its rate)."""
        if self.period_ns > 0:
            return self.p95_ns > self.period_ns
        return self.rate_hz > 0 and self.mean_ns > 1e9 / self.rate_hz


class _Series:
    __slots__ = ("history", "last")

    def __init__(self) -> None:
        self.history: deque[int] = deque(maxlen=HISTORY)
        self.last: Any = None


class ComponentsModel:
    """Callback statistics of one robot (activate to receive, deactivate to stop)."""

    def __init__(
        self,
        source: Source,
        robot: RobotId,
        *,
        rate_hz: float = 1.0,
        clock: Callable[[], float] | None = None,
        wall_clock: Callable[[], float] = time.time,
    ) -> None:
        self.source = source
        self.robot = robot
        self.rate_hz = rate_hz
        #: The source's clock (seconds): monotonic live, the log's time in a playback.
        self._clock = clock or source.now
        self._wall_clock = wall_clock
        #: (GUI time, robot stamp in s) of the first and the latest statistics heard.
        self._first_stamp: tuple[float, float] | None = None
        self._last_stamp: tuple[float, float] | None = None
        self._lock = threading.Lock()
        self._feed: Stream | None = None
        self._ages = StampAges(self._clock)
        self._unsubscribe_reset: Callable[[], None] | None = None
        #: process key -> (time heard, its last stamp (ns), {callback key -> series})
        self._processes: dict[
            str, tuple[float, int, dict[tuple[str, str, str], _Series]]] = {}
        self._last_stamp_ns = 0
        self.messages = 0
        #: When (source's clock) the last statistics were delivered (None: none yet).
        self.last_heard: float | None = None

    # -- feed --------------------------------------------------------------------------

    def activate(self) -> None:
        """Subscribe at the view's rate (idempotent)."""
        from efficient_comm_interfaces.msg import ExecutorStats

        if self._feed is None:
            self._unsubscribe_reset = self.source.on_reset(self.reset)
            self._feed = self.source.subscribe(
                self.robot, STATS_SUFFIX, ExecutorStats, self.on_stats, rate_hz=self.rate_hz
            )

    def deactivate(self) -> None:
        """Close the feed: the robot stops computing snapshots for us."""
        feed, self._feed = self._feed, None
        unsubscribe, self._unsubscribe_reset = self._unsubscribe_reset, None
        if feed is not None:
            feed.close()
        if unsubscribe is not None:
            unsubscribe()

    def reset(self) -> None:
        """Forget every process, history and stamp (the source moved to another instant)."""
        with self._lock:
            self._processes.clear()
            self._first_stamp = self._last_stamp = None
            self._last_stamp_ns = 0
            self._ages.reset()
            self.messages = 0
            self.last_heard = None

    @property
    def active(self) -> bool:
        return self._feed is not None

    def on_stats(self, msg: Any) -> None:
        """One ExecutorStats message (called on the Hub's thread, or by tests)."""
        process = f"{msg.process_name} ({msg.hostname}:{msg.pid})"
        stamp_ns = from_msg(msg.stamp)
        with self._lock:
            now = self._ages.heard(stamp_ns)
            _, _, series = self._processes.get(process, (now, 0, {}))
            seen = set()
            for cb in msg.callbacks:
                key = (cb.node, cb.kind, cb.name)
                seen.add(key)
                s = series.setdefault(key, _Series())
                s.last = cb
                s.history.append(int(cb.mean_ns))
            for key in set(series) - seen:
                del series[key]  # destroyed (a component unloaded)
            self._processes[process] = (now, stamp_ns, series)
            self.messages += 1
            self.last_heard, self._last_stamp_ns = now, stamp_ns
            stamp = stamp_ns / 1e9
            if stamp > 0:
                self._last_stamp = (now, stamp)
                if self._first_stamp is None or stamp < self._first_stamp[1]:
                    self._first_stamp = self._last_stamp

    # -- what the view reads ------------------------------------------------------------

    def rows(self, *, sort_by: str = "p95_ns", descending: bool = True) -> list[Row]:
        """Every callback of every live process, sorted."""
        if sort_by not in SORT_KEYS:
            raise InvalidInput(f"cannot sort by {sort_by!r}; one of {', '.join(SORT_KEYS)}")
        out: list[Row] = []
        with self._lock:
            for process, (heard, stamp_ns, series) in list(self._processes.items()):
                if self._ages.age_s(stamp_ns, delivered_s=heard) > STALE_AFTER_S:
                    del self._processes[process]
                    continue
                for s in series.values():
                    cb = s.last
                    out.append(Row(
                        process=process, node=cb.node, kind=cb.kind, name=cb.name,
                        calls=int(cb.calls), exceptions=int(cb.exceptions),
                        drops=int(cb.drops), rate_hz=float(cb.rate_hz),
                        mean_ns=int(cb.mean_ns), p95_ns=int(cb.p95_ns),
                        max_ns=int(cb.max_ns), period_ns=int(cb.period_ns),
                        history=list(s.history),
                    ))
        out.sort(key=lambda r: (getattr(r, sort_by), r.key), reverse=descending)
        return out

    def clock_factor(self) -> float | None:
        """How fast the robot's clock runs against the GUI's (1.0: real time; 0.4 under a
        lockstep simulation that manages 40 %), from the statistics' stamps; None until
        :data:`CLOCK_SPAN_S` of them were heard."""
        with self._lock:
            first, last = self._first_stamp, self._last_stamp
        if first is None or last is None or last[0] - first[0] < CLOCK_SPAN_S:
            return None
        return (last[1] - first[1]) / (last[0] - first[0])

    def clock_note(self) -> str:
        """What the view says when the robot's rates are not per second of real time: a
        robot on a simulated or manual clock (``--lockstep``) counts rates, periods and
        execution-time windows in its own seconds. Empty for a robot on the wall clock."""
        factor = self.clock_factor()
        with self._lock:
            last = self._last_stamp
        if factor is None or last is None:
            return ""
        # A log's stamps are far from today's wall clock whatever clock the robot ran on.
        off_wall = (self.source.live
                    and abs(last[1] - self._wall_clock()) > WALL_CLOCK_TOLERANCE_S)
        if not off_wall and abs(factor - 1.0) <= REAL_TIME_TOLERANCE:
            return ""
        return (f"rates in the robot's time: its clock runs at {factor:.1f}x real time "
                "(simulated or lockstep)")

    def age_s(self) -> float | None:
        """How old the last stats message is, by its stamp on the source's clock (None:
        none yet)."""
        with self._lock:
            if self.last_heard is None:
                return None
            return self._ages.age_s(self._last_stamp_ns, delivered_s=self.last_heard)

    def statistics_published(self) -> bool:
        """False for a robot that publishes no statistics at all (a plain ROS 2 robot, found
        with the Hub's ``plain_robots``), so the view can say so instead of waiting."""
        if self.last_heard is not None:
            return True
        try:
            return self.source.publishes_statistics(self.robot)
        except DebugGuiError:  # the GUI is closing: nothing to tell
            return True


_BARS = "▁▂▃▄▅▆▇█"


def sparkline(values: list[int]) -> str:
    """A one-line history (``▁▃▇``), scaled to the row's own maximum."""
    if not values:
        return ""
    top = max(values)
    if top <= 0:
        return _BARS[0] * len(values)
    return "".join(_BARS[min(len(_BARS) - 1, v * len(_BARS) // (top + 1))] for v in values)
