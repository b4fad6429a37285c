"""How old a robot's message is: by its own stamp, on the source's clock.

A message's age is not the time since it was delivered: a playback catching up after a
seek delivers two seconds of messages at one instant, and a paused one delivers nothing,
yet its last messages are as old as they were. Nor can a stamp be compared with the
source's clock directly: live, the clock is the GUI's monotonic one and a robot stamps
with its own (the wall clock, or a simulated one under lockstep).

So each robot's clock is tied to the source's by its newest stamp: when a message stamped
``s`` is the newest heard, delivered at source time ``t``, the robot's "now" is
``s + (source.now() - t)``, and a message stamped ``m`` is ``(s - m) + (source.now() - t)``
old. It follows the source's clock (a paused playback ages nothing, a jump forward ages
everything), and a message stamped older than the robot's newest shows as that much older.
A message without a stamp (0) is as old as the time since its delivery.
"""

from __future__ import annotations

from collections.abc import Callable


class StampAges:
    """One robot's clock tied to the source's (not thread-safe: the model's lock guards it)."""

    __slots__ = ("_clock", "_newest_at", "_newest_ns")

    def __init__(self, clock: Callable[[], float]) -> None:
        self._clock = clock
        self._newest_ns = 0
        self._newest_at = 0.0

    def heard(self, stamp_ns: int) -> float:
        """Note a message stamped ``stamp_ns`` delivered now; returns now (its delivery
        time, for :meth:`age_s` of a message without a stamp)."""
        now = self._clock()
        if stamp_ns > 0 and stamp_ns >= self._newest_ns:
            self._newest_ns, self._newest_at = stamp_ns, now
        return now

    def age_s(self, stamp_ns: int, *, delivered_s: float) -> float:
        """Seconds the message stamped ``stamp_ns`` (delivered at ``delivered_s`` on the
        source's clock) is old now; never negative."""
        now = self._clock()
        if stamp_ns > 0 and self._newest_ns > 0:
            return max(0.0, (self._newest_ns - stamp_ns) / 1e9 + now - self._newest_at)
        return max(0.0, now - delivered_s)

    def reset(self) -> None:
        """Forget the robot's clock (a seek: the next stamps may be older)."""
        self._newest_ns = 0
        self._newest_at = 0.0
