"""Every error team_clock raises, under one root.

Catch :class:`TeamClockError` to handle anything this package raises::

    TeamClockError
    ├── NoEstimateError     a log (or a robot) holds no clock-offset estimate to align it with
    ├── LogFormatError      an input log is not MCAP in the ros2 profile, or is damaged
    └── MergeError          merging was asked for something impossible (name clash, bad output)
"""

from __future__ import annotations


class TeamClockError(Exception):
    """Root of all team_clock errors."""


class NoEstimateError(TeamClockError, LookupError):
    """There is no clock-offset estimate where one is needed.

    Raised rather than assuming the clocks agree: a log aligned with a made-up offset is
    worse than one that is refused, because nothing downstream could notice the error.
    """


class LogFormatError(TeamClockError, ValueError):
    """An input log cannot be read: not MCAP, not the ros2 profile, or damaged."""


class MergeError(TeamClockError, ValueError):
    """A merge request is inconsistent (two robots under one namespace, output exists)."""
