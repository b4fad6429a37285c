"""Every error soccer_field raises, under one root::

    SoccerFieldError
    └── FieldDimensionError   dimensions that cannot make a field (ValueError)
"""

from __future__ import annotations


class SoccerFieldError(Exception):
    """Root of every error raised by soccer_field."""


class FieldDimensionError(SoccerFieldError, ValueError):
    """Dimensions that cannot make a field (a goal wider than the field, a negative length)."""
