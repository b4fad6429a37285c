"""Every error throttle_publisher raises, under one root (itself an efficient_comm error).

    ThrottleError
    └── InvalidOptionsError      options a subscriber may not ask for (bad rate, n = 0, ...)
"""

from __future__ import annotations

from efficient_comm import EfficientCommError


class ThrottleError(EfficientCommError):
    """Root of all throttle_publisher errors."""


class InvalidOptionsError(ThrottleError, ValueError):
    """Throttle options that are out of range, of the wrong kind or unknown."""
