"""Offset and drift of one clock against another, from NTP four-timestamp samples.

Pure arithmetic, no ROS: the clock-sync component feeds it samples and asks for estimates.

A sample is one round trip: the client sends at local time ``t1``, the server receives at
``t2`` and answers at ``t3`` (both in reference time), the client receives at local ``t4``.
Then ``offset = ((t2 - t1) + (t3 - t4)) / 2`` and ``delay = (t4 - t1) - (t3 - t2)``. Whatever
the split of the delay between the two directions, the true offset lies within ``delay / 2``
of the sample's offset (plus the server's own uncertainty when it is not the reference): this
bound is what makes the reported uncertainty honest.

The estimator keeps a window of samples, uses the ones with the shortest round trips (queueing
only ever adds delay, so short round trips are the accurate ones), and fits
``offset(local) = a + b * local`` by weighted least squares. The fitted value at a time ``x``
is a linear combination ``sum(c_i * offset_i)`` of the samples, so its error is at most
``sum(|c_i| * bound_i)``; samples that contradict the fit by more than their bound (a model
violation: drift that is not constant, a clock step) widen the uncertainty by the excess or,
when clearly outliers, are dropped.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import KW_ONLY, dataclass

import numpy as np

__all__ = ["Estimate", "OffsetEstimator", "Sample"]


@dataclass(frozen=True, slots=True)
class Sample:
    """One round trip: client times ``t1``, ``t4`` (local), server times ``t2``, ``t3``."""

    t1: int
    t2: int
    t3: int
    t4: int
    _: KW_ONLY
    #: The server's own uncertainty about reference time (0 for the reference itself).
    server_uncertainty_ns: int = 0

    @property
    def delay_ns(self) -> int:
        """Round-trip time spent on the wire (the server's processing time excluded)."""
        return (self.t4 - self.t1) - (self.t3 - self.t2)

    @property
    def offset_ns(self) -> float:
        """Reference minus local time, assuming equal delays both ways."""
        return ((self.t2 - self.t1) + (self.t3 - self.t4)) / 2

    @property
    def local_ns(self) -> int:
        """The local time the offset belongs to: the middle of the round trip."""
        return (self.t1 + self.t4) // 2

    @property
    def bound_ns(self) -> float:
        """How far the sample's offset can be from the truth at :attr:`local_ns`."""
        return max(self.delay_ns, 0) / 2 + self.server_uncertainty_ns


@dataclass(frozen=True, slots=True)
class Estimate:
    """``reference = local + offset_ns + drift_ppm * 1e-6 * (local - stamp_ns)``."""

    _: KW_ONLY
    stamp_ns: int
    offset_ns: int
    drift_ppm: float
    #: Bound on the error of ``offset_ns`` at ``stamp_ns``.
    uncertainty_ns: int
    samples: int
    #: How fast the uncertainty grows away from ``stamp_ns`` (unmodelled drift changes).
    holdover_ppm: float = 0.0

    def to_reference(self, local_ns: int) -> int:
        return local_ns + self.offset_ns + round(self.drift_ppm * 1e-6 * (local_ns - self.stamp_ns))

    def uncertainty_at(self, local_ns: int) -> int:
        growth = self.holdover_ppm * 1e-6 * abs(local_ns - self.stamp_ns)
        return self.uncertainty_ns + math.ceil(growth)


class OffsetEstimator:
    """Windowed, delay-filtered, weighted linear fit of offset against local time.

    ``window_ns`` and ``max_samples`` bound the memory; ``keep_fraction`` of the window's
    samples with the shortest round trips enter the fit (at least four of them, if
    there are that many). ``max_drift_ppm`` is the worst rate error assumed for a clock:
    it bounds the drift prior of the fit, and with a single sample the uncertainty grows at
    that rate. ``holdover_ppm`` is the rate error assumed for the fitted drift itself when
    the estimate is used away from the samples.
    """

    def __init__(
        self,
        *,
        window_ns: int = 60_000_000_000,
        max_samples: int = 128,
        keep_fraction: float = 0.5,
        max_drift_ppm: float = 200.0,
        holdover_ppm: float = 0.5,
    ) -> None:
        if not 0.0 < keep_fraction <= 1.0:
            raise ValueError(f"keep_fraction must be in (0, 1], got {keep_fraction}")
        self.window_ns = window_ns
        self.keep_fraction = keep_fraction
        self.min_fit = 4
        self.max_drift_ppm = max_drift_ppm
        self.holdover_ppm = holdover_ppm
        self._samples: deque[Sample] = deque(maxlen=max_samples)
        #: Samples refused by :meth:`add` (negative round trip, time running backwards).
        self.rejected = 0
        #: Times the window held samples no straight line explains (see :meth:`_consistent`).
        self.inconsistent = 0

    def __len__(self) -> int:
        return len(self._samples)

    @property
    def newest(self) -> Sample | None:
        """The newest sample kept, or None before the first one (staleness, diagnostics)."""
        return self._samples[-1] if self._samples else None

    def clear(self) -> None:
        self._samples.clear()

    def add(self, sample: Sample) -> bool:
        """Keep ``sample`` if it is physically possible; False (and counted) otherwise."""
        tolerance = 1_000 + sample.server_uncertainty_ns  # rounding of relayed timestamps
        if sample.t4 < sample.t1 or sample.t3 < sample.t2 or sample.delay_ns < -tolerance:
            self.rejected += 1
            return False
        self._samples.append(sample)
        return True

    def estimate(self, at_ns: int) -> Estimate | None:
        """The offset at local time ``at_ns`` with its error bound; None without samples."""
        horizon = at_ns - self.window_ns
        while self._samples and self._samples[0].local_ns < horizon:
            self._samples.popleft()
        if not self._samples:
            return None
        window = self._consistent(list(self._samples), at_ns)
        # shortest round trips first; of equal ones, the newest
        by_delay = sorted(window, key=lambda s: (s.delay_ns, -s.local_ns))
        keep = max(min(self.min_fit, len(by_delay)), math.ceil(len(by_delay) * self.keep_fraction))
        used = by_delay[:keep]
        if len(used) < 2:
            return self._constant(used, at_ns)
        return self._fit(used, window, at_ns)

    def _consistent(self, window: list[Sample], at_ns: int) -> list[Sample]:
        """The samples one straight line can explain, preferring the newest.

        When no line fits the whole window, the clock stepped, its drift changed, or a
        sample is wrong. If at least ``min_fit`` of the newest samples agree with each other,
        that is the new state of the clock: older samples are forgotten. If fewer do, they
        are held back until enough confirm them, so a single bad answer cannot move the
        estimate.
        """
        if len(window) < 2 or _feasible_range(window, at_ns, self.max_drift_ppm) is not None:
            return window
        good, bad = 1, len(window)  # a suffix of `good` samples fits, one of `bad` does not
        while bad - good > 1:
            mid = (good + bad) // 2
            if _feasible_range(window[-mid:], at_ns, self.max_drift_ppm) is None:
                bad = mid
            else:
                good = mid
        self.inconsistent += 1
        if good >= self.min_fit:
            for _ in range(len(window) - good):
                self._samples.popleft()
            return window[-good:]
        older = window[:-good]
        if _feasible_range(older, at_ns, self.max_drift_ppm) is not None:
            return older
        return window

    def _constant(self, used: list[Sample], at_ns: int) -> Estimate:
        """No drift measurable yet: the tightest sample, widened by the worst drift."""
        best = min(used, key=lambda s: s.bound_ns)
        spread = abs(at_ns - best.local_ns) * self.max_drift_ppm * 1e-6
        return Estimate(
            stamp_ns=at_ns,
            offset_ns=round(best.offset_ns),
            drift_ppm=0.0,
            uncertainty_ns=math.ceil(best.bound_ns + spread),
            samples=len(used),
            holdover_ppm=self.max_drift_ppm,
        )

    def _fit(self, used: list[Sample], window: list[Sample], at_ns: int) -> Estimate:
        samples = list(used)
        # Drop clear outliers (a sample further from the fit than its own bound plus the
        # typical bound), at most a quarter of them, one at a time.
        for _ in range(len(samples) // 4):
            fit = _weighted_fit(samples, at_ns, self.max_drift_ppm)
            typical = sorted(s.bound_ns for s in samples)[len(samples) // 2]
            excess = [abs(r) - s.bound_ns for s, r in zip(samples, fit.residuals, strict=True)]
            worst = max(range(len(samples)), key=excess.__getitem__)
            if excess[worst] <= typical:
                break
            del samples[worst]
        fit = _weighted_fit(samples, at_ns, self.max_drift_ppm)
        model_error = max(
            0.0,
            max(abs(r) - s.bound_ns for s, r in zip(samples, fit.residuals, strict=True)),
        )
        value, bound = fit.value, fit.bound + model_error
        # Tighter, when the samples agree with a straight line: the exact range of lines
        # that every sample of the window allows (dropped outliers excepted, if need be).
        dropped = set(map(id, used)) - set(map(id, samples))
        feasible = (_feasible_range(window, at_ns, self.max_drift_ppm)
                    or _feasible_range([s for s in window if id(s) not in dropped], at_ns,
                                       self.max_drift_ppm))
        if feasible is not None:
            low, high = feasible
            value = min(max(value, low), high)  # the fit may stray outside what is possible
            bound = min(bound, max(high - value, value - low))
        newest = max(s.local_ns for s in samples)
        holdover = self.holdover_ppm * 1e-6 * max(0, at_ns - newest)
        return Estimate(
            stamp_ns=at_ns,
            offset_ns=round(value),
            drift_ppm=fit.slope * 1e6,
            uncertainty_ns=math.ceil(bound + holdover),
            samples=len(samples),
            holdover_ppm=self.holdover_ppm,
        )


@dataclass(frozen=True, slots=True)
class _Fit:
    value: float  # fitted offset at the query time
    slope: float  # d offset / d local time
    bound: float  # sum(|c_i| * bound_i): worst-case error of `value`
    residuals: list[float]


def _weighted_fit(samples: list[Sample], at_ns: int, max_drift_ppm: float) -> _Fit:
    """Weighted least-squares line evaluated at ``at_ns``, with its worst-case error.

    Weights favour samples whose round trip is close to the window's shortest: their delay
    is nearly all fixed latency, split almost evenly, so their offsets are the accurate ones
    (the error *bound* still uses each sample's full ``delay / 2``). A weak prior pulls the
    slope towards zero (drift of a few ppm is the rule, ``max_drift_ppm`` the limit), so a
    few samples over a short span cannot produce an absurd drift; the bias this can cause is
    bounded by ``max_drift_ppm`` and added to the error bound.
    """
    min_delay = min(max(s.delay_ns, 0) for s in samples)
    # Typical asymmetry of the kept samples: half the median delay above the shortest.
    excess = sorted(max(s.delay_ns, 0) - min_delay for s in samples)
    floor = max(20_000.0, excess[len(excess) // 2] / 2)
    weights = [1.0 / ((max(s.delay_ns, 0) - min_delay) / 2 + s.server_uncertainty_ns / 4 + floor)
               ** 2 for s in samples]
    prior = 1.0 / (max_drift_ppm * 1e-6 / 2) ** 2  # slope prior: sigma = max_drift / 2
    xs = [float(s.local_ns - at_ns) for s in samples]  # relative: keeps float precision
    ys = [s.offset_ns for s in samples]
    total = sum(weights)
    x_mean = sum(w * x for w, x in zip(weights, xs, strict=True)) / total
    y_mean = sum(w * y for w, y in zip(weights, ys, strict=True)) / total
    sxx = sum(w * (x - x_mean) ** 2 for w, x in zip(weights, xs, strict=True)) + prior
    slope = sum(w * (x - x_mean) * (y - y_mean)
                for w, x, y in zip(weights, xs, ys, strict=True)) / sxx
    # value at x = 0 (the query time) = sum(c_i * y_i) + bias from the slope prior
    coefficients = [w / total + w * (x - x_mean) * (0.0 - x_mean) / sxx
                    for w, x in zip(weights, xs, strict=True)]
    value = y_mean + slope * (0.0 - x_mean)
    bias = max_drift_ppm * 1e-6 * abs(x_mean) * prior / sxx
    bound = sum(abs(c) * s.bound_ns for c, s in zip(coefficients, samples, strict=True)) + bias
    residuals = [y - (y_mean + slope * (x - x_mean)) for x, y in zip(xs, ys, strict=True)]
    return _Fit(value=value, slope=slope, bound=bound, residuals=residuals)


_SLOPES = 801  # grid of drifts across +-max_drift: 0.5 ppm steps at 200 ppm


def _feasible_range(samples: list[Sample], at_ns: int,
                    max_drift_ppm: float) -> tuple[float, float] | None:
    """Lowest and highest offset at ``at_ns`` of any line within every sample's bound.

    Each sample confines the true line to ``offset_i +- bound_i`` at its time, and the drift
    to ``+-max_drift_ppm``; the true offset at ``at_ns`` lies between these two values. For a
    drift ``b`` the allowed offsets at ``at_ns`` are ``[max(lo_i - b*x_i), min(hi_i - b*x_i)]``.
    The drifts are scanned on a grid. A true drift between two grid points is within half a
    step of one of them, which moves the line by at most ``step/2 * |x_i|`` at sample ``i``:
    widening each sample's interval by that much makes the nearest grid drift admit the
    true line. Without the widening a link so good that the allowed drifts span less than a
    step (a few microseconds of round trip over a minute) would fall between grid points and
    look like a clock step. None when no line fits every sample (a clock step, a drift that
    changed, a wrong server).
    """
    if len(samples) < 2:
        return None
    xs = np.array([float(s.local_ns - at_ns) for s in samples])
    centre = np.array([s.offset_ns for s in samples])
    limit = max_drift_ppm * 1e-6
    slopes = np.linspace(-limit, limit, _SLOPES)
    bounds = np.array([s.bound_ns for s in samples]) + np.abs(xs) * (slopes[1] - slopes[0]) / 2
    shift = np.outer(xs, slopes)  # b * x_i for every sample and drift
    low = np.max((centre - bounds)[:, None] - shift, axis=0)
    high = np.min((centre + bounds)[:, None] - shift, axis=0)
    ok = low <= high
    if not ok.any():
        return None
    return float(low[ok].min()), float(high[ok].max())
