"""Dynamic roles: who is striker, supporter, defender or goalie, from the shared data.

Every robot decides for the whole team from what its teammates told it (their time to the
ball, their positions and the role each claims), and takes its own role from that
decision: no robot commands another, so a lost message costs no role, only its freshness
(the dissertation's role assignment on explicit team communication, Fig. 6.10).

The rules, in order:

* alone (no fresh teammate): striker, whatever the configuration says (a robot that plays
  alone goes for the ball);
* ``goalie_number`` (when not 0): that player is the goalie;
* striker: the field player with the lowest time to the ball; the incumbent (the one that
  claims striker now) keeps it unless another is faster by more than ``margin_s``;
* of the others, the one nearest the own goal defends (again keeping an incumbent unless
  another is nearer by more than ``position_margin_m``), the rest support. One player
  left over supports.

Ties go to the lower player number, so every robot that has the same data decides alike.

Hysteresis is what keeps the decision still while two robots' times cross back and forth
(as they do when two robots walk towards the ball): without it, roles oscillate, the
dissertation's Fig. 5.11 ("conditions of the state transitions with insufficient
hysteresis lead to oscillating states"). Two knobs: a margin a challenger must beat, and
``min_hold_s``, the least time this robot keeps a role once it took it
(:class:`RoleKeeper`). Both 0 shows the oscillation.
"""

from __future__ import annotations

import enum
import math
from collections.abc import Sequence
from dataclasses import dataclass

from soccer_field import KIDSIZE


class Role(enum.Enum):
    """A player's role; the value is what the ``role`` topic carries (std_msgs/String).

    ``wire`` is the number the team message carries (``TeamMessage.ROLE_*``).
    """

    UNDEFINED = "undefined"
    STRIKER = "striker"
    SUPPORTER = "supporter"
    DEFENDER = "defender"
    GOALIE = "goalie"

    @property
    def wire(self) -> int:
        return _WIRE[self]

    @classmethod
    def from_wire(cls, value: int) -> Role:
        """The role a team message names; numbers this version does not know: UNDEFINED."""
        return _FROM_WIRE.get(int(value), Role.UNDEFINED)


# TeamMessage.ROLE_UNDEFINED .. ROLE_GOALIE (soccer_interfaces/msg/TeamMessage.msg)
_WIRE = {Role.UNDEFINED: 0, Role.STRIKER: 1, Role.SUPPORTER: 2, Role.DEFENDER: 3,
         Role.GOALIE: 4}
_FROM_WIRE = {v: k for k, v in _WIRE.items()}


@dataclass(frozen=True, slots=True)
class Player:
    """What the role decision needs of one player (this robot or a teammate)."""

    number: int
    x: float
    y: float
    #: Seconds to reach the ball and kick (inf: does not know where the ball is).
    time_to_ball_s: float
    #: The role the player holds now (its last message; this robot's own current role).
    role: Role = Role.UNDEFINED


@dataclass(frozen=True, slots=True)
class RoleRules:
    """The figures of the decision (see the module docstring); the hold time is the
    :class:`RoleKeeper`'s, since only this robot's own role is held."""

    goalie_number: int = 0
    margin_s: float = 1.0
    position_margin_m: float = 0.5
    #: Where the own goal is (the defender is the field player nearest to it).
    own_goal: tuple[float, float] = (-KIDSIZE.half_length, 0.0)


def _keep_or_take(players: Sequence[Player], role: Role, score: dict[int, float],
                  margin: float) -> Player:
    """The incumbent of ``role`` unless the best by ``score`` beats it by more than
    ``margin``; the best when nobody holds the role."""
    best = min(players, key=lambda p: (score[p.number], p.number))
    holders = [p for p in players if p.role == role]
    if not holders:
        return best
    incumbent = min(holders, key=lambda p: (score[p.number], p.number))
    if score[best.number] < score[incumbent.number] - margin:
        return best
    return incumbent


def assign_roles(players: Sequence[Player], rules: RoleRules) -> dict[int, Role]:
    """Every player's role, by number. ``players`` holds this robot and its fresh
    teammates, each once; an empty sequence gives an empty mapping."""
    if not players:
        return {}
    if len(players) == 1:
        return {players[0].number: Role.STRIKER}
    roles: dict[int, Role] = {}
    field = list(players)
    if rules.goalie_number:
        goalies = [p for p in field if p.number == rules.goalie_number]
        if goalies:
            roles[rules.goalie_number] = Role.GOALIE
            field = [p for p in field if p.number != rules.goalie_number]
    if not field:
        return roles
    times = {p.number: p.time_to_ball_s if not math.isnan(p.time_to_ball_s) else math.inf
             for p in field}
    striker = _keep_or_take(field, Role.STRIKER, times, rules.margin_s)
    roles[striker.number] = Role.STRIKER
    rest = [p for p in field if p.number != striker.number]
    if len(rest) == 1:
        roles[rest[0].number] = Role.SUPPORTER
    elif rest:
        gx, gy = rules.own_goal
        distance = {p.number: math.hypot(p.x - gx, p.y - gy) for p in rest}
        defender = _keep_or_take(rest, Role.DEFENDER, distance, rules.position_margin_m)
        for p in rest:
            roles[p.number] = Role.DEFENDER if p is defender else Role.SUPPORTER
    return roles


class RoleKeeper:
    """This robot's role over time: the decision, held for at least ``min_hold_s``.

    ``update`` is called at the decision rate with the current decision for this robot;
    the role changes only once the current one has been held ``min_hold_s`` (a decision
    that flips back within that time is never acted on). ``switches`` counts changes.
    """

    def __init__(self, *, min_hold_s: float, initial: Role = Role.UNDEFINED) -> None:
        self.min_hold_ns = round(min_hold_s * 1e9)
        self.role = initial
        self.since_ns: int | None = None
        self.switches = 0

    def update(self, wanted: Role, now_ns: int) -> Role:
        """The role to play now, given the decision ``wanted`` at ``now_ns``."""
        if wanted == self.role:
            return self.role
        first = self.role == Role.UNDEFINED  # taking the first role is not a switch
        if first or self.since_ns is None or now_ns - self.since_ns >= self.min_hold_ns:
            self.switches += 0 if first else 1
            self.role, self.since_ns = wanted, now_ns
        return self.role
