"""Execution time and call frequency of every callback, as the GUI views will show them.

Recording costs two ``perf_counter_ns`` calls and a few integer additions per callback, so
it is always on. :meth:`CallbackStats.snapshot` gives an immutable copy for readers in
other threads.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

from ._failures import FailureLog

CallbackKind = Literal["subscription", "timer", "service", "client"]


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
        "total_ns",
    )

    def __init__(self, node: str, kind: CallbackKind, name: str) -> None:
        self.node = node
        self.kind: CallbackKind = kind
        self.name = name
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
        if not self.calls:
            self.first_call_ns = start_ns
        self.calls += 1
        self.last_call_ns = start_ns
        elapsed = elapsed_ns
        self.total_ns += elapsed
        if elapsed > self.max_ns:
            self.max_ns = elapsed

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

    def add(self, node: str, kind: CallbackKind, name: str) -> CallbackStats:
        entry = CallbackStats(node, kind, name)
        self._entries.append(entry)
        return entry

    def remove_node(self, node: str) -> None:
        self._entries = [e for e in self._entries if e.node != node]

    def snapshot(self) -> list[StatsSnapshot]:
        return [e.snapshot() for e in self._entries]


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
