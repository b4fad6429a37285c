"""A link's byte budget and what crossed it: the team link's bandwidth rules, measured.

RoboCup gives a robot a few kilobytes per second on the field's network, and a robot that
sends more harms its own team first (the access point drops what does not fit, for
everybody). :class:`ByteBudget` is a token bucket over the bytes a link hands to its
transport (payload and the link's own header): ``rate`` bytes per second on average, at
most ``burst`` at once; a message that does not fit is not sent, and counted. It judges
before sending, so what goes out never exceeds ``burst + rate · t`` in any interval ``t``.

:class:`LinkUsage` is what a link reports: bytes and messages each way, drops for the
budget, the average and the busiest second's rate. Throttling (a message rate per topic) is
the router's; the budget is the link's, over all its topics together.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from dataclasses import dataclass


@dataclass(frozen=True, slots=True)
class LinkUsage:
    """What crossed a link since it started (bytes as handed to the transport)."""

    link: str
    robot_id: str
    sent_messages: int
    sent_bytes: int
    received_messages: int
    received_bytes: int
    #: Messages not sent because they did not fit the budget.
    over_budget: int
    elapsed_s: float
    #: Bytes per second allowed on average (None: no budget) and at once.
    budget_bytes_per_s: float | None
    budget_burst_bytes: int | None
    #: The most bytes sent within one second (whole seconds since the start).
    peak_bytes_per_s: int

    @property
    def sent_bytes_per_s(self) -> float:
        """The average rate sent since the start."""
        return self.sent_bytes / self.elapsed_s if self.elapsed_s > 0 else 0.0


class ByteBudget:
    """Token bucket over bytes; ``now_ns`` is a monotonic clock (real time: the budget
    shapes a real link, whatever clock the robot's software runs on)."""

    def __init__(self, rate_bytes_per_s: float, burst_bytes: int, *,
                 now_ns: Callable[[], int]) -> None:
        if rate_bytes_per_s <= 0 or burst_bytes <= 0:
            raise ValueError(f"a budget needs rate and burst > 0, got {rate_bytes_per_s}, "
                             f"{burst_bytes}")
        self.rate = rate_bytes_per_s
        self.burst = burst_bytes
        self._now_ns = now_ns
        self._tokens = float(burst_bytes)
        self._last_ns = now_ns()
        self._lock = threading.Lock()

    def take(self, nbytes: int) -> bool:
        """Spend ``nbytes`` if they fit now; False (nothing spent) if not."""
        with self._lock:
            now = self._now_ns()
            self._tokens = min(self.burst, self._tokens + (now - self._last_ns) * 1e-9 * self.rate)
            self._last_ns = now
            if nbytes > self._tokens:
                return False
            self._tokens -= nbytes
            return True


class UsageCounter:
    """Counts a link's traffic for :class:`LinkUsage` (thread-safe: adapters send from the
    executor and receive on their own threads)."""

    def __init__(self, link: str, robot_id: str, *, now_ns: Callable[[], int],
                 budget: ByteBudget | None = None) -> None:
        self.link, self.robot_id = link, robot_id
        self.budget = budget
        self._now_ns = now_ns
        self._start_ns = now_ns()
        self._lock = threading.Lock()
        self._sent = self._sent_bytes = self._received = self._received_bytes = 0
        self._over_budget = 0
        self._second = 0  # whole seconds since the start, of the window being counted
        self._second_bytes = 0
        self._peak = 0

    def admit(self, nbytes: int) -> bool:
        """Whether ``nbytes`` may be sent now (counted as over budget if not)."""
        if self.budget is None or self.budget.take(nbytes):
            return True
        with self._lock:
            self._over_budget += 1
        return False

    def sent(self, nbytes: int) -> None:
        with self._lock:
            second = (self._now_ns() - self._start_ns) // 1_000_000_000
            if second != self._second:
                self._second, self._second_bytes = second, 0
            self._second_bytes += nbytes
            self._peak = max(self._peak, self._second_bytes)
            self._sent += 1
            self._sent_bytes += nbytes

    def received(self, nbytes: int) -> None:
        with self._lock:
            self._received += 1
            self._received_bytes += nbytes

    def snapshot(self) -> LinkUsage:
        with self._lock:
            return LinkUsage(
                link=self.link, robot_id=self.robot_id, sent_messages=self._sent,
                sent_bytes=self._sent_bytes, received_messages=self._received,
                received_bytes=self._received_bytes, over_budget=self._over_budget,
                elapsed_s=(self._now_ns() - self._start_ns) / 1e9,
                budget_bytes_per_s=self.budget.rate if self.budget else None,
                budget_burst_bytes=self.budget.burst if self.budget else None,
                peak_bytes_per_s=self._peak,
            )
