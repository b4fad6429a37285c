"""Quintic splines: smooth foot trajectories for the walk engine.

A foot that starts or stops with a jump in acceleration jerks the servos and shakes the
robot; a quintic polynomial per segment can match position, velocity and acceleration at
both ends, so a trajectory made of them is smooth to the second derivative wherever its
knots say so. The walk uses them for the swing foot's path forward and sideways (from rest
on the ground to rest on the ground) and for its lift (up to the apex and down again).
"""

from __future__ import annotations

import itertools
from bisect import bisect_right
from collections.abc import Sequence
from dataclasses import dataclass

from ..errors import SimConfigError


@dataclass(frozen=True, slots=True)
class Knot:
    """Where the spline passes at ``t``: position, velocity and acceleration."""

    t: float
    position: float
    velocity: float = 0.0
    acceleration: float = 0.0


def _coefficients(a: Knot, b: Knot) -> tuple[float, ...]:
    """The quintic on [a.t, b.t] matching both knots, in powers of (t - a.t)."""
    h = b.t - a.t
    p0, v0, a0 = a.position, a.velocity, a.acceleration
    p1, v1, a1 = b.position, b.velocity, b.acceleration
    c3 = (20 * (p1 - p0) - (8 * v1 + 12 * v0) * h - (3 * a0 - a1) * h * h) / (2 * h ** 3)
    c4 = (30 * (p0 - p1) + (14 * v1 + 16 * v0) * h + (3 * a0 - 2 * a1) * h * h) / (2 * h ** 4)
    c5 = (12 * (p1 - p0) - 6 * (v1 + v0) * h - (a0 - a1) * h * h) / (2 * h ** 5)
    return p0, v0, a0 / 2, c3, c4, c5


class QuinticSpline:
    """A piecewise quintic through ``knots`` (strictly increasing times); constant outside."""

    def __init__(self, knots: Sequence[Knot]) -> None:
        if len(knots) < 2 or any(b.t <= a.t for a, b in itertools.pairwise(knots)):
            raise SimConfigError("a spline needs two or more knots at increasing times")
        self.knots = tuple(knots)
        self._times = [k.t for k in knots]
        self._segments = [_coefficients(a, b) for a, b in itertools.pairwise(knots)]

    def __call__(self, t: float) -> float:
        if t <= self._times[0]:
            return self.knots[0].position
        if t >= self._times[-1]:
            return self.knots[-1].position
        i = bisect_right(self._times, t) - 1
        c0, c1, c2, c3, c4, c5 = self._segments[i]
        s = t - self._times[i]
        return c0 + s * (c1 + s * (c2 + s * (c3 + s * (c4 + s * c5))))


#: From 0 to 1 at rest at both ends (the swing foot's way forward and sideways).
SMOOTH_STEP = QuinticSpline([Knot(0.0, 0.0), Knot(1.0, 1.0)])
#: From 0 up to 1 at the middle and down again, at rest at all three (the swing foot's lift).
BUMP = QuinticSpline([Knot(0.0, 0.0), Knot(0.5, 1.0), Knot(1.0, 0.0)])
