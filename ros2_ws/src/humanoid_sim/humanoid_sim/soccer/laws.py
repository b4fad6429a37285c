"""The laws of the game that both the referee applies and the robots obey, as plain functions.

One module, so that the referee (simulation side, judging from ground truth) and the
robot's game control (robot side, deciding where to stand) cannot disagree on a spot or on
what is legal. Sources: the RoboCup Humanoid Soccer League's laws (HSL-Rules,
``rules/game.tex``: robot states, Law 8 kick-off, Law 9 ball out, Law 10 goal, Law 13 free
kicks, kick-in, goal kick, corner kick) and the field of :mod:`soccer_field` (KidSize).

Frames: field coordinates (the centre mark is the origin; blue attacks +x in the first
half, red -x; the teams change ends for the second half). Robots are named
``<team><number>`` (``blue1``, ``red3``), teams ``blue`` and ``red``, numbers 1 to
:data:`MAX_PLAYERS`.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from enum import Enum

from soccer_field import KIDSIZE

from ..errors import SimConfigError
from .world_model import BALL_RADIUS_M

TEAMS = ("blue", "red")
#: Players a team may have (the contract of issue 19: numbers 1..3).
MAX_PLAYERS = 3
_NAME = re.compile(r"^(blue|red)([1-9][0-9]*)$")

L, W = KIDSIZE.half_length, KIDSIZE.half_width
CENTRE_CIRCLE_RADIUS = KIDSIZE.centre_circle_diameter / 2

#: Where each player stands at a kick-off, in its team's attacking frame (own goal at -x;
#: x, y in m): ``(kicking team, other team)``. Player 1 takes the kick-off just behind the
#: ball, inside the centre circle (the kicking team may be there), or waits just outside the
#: circle; player 2 stands back on the left as a supporter; player 3 guards the own goal
#: from its goal area. All face the opponent goal.
KICKOFF_SPOTS: dict[int, tuple[tuple[float, float], tuple[float, float]]] = {
    1: ((-0.3, 0.0), (-(CENTRE_CIRCLE_RADIUS + 0.3), 0.0)),
    2: ((-1.5, 1.0), (-1.5, 1.0)),
    3: ((-(L - 0.5), 0.0), (-(L - 0.5), 0.0)),
}


@dataclass(frozen=True, slots=True)
class Player:
    """One robot of a team: its team colour and its player number."""

    team: str
    number: int

    @property
    def name(self) -> str:
        return f"{self.team}{self.number}"


def parse_robot(name: str) -> Player:
    """``blue2`` -> Player("blue", 2); anything else is refused with the rule it broke."""
    match = _NAME.match(name)
    if match is None or not 1 <= int(match[2]) <= MAX_PLAYERS:
        raise SimConfigError(f"a robot's name is <team><number> with team blue or red and "
                             f"number 1..{MAX_PLAYERS} (blue1, red3), got {name!r}")
    return Player(match[1], int(match[2]))


def other(team: str) -> str:
    return TEAMS[1 - TEAMS.index(team)]


def attack_sign(team: str, *, first_half: bool) -> float:
    """+1 if ``team`` attacks the goal at +x (blue in the first half), else -1."""
    return 1.0 if (team == "blue") == first_half else -1.0


# -- the ball in and out of play (Laws 9 and 10) ------------------------------------------

class Line(Enum):
    """Which line the whole ball crossed."""

    GOAL = "goal"  # the goal line between the posts and under the crossbar: a goal
    GOAL_LINE = "goal line"  # the goal line beside the goal
    TOUCH_LINE = "touch line"


@dataclass(frozen=True, slots=True)
class Crossing:
    """The ball out of play: the line it crossed, and on which side of the field (x_side:
    the goal line at +x or -x; y_side: the touch line at +y or -y, or the half of the goal
    line it crossed)."""

    line: Line
    x_side: float
    y_side: float


def judge_ball(x: float, y: float, z: float) -> Crossing | None:
    """The ball's centre at ``x, y, z``: out of play (and how), or None while in play.

    Out means wholly over a line: the centre more than the ball's radius past it. A goal
    also needs the ball between the posts and under the crossbar (Law 10).
    """
    over_goal_line = abs(x) > L + BALL_RADIUS_M
    over_touch_line = abs(y) > W + BALL_RADIUS_M
    if not over_goal_line and not over_touch_line:
        return None
    x_side, y_side = math.copysign(1.0, x), math.copysign(1.0, y)
    if over_goal_line and abs(y) < KIDSIZE.goal_width / 2 and z < KIDSIZE.goal_height:
        return Crossing(Line.GOAL, x_side, y_side)
    if over_touch_line and abs(x) <= L + BALL_RADIUS_M:
        return Crossing(Line.TOUCH_LINE, x_side, y_side)
    return Crossing(Line.GOAL_LINE, x_side, y_side)


def throw_in_spot(x: float, y_side: float) -> tuple[float, float]:
    """Kick-in (throw-in): on the touch line where the ball left the field."""
    return (max(-L, min(L, x)), y_side * W)


def goal_kick_spot(x_side: float, y_side: float) -> tuple[float, float]:
    """Goal kick: the goal area's corner on the side the ball went out (where the goal
    area's line meets its side line, not the T-junction on the goal line)."""
    return (x_side * (L - KIDSIZE.goal_area_length), y_side * KIDSIZE.goal_area_width / 2)


def corner_spot(x_side: float, y_side: float) -> tuple[float, float]:
    """Corner kick: the field's corner on the side the ball went out."""
    return (x_side * L, y_side * W)


# -- kick-off (Law 8) ---------------------------------------------------------------------

def in_centre_circle(x: float, y: float) -> bool:
    return math.hypot(x, y) < CENTRE_CIRCLE_RADIUS


def kickoff_pose(player: Player, *, first_half: bool,
                 kicking: bool) -> tuple[float, float, float]:
    """Where ``player`` stands for a kick-off, on the field: x, y (m) and heading (rad),
    facing the goal it attacks (:data:`KICKOFF_SPOTS` turned into its half)."""
    x, y = KICKOFF_SPOTS[player.number][0 if kicking else 1]
    sign = attack_sign(player.team, first_half=first_half)
    return (sign * x, sign * y, 0.0 if sign > 0 else math.pi)


def legal_at_kickoff(team: str, x: float, y: float, *, first_half: bool,
                     kicking: bool) -> bool:
    """Law 8 at a kick-off: inside the field, in the own half, and out of the centre
    circle unless the team takes the kick-off (``x, y``: the robot's torso on the ground)."""
    inside = abs(x) <= L and abs(y) <= W
    own_half = attack_sign(team, first_half=first_half) * x <= 0.0
    return inside and own_half and (kicking or not in_centre_circle(x, y))
