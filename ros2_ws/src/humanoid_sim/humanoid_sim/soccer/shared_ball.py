"""The shared ball: this robot's ball observation fused with its teammates'.

Each robot keeps its own model and takes in what its teammates report (the decentral
approach of the dissertation's sec. 2.1.4: no central data pool that every robot must
reach, so a lost link degrades to the robot's own model). The transform of a teammate's
ball into this robot's frame is trivial: every pose and ball in a team message is on the
field, in the team's frame (own goal at -x).

A ball belief is only as good as the pose it was seen from: a teammate that is 0.5 m off in
its localization puts the ball 0.5 m off too, however well it sees it. So a belief's
standard deviation combines the observation's and the observer's pose's (independent
errors, so in quadrature), and grows with the belief's age (the ball may have rolled since):
``sigma² = ball_sigma² + pose_sigma² + (growth · age)²``.

Fusion weights beliefs by the inverse of that variance. Beliefs that contradict the most
certain one (further from it than ``gate`` standard deviations of their difference) are
left out rather than averaged in: the mean of a right and a wrong ball lies where no ball
is, and a teammate that is lost on the field is the common cause of such a contradiction.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass

#: Who made a belief: this robot itself (teammates are their player numbers).
OWN = 0


@dataclass(frozen=True, slots=True)
class BallBelief:
    """A ball on the field (m), how sure (one standard deviation, m, the observer's pose
    included) and how old (s: since the ball was last seen); ``source`` is the player
    number of the robot that saw it (:data:`OWN` for this robot)."""

    x: float
    y: float
    sigma: float
    age_s: float
    source: int = OWN


def observed(x: float, y: float, *, ball_sigma: float, pose_sigma: float, age_s: float,
             source: int = OWN) -> BallBelief:
    """A belief from an observation ``ball_sigma`` good, made from a pose ``pose_sigma``
    good: the two errors add in quadrature."""
    return BallBelief(x, y, math.hypot(ball_sigma, pose_sigma), age_s, source)


@dataclass(frozen=True, slots=True)
class FusedBall:
    """The fused ball: position (m), standard deviation (m), the age of the freshest belief
    that went into it (s), and the sources used (player numbers, :data:`OWN` for this
    robot)."""

    x: float
    y: float
    sigma: float
    age_s: float
    sources: tuple[int, ...]


def effective_sigma(belief: BallBelief, *, growth_m_per_s: float) -> float:
    """The belief's standard deviation now: its own, grown by its age."""
    return math.hypot(belief.sigma, growth_m_per_s * max(0.0, belief.age_s))


def fuse(beliefs: Iterable[BallBelief], *, max_age_s: float, growth_m_per_s: float,
         gate: float = 3.0, min_sigma: float = 1e-3) -> FusedBall | None:
    """Inverse-variance fusion of the beliefs not older than ``max_age_s`` that agree with
    the most certain one (within ``gate`` standard deviations of the difference); None if
    no belief is fresh enough. Beliefs with a non-finite number are ignored."""
    usable = [b for b in beliefs
              if all(math.isfinite(v) for v in (b.x, b.y, b.sigma, b.age_s))
              and 0.0 <= b.age_s <= max_age_s]
    if not usable:
        return None
    sigmas = {id(b): max(min_sigma, effective_sigma(b, growth_m_per_s=growth_m_per_s))
              for b in usable}
    best = min(usable, key=lambda b: (sigmas[id(b)], b.age_s, b.source))
    agreeing = [b for b in usable
                if math.hypot(b.x - best.x, b.y - best.y)
                <= gate * math.hypot(sigmas[id(b)], sigmas[id(best)])]
    weights = [1.0 / sigmas[id(b)] ** 2 for b in agreeing]
    total = sum(weights)
    return FusedBall(
        x=sum(w * b.x for w, b in zip(weights, agreeing, strict=True)) / total,
        y=sum(w * b.y for w, b in zip(weights, agreeing, strict=True)) / total,
        sigma=1.0 / math.sqrt(total),
        age_s=min(b.age_s for b in agreeing),
        sources=tuple(sorted({b.source for b in agreeing})),
    )
