"""Per-topic statistics: messages, bytes, drops by reason, and the bridge's own latency.

Counters are updated from adapter threads and the executor thread alike, so one lock
guards them; a snapshot is a plain frozen value for logs, tests and the benchmark.
"""

from __future__ import annotations

import collections
import statistics
import threading
from dataclasses import dataclass, field


@dataclass(frozen=True, slots=True)
class TopicStatsSnapshot:
    topic: str
    direction: str  # "to_<peer>" or "from_<peer>"
    messages: int
    bytes: int
    drops: dict[str, int] = field(default_factory=dict)
    latency_median_us: float | None = None
    latency_p99_us: float | None = None

    @property
    def dropped(self) -> int:
        return sum(self.drops.values())


class TopicStats:
    """One route direction's counters. ``drops`` reasons name what happened (throttled,
    queue_full, connection_dropped, no_subscriber, malformed, untranslatable, oversize...)."""

    def __init__(self, topic: str, direction: str, *, window: int = 2048) -> None:
        self.topic = topic
        self.direction = direction
        self._lock = threading.Lock()
        self._messages = 0
        self._bytes = 0
        self._drops: collections.Counter[str] = collections.Counter()
        self._latency_ns: collections.deque[int] = collections.deque(maxlen=window)

    def delivered(self, nbytes: int, latency_ns: int | None = None) -> None:
        with self._lock:
            self._messages += 1
            self._bytes += nbytes
            if latency_ns is not None:
                self._latency_ns.append(latency_ns)

    def dropped(self, reason: str, count: int = 1) -> None:
        with self._lock:
            self._drops[reason] += count

    def snapshot(self) -> TopicStatsSnapshot:
        with self._lock:
            lat = sorted(self._latency_ns)
            return TopicStatsSnapshot(
                self.topic,
                self.direction,
                self._messages,
                self._bytes,
                dict(self._drops),
                statistics.median(lat) / 1e3 if lat else None,
                lat[min(len(lat) - 1, int(len(lat) * 0.99))] / 1e3 if lat else None,
            )
