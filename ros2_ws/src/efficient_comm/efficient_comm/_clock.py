"""Clocks the executor schedules timers on: real ROS time, manual time for tests, simulated
time driven by another process (``/clock``), and a skewed clock (a computer of its own)."""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass
from typing import TYPE_CHECKING

from builtin_interfaces.msg import Time

if TYPE_CHECKING:
    from .handle import Clock


class SystemClock:
    """ROS time without simulation: the wall clock in nanoseconds (what rclpy uses)."""

    __slots__ = ()
    is_manual = False

    def now_ns(self) -> int:
        return time.time_ns()


class ManualClock:
    """Time that moves only when told to, so tests and lockstep simulation are exact.

    The executor never sleeps on a manual clock: :meth:`advance` on the executor moves the
    clock forward timer by timer and runs every callback that falls due on the way.
    """

    is_manual = True

    def __init__(self, *, start_ns: int = 0) -> None:
        self._now = start_ns
        self._lock = threading.Lock()

    def now_ns(self) -> int:
        return self._now

    def set_ns(self, now_ns: int) -> None:
        """Move to ``now_ns``; time never runs backwards."""
        with self._lock:
            if now_ns < self._now:
                raise ValueError(f"manual clock cannot go back from {self._now} to {now_ns}")
            self._now = now_ns


class SimClock:
    """Simulated time, told by another process on ``/clock`` (``use_sim_time`` in ROS).

    Two readings: :meth:`receive` records the latest time the time source published (the
    *target*; any thread), and the executor moves :meth:`now_ns` up to it timer by timer, as
    :meth:`ConsecutiveExecutor.advance` moves a :class:`ManualClock`: every callback sees the
    time of its own timer's deadline, not whenever the message happened to arrive, so a run
    repeats exactly. Time never runs backwards: an older ``/clock`` (a time source that
    restarted) is ignored and counted in :attr:`ignored`. Before the first ``/clock``
    message the time stands at ``start_ns`` (0), as ROS time does with ``use_sim_time`` and
    no clock yet: timers created then are due one period after 0 and fire with the first
    message that reaches their deadline.
    """

    is_manual = True

    def __init__(self, *, start_ns: int = 0) -> None:
        self._now = start_ns
        self._target = start_ns
        self._lock = threading.Lock()
        #: /clock messages older than the time already received (ignored).
        self.ignored = 0
        #: Whether any /clock message arrived yet.
        self.started = False

    def now_ns(self) -> int:
        return self._now

    @property
    def target_ns(self) -> int:
        """The latest time received: the executor has work while :meth:`now_ns` is behind."""
        return self._target

    def receive(self, time_ns: int) -> bool:
        """Record a time the source published; False (and counted) if it went back."""
        with self._lock:
            self.started = True
            if time_ns < self._target:
                self.ignored += 1
                return False
            self._target = time_ns
            return True

    def set_ns(self, now_ns: int) -> None:
        """Move to ``now_ns`` (the executor does, between timers); never backwards."""
        with self._lock:
            if now_ns < self._now:
                raise ValueError(f"sim clock cannot go back from {self._now} to {now_ns}")
            self._now = now_ns
            self._target = max(self._target, now_ns)


@dataclass(frozen=True, slots=True)
class SkewedClock:
    """``base`` time shifted by ``offset_ns`` and running ``drift_ppm`` fast.

    ``local = base + offset_ns + drift_ppm * 1e-6 * (base - epoch_ns)``: at ``base ==
    epoch_ns`` the clock is exactly ``offset_ns`` ahead, and every second of base time it
    gains ``drift_ppm`` microseconds (loses, when negative). A container given
    ``clock_offset_s`` runs on one over the system clock, as a separate computer whose
    clock is not synchronised would; team_clock gives simulated robots in one process one
    each (its estimator is what measures them).
    """

    base: Clock
    offset_ns: int = 0
    drift_ppm: float = 0.0
    epoch_ns: int = 0

    def now_ns(self) -> int:
        return self.local_ns(self.base.now_ns())

    def local_ns(self, base_ns: int) -> int:
        """The local reading at base time ``base_ns`` (for computing ground truth)."""
        return base_ns + self.offset_ns + round(self.drift_ppm * 1e-6 * (base_ns - self.epoch_ns))

    def base_of(self, local_ns: int) -> int:
        """The base time at which this clock reads ``local_ns`` (inverse of :meth:`local_ns`)."""
        rate = 1.0 + self.drift_ppm * 1e-6
        return self.epoch_ns + round((local_ns - self.offset_ns - self.epoch_ns) / rate)


def to_msg(ns: int) -> Time:
    """``builtin_interfaces/Time`` for a nanosecond timestamp, for message headers."""
    return Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def from_msg(stamp: Time) -> int:
    """Integer nanoseconds of a ``builtin_interfaces/Time`` (a header stamp): the inverse
    of :func:`to_msg`, and the one place that does this arithmetic."""
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)
