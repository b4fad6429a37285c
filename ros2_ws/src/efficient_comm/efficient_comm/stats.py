"""Execution time and call frequency of every callback, as the GUI views will show them.

Recording costs two ``perf_counter_ns`` calls, a few integer additions and one store into a
small preallocated ring of recent durations per callback, so it is always on.
:meth:`CallbackStats.snapshot` gives an immutable copy for readers in other threads;
:class:`StatsWindow` turns the live counters into figures over the last window (rate, mean,
p95, max), what the ``<namespace>/efficient_comm/stats`` topic carries
(:mod:`efficient_comm.stats_publisher`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

from ._failures import FailureLog

CallbackKind = Literal["subscription", "timer", "service", "client"]

#: Durations kept per callback for the windowed p95 (a power of two: the ring index is a
#: mask). A window with more calls than this takes its p95 from the most recent ones.
RECENT = 128
_RECENT_MASK = RECENT - 1


@dataclass(frozen=True, slots=True)
class StatsSnapshot:
    """One callback's figures at one moment. Durations in nanoseconds.

    Durations are the callback's own time: with depth-first delivery, callbacks its
    publishes triggered are measured for themselves and not counted again here.
    """

    node: str
    kind: CallbackKind
    name: str
    calls: int
    exceptions: int
    dropped: int
    total_ns: int
    max_ns: int
    first_call_ns: int
    last_call_ns: int

    @property
    def mean_ns(self) -> float:
        return self.total_ns / self.calls if self.calls else 0.0

    @property
    def rate_hz(self) -> float:
        """Mean call frequency between the first and the last call."""
        span = self.last_call_ns - self.first_call_ns
        return (self.calls - 1) * 1e9 / span if self.calls > 1 and span > 0 else 0.0


class CallbackStats:
    """Live, mutable counters of one callback; written only by the executor thread."""

    __slots__ = (
        "calls",
        "dropped",
        "exceptions",
        "failures",
        "first_call_ns",
        "kind",
        "last_call_ns",
        "max_ns",
        "name",
        "node",
        "period_ns",
        "recent",
        "total_ns",
        "window_max_ns",
    )

    def __init__(self, node: str, kind: CallbackKind, name: str, *, period_ns: int = 0) -> None:
        self.node = node
        self.kind: CallbackKind = kind
        self.name = name
        #: A timer's period (0 for other kinds): a callback slower than it cannot keep up.
        self.period_ns = period_ns
        #: The last :data:`RECENT` own times, call ``i`` at ``i & (RECENT - 1)``; allocated
        #: once so that recording never allocates.
        self.recent = [0] * RECENT
        #: Longest call since :class:`StatsWindow` last took a window (it resets this).
        self.window_max_ns = 0
        self.calls = 0
        self.exceptions = 0
        #: What of its exceptions was logged (see efficient_comm._failures).
        self.failures = FailureLog()
        self.dropped = 0
        self.total_ns = 0
        self.max_ns = 0
        self.first_call_ns = 0
        self.last_call_ns = 0

    def record(self, start_ns: int, elapsed_ns: int) -> None:
        """One call that began at ``start_ns`` and ran for ``elapsed_ns`` of its own time."""
        calls = self.calls
        if not calls:
            self.first_call_ns = start_ns
        self.recent[calls & _RECENT_MASK] = elapsed_ns
        self.calls = calls + 1
        self.last_call_ns = start_ns
        self.total_ns += elapsed_ns
        if elapsed_ns > self.window_max_ns:  # the window's max never exceeds the overall one
            self.window_max_ns = elapsed_ns
            if elapsed_ns > self.max_ns:
                self.max_ns = elapsed_ns

    def snapshot(self) -> StatsSnapshot:
        return StatsSnapshot(
            self.node,
            self.kind,
            self.name,
            self.calls,
            self.exceptions,
            self.dropped,
            self.total_ns,
            self.max_ns,
            self.first_call_ns,
            self.last_call_ns,
        )


class StatsRegistry:
    """All callbacks of one executor (or one standalone node)."""

    def __init__(self) -> None:
        self._entries: list[CallbackStats] = []

    def add(
        self, node: str, kind: CallbackKind, name: str, *, period_ns: int = 0
    ) -> CallbackStats:
        entry = CallbackStats(node, kind, name, period_ns=period_ns)
        self._entries.append(entry)
        return entry

    def entries(self) -> list[CallbackStats]:
        """The live entries (read them in the thread that records into them)."""
        return list(self._entries)

    def remove_node(self, node: str) -> None:
        self._entries = [e for e in self._entries if e.node != node]

    def snapshot(self) -> list[StatsSnapshot]:
        return [e.snapshot() for e in self._entries]


@dataclass(frozen=True, slots=True)
class WindowedStats:
    """One callback over the last window: cumulative counts, windowed figures (ns, Hz).

    What one ``efficient_comm_interfaces/CallbackStats`` message carries.
    """

    node: str
    kind: CallbackKind
    name: str
    calls: int
    exceptions: int
    dropped: int
    rate_hz: float
    mean_ns: int
    p95_ns: int
    max_ns: int
    period_ns: int


class StatsWindow:
    """Figures of a registry's callbacks since the previous :meth:`take`.

    Each window's rate and mean come from the difference of the cumulative counters, its
    max from :attr:`CallbackStats.window_max_ns` (which :meth:`take` resets, so a registry
    has one window taker: its stats publisher), its p95 from the ring of recent durations.
    Nothing is computed between takes: a publisher nobody listens to does not call
    :meth:`take`, and the next window then simply covers the whole pause.
    Call it in the thread that records (the executor's).
    """

    def __init__(self, registry: StatsRegistry, *, now_ns: int) -> None:
        self._registry = registry
        self._start_ns = now_ns
        self._base: dict[int, tuple[CallbackStats, int, int]] = {}

    def take(self, now_ns: int) -> tuple[int, list[WindowedStats]]:
        """``(window length ns, one row per callback)``; starts the next window at ``now_ns``."""
        window_ns = max(now_ns - self._start_ns, 0)
        self._start_ns = now_ns
        rows: list[WindowedStats] = []
        base: dict[int, tuple[CallbackStats, int, int]] = {}
        for entry in self._registry.entries():
            _, calls0, total0 = self._base.get(id(entry), (entry, 0, 0))
            calls, total = entry.calls, entry.total_ns
            n = calls - calls0
            rows.append(
                WindowedStats(
                    entry.node,
                    entry.kind,
                    entry.name,
                    calls,
                    entry.exceptions,
                    entry.dropped,
                    n * 1e9 / window_ns if window_ns > 0 else 0.0,
                    (total - total0) // n if n > 0 else 0,
                    _p95(entry.recent, calls, min(n, RECENT)),
                    entry.window_max_ns if n > 0 else 0,
                    entry.period_ns,
                )
            )
            entry.window_max_ns = 0
            base[id(entry)] = (entry, calls, total)
        self._base = base  # entries removed from the registry are forgotten
        return window_ns, rows


def _p95(recent: list[int], calls: int, n: int) -> int:
    """95th percentile (nearest rank) of the last ``n`` of ``calls`` durations in ``recent``."""
    if n <= 0:
        return 0
    last = sorted(recent[(calls - 1 - i) & _RECENT_MASK] for i in range(n))
    return last[math.ceil(0.95 * n) - 1]


def format_stats(rows: Sequence[StatsSnapshot]) -> str:
    """A plain-text table of ``rows`` (``container.stats()``), one callback per line.

    Node and topic names are shown whole: columns are as wide as their longest entry, since
    a cut name (``.../image_raw`` of which robot?) is what a reader cannot tell apart.
    """
    header = ("node", "kind", "name", "calls", "Hz", "mean µs", "max µs", "exc", "drop")
    table = [header] + [
        (s.node, s.kind, s.name or "-", str(s.calls), f"{s.rate_hz:.1f}",
         f"{s.mean_ns / 1e3:.1f}", f"{s.max_ns / 1e3:.1f}", str(s.exceptions), str(s.dropped))
        for s in rows
    ]
    widths = [max(len(row[i]) for row in table) for i in range(len(header))]
    return "\n".join(
        " ".join(
            cell.ljust(width) if i < 3 else cell.rjust(width)
            for i, (cell, width) in enumerate(zip(row, widths, strict=True))
        ).rstrip()
        for row in table
    )
