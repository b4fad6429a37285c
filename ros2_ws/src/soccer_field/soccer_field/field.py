"""The field's dimensions: RoboCup Humanoid League KidSize, Laws of the Game 2025.

The values are the KidSize column of Table 1 in Law 1 ("The Field of Play") of the RoboCup
Soccer Humanoid League "Laws of the Game 2025" (April 14th, 2025), with the line width and
the goal's measures from the same law's text. Lengths are in metres, along the field (x,
from the own goal to the opponent goal) or across it (y); the centre mark is the origin, and
the opponent goal, the one the robot attacks, is at +x. A dimension is a distance between
line centres where the law measures lines.
"""

from __future__ import annotations

from dataclasses import dataclass

from .errors import FieldDimensionError

__all__ = ["KIDSIZE", "FieldDimensions"]


@dataclass(frozen=True, slots=True)
class FieldDimensions:
    """One field's dimensions (metres); letters are Table 1's."""

    length: float  # A, goal line to goal line
    width: float  # B, touch line to touch line
    goal_width: float  # D, between the posts
    goal_height: float  # the crossbar's lower edge above the ground
    goal_area_length: float  # E, into the field
    goal_area_width: float  # F
    penalty_mark_distance: float  # G, from the goal line
    centre_circle_diameter: float  # H
    border_strip_width: float  # I, at least
    penalty_area_length: float  # J, into the field
    penalty_area_width: float  # K
    line_width: float  # "approximately 5 cm", all lines alike

    def __post_init__(self) -> None:
        if not all(v > 0 for v in (self.length, self.width, self.line_width)) or not (
                self.goal_width < self.goal_area_width < self.penalty_area_width < self.width
                and self.goal_area_length < self.penalty_area_length < self.length / 2):
            raise FieldDimensionError(f"these dimensions make no field: {self}")

    @property
    def half_length(self) -> float:
        """The goal lines' x (the opponent's at +x, the own at -x)."""
        return self.length / 2

    @property
    def half_width(self) -> float:
        """The touch lines' y (left at +y)."""
        return self.width / 2

    @property
    def opponent_goal(self) -> tuple[float, float]:
        """The centre of the opponent goal's line, the point the robot attacks."""
        return (self.half_length, 0.0)


#: The KidSize field of the 2025 laws.
KIDSIZE = FieldDimensions(
    length=9.0, width=6.0, goal_width=2.6, goal_height=1.2, goal_area_length=1.0,
    goal_area_width=3.0, penalty_mark_distance=1.5, centre_circle_diameter=1.5,
    border_strip_width=1.0, penalty_area_length=2.0, penalty_area_width=5.0, line_width=0.05,
)
