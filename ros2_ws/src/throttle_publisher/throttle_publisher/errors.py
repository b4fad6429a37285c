"""Every error throttle_publisher raises, under one root (see ARCHITECTURE.md, "Errors").

    ThrottleError
    └── InvalidOptionsError      options a subscriber may not ask for (bad rate, n = 0, ...)
"""

from __future__ import annotations


class ThrottleError(Exception):
    """Root of all throttle_publisher errors."""


class InvalidOptionsError(ThrottleError, ValueError):
    """Throttle options that are out of range, of the wrong kind or unknown."""
