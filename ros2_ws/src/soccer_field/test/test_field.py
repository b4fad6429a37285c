"""The field module holds the KidSize column of the 2025 laws, and refuses a field that is none."""

from __future__ import annotations

import dataclasses

import pytest

from soccer_field import KIDSIZE, FieldDimensions, SoccerFieldError


def test_kidsize_is_table_1_of_the_2025_laws() -> None:
    assert dataclasses.asdict(KIDSIZE) == {
        "length": 9.0, "width": 6.0, "goal_width": 2.6, "goal_height": 1.2,
        "goal_area_length": 1.0, "goal_area_width": 3.0, "penalty_mark_distance": 1.5,
        "centre_circle_diameter": 1.5, "border_strip_width": 1.0,
        "penalty_area_length": 2.0, "penalty_area_width": 5.0, "line_width": 0.05,
    }
    assert (KIDSIZE.half_length, KIDSIZE.half_width) == (4.5, 3.0)
    assert KIDSIZE.opponent_goal == (4.5, 0.0)


def test_dimensions_that_make_no_field_are_refused() -> None:
    with pytest.raises(SoccerFieldError, match="make no field"):
        dataclasses.replace(KIDSIZE, goal_width=7.0)
    with pytest.raises(ValueError):
        FieldDimensions(**{**dataclasses.asdict(KIDSIZE), "length": -9.0})
