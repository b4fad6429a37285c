"""How far a simulator steps at each tick of its timer: one period in lockstep, up to the wall
clock otherwise; and how fast it ran (the real-time factor).

Shared by the one-robot :class:`~.simulator.Simulator` and the team's
:class:`~.world_simulator.WorldSimulator`, which pace their worlds alike.
"""

from __future__ import annotations

import time
from collections.abc import Callable

#: How many periods a late tick may step at once to catch up with the wall clock.
MAX_CATCH_UP = 4


class Pacer:
    """Paces a world that ticks every ``period_s``; ``monotonic`` is the wall clock."""

    def __init__(self, *, period_s: float, monotonic: Callable[[], float] = time.monotonic
                 ) -> None:
        self.period_s = period_s
        self._monotonic = monotonic
        #: Simulated time given up because the machine fell behind (real time only).
        self.skipped_s = 0.0
        self._wall_start: float | None = None  # wall time that sim time 0 stands for
        self._wall_first: float | None = None  # wall time of the first tick

    def step_s(self, sim_time_s: float, *, lockstep: bool) -> float:
        """How far to step at this tick, the world being at ``sim_time_s``.

        In lockstep one period. On the wall clock, up to the wall clock: a machine that
        falls further behind than :data:`MAX_CATCH_UP` periods gives the rest up (counted
        in :attr:`skipped_s`), so the world slows down for a moment instead of racing
        through the backlog afterwards.
        """
        if lockstep or self._wall_start is None:
            if self._wall_start is None:
                self._wall_first = self._wall_start = self._monotonic() - self.period_s
            return self.period_s
        limit = MAX_CATCH_UP * self.period_s
        behind = self._monotonic() - self._wall_start - sim_time_s
        if behind > limit:
            self._wall_start += behind - limit
            self.skipped_s += behind - limit
        return min(max(behind, self.period_s / 2), limit)

    def real_time_factor(self, sim_time_s: float) -> float:
        """Simulated seconds per wall-clock second since the first tick."""
        if self._wall_first is None:
            return 0.0
        wall = self._monotonic() - self._wall_first
        return sim_time_s / wall if wall > 0 else 0.0
