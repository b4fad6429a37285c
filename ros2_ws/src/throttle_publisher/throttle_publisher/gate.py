"""The per-subscriber decision: does this sample go to this subscriber?

A :class:`Gate` holds one subscriber's options and the little state they need. The
publisher asks every gate before it computes a sample (:meth:`Gate.wants`, no state
change: the demand API) and tells every gate about each sample it produced or skipped
(:meth:`Gate.offer`), so that ``every_nth`` counts the source's samples, computed or not.

``max_rate_hz`` is enforced with the generic cell rate algorithm (a virtual schedule): a
sample is taken if it is not earlier than the theoretical time of the next one minus a
tolerance, and each taken sample moves that time on by one period. So the long-run rate
never exceeds the request, and a source whose samples jitter around the requested
schedule does not lose every other one. The tolerance is a little over half the source's
own sample interval (a running estimate), and never more than one period.
"""

from __future__ import annotations

from .options import ThrottleOptions

_EMA = 0.125  # weight of the newest sample interval in the source-interval estimate
_TOLERANCE = 0.6  # of a source interval: a little over half, so exact ties are taken


class Gate:
    """One subscriber's throttle state; times are integer nanoseconds."""

    __slots__ = ("_count", "_last_offer_ns", "_period_ns", "_source_ns", "_tat_ns", "options")

    def __init__(self, options: ThrottleOptions) -> None:
        self.options = options
        self._period_ns = self._period(options)
        self._count = 0  # samples offered since the options took effect (for every_nth)
        self._tat_ns: int | None = None  # theoretical arrival time of the next sample
        self._last_offer_ns: int | None = None
        self._source_ns = 0.0  # running estimate of the source's sample interval

    @staticmethod
    def _period(options: ThrottleOptions) -> int:
        return round(1e9 / options.max_rate_hz) if options.max_rate_hz else 0

    def update(self, options: ThrottleOptions) -> None:
        """New options at run time; the every_nth phase and the schedule restart."""
        self.options = options
        self._period_ns = self._period(options)
        self._count = 0
        self._tat_ns = None

    def _tolerance_ns(self) -> int:
        return min(self._period_ns, int(self._source_ns * _TOLERANCE))

    def wants(self, now_ns: int) -> bool:
        """Would a sample produced at ``now_ns`` go to this subscriber?"""
        if self.options.paused or self._count % self.options.every_nth:
            return False
        tat = self._tat_ns
        return tat is None or now_ns >= tat - self._tolerance_ns()

    def next_due_ns(self, now_ns: int) -> int | None:
        """Earliest time a sample could be taken (None while paused).

        With ``every_nth``, samples must also be offered in between: the publisher still
        has to tick, even if it need not compute.
        """
        if self.options.paused:
            return None
        tat = self._tat_ns
        return now_ns if tat is None else max(now_ns, tat - self._tolerance_ns())

    def offer(self, now_ns: int) -> bool:
        """A sample was produced (or skipped) at ``now_ns``: does this subscriber take it?"""
        last = self._last_offer_ns
        if last is not None and now_ns > last:
            gap = now_ns - last
            self._source_ns = gap if not self._source_ns else (
                (1 - _EMA) * self._source_ns + _EMA * gap
            )
        self._last_offer_ns = now_ns
        take = self.wants(now_ns)
        self._count += 1
        if take and self._period_ns:
            tat = self._tat_ns
            self._tat_ns = (now_ns if tat is None else max(now_ns, tat)) + self._period_ns
        return take
