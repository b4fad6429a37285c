"""Clocks the executor schedules timers on: real ROS time, or manual time for tests."""

from __future__ import annotations

import threading
import time

from builtin_interfaces.msg import Time


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


def to_msg(ns: int) -> Time:
    """``builtin_interfaces/Time`` for a nanosecond timestamp, for message headers."""
    return Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def from_msg(stamp: Time) -> int:
    """Integer nanoseconds of a ``builtin_interfaces/Time`` (a header stamp): the inverse
    of :func:`to_msg`, and the one place that does this arithmetic."""
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)
