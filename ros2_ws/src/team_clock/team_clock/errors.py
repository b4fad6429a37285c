"""Every error team_clock raises, under one root.

Catch :class:`TeamClockError` to handle anything this package raises::

    TeamClockError
    ├── NoEstimateError     a log (or a robot) holds no clock-offset estimate to align it with
    │   └── OtherRobotError a log holds estimates, but of other robots than the one asked for
    ├── LogFormatError      an input log is not MCAP in the ros2 profile, or is damaged
    └── MergeError          merging was asked for something impossible (name clash, bad output)
"""

from __future__ import annotations

from collections.abc import Sequence


class TeamClockError(Exception):
    """Root of all team_clock errors."""


class NoEstimateError(TeamClockError, LookupError):
    """There is no clock-offset estimate where one is needed.

    Raised rather than assuming the clocks agree: a log aligned with a made-up offset is
    worse than one that is refused, because nothing downstream could notice the error.
    """


class OtherRobotError(NoEstimateError):
    """A log holds clock estimates, but only of other robots than the one asked for.

    ``wanted`` is the robot asked for, ``found`` the robots whose estimates the log holds.
    """

    def __init__(self, message: str, *, wanted: str, found: Sequence[str]) -> None:
        super().__init__(message)
        self.wanted = wanted
        self.found = tuple(found)


class LogFormatError(TeamClockError, ValueError):
    """An input log cannot be read: not MCAP, not the ros2 profile, or damaged."""


class MergeError(TeamClockError, ValueError):
    """A merge request is inconsistent (two robots under one namespace, output exists)."""
