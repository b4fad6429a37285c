"""Local clocks: the seam through which the clock-sync component reads "its robot's" time.

A real robot reads its own system clock. Tests and simulations run several robots in one
process (or on one machine) and give each a :class:`SkewedClock`: the shared true time with
an offset and a rate error, so the exchange has real skew and drift to measure.
"""

from __future__ import annotations

from dataclasses import dataclass

from efficient_comm.handle import Clock

__all__ = ["Clock", "SkewedClock"]


@dataclass(frozen=True, slots=True)
class SkewedClock:
    """``base`` time shifted by ``offset_ns`` and running ``drift_ppm`` fast.

    ``local = base + offset_ns + drift_ppm * 1e-6 * (base - epoch_ns)``: at ``base ==
    epoch_ns`` the clock is exactly ``offset_ns`` ahead, and every second of base time it
    gains ``drift_ppm`` microseconds (loses, when negative).
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
