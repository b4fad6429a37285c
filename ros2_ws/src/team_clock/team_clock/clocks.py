"""Local clocks: the seam through which the clock-sync component reads "its robot's" time.

A real robot reads its own system clock. Tests and simulations run several robots in one
process (or on one machine) and give each a :class:`SkewedClock`: the shared true time with
an offset and a rate error, so the exchange has real skew and drift to measure. The class is
efficient_comm's (a container's ``clock_offset_s`` runs on one too): one owner, re-exported.
"""

from __future__ import annotations

from efficient_comm import SkewedClock
from efficient_comm.handle import Clock

__all__ = ["Clock", "SkewedClock"]
