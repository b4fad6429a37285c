"""Errors of the recorder and player; one root, so callers can catch everything at once.

::

    RecorderError
    ├── RecorderConfigError   bad topic selection, option or path (nothing was started)
    ├── UnknownTypeError      a message type whose module or .msg definition is not installed
    ├── StorageError          writing failed (disk full, free-space guard, I/O error)
    └── PlaybackError         a bag that cannot be played (missing, unreadable, unknown type)

The bag format itself is rosbag2_layout's: its errors reach the recorder's callers wrapped
in these (``raise StorageError(...) from exc``, the bag's error kept as ``__cause__``), never
as subclasses of rosbag2_layout's, so ``except RecorderError`` means "the recorder failed"
and this tree does not change when rosbag2_layout's does (ARCHITECTURE.md, "Errors").
"""

from __future__ import annotations


class RecorderError(Exception):
    """Root of every error raised by robot_recorder."""


class RecorderConfigError(RecorderError, ValueError):
    """A topic selection, option or path the recorder refuses before starting anything."""


class UnknownTypeError(RecorderError, LookupError):
    """A message type that is not installed (no Python module or no .msg file)."""


class StorageError(RecorderError, OSError):
    """Writing the recording failed; the recording stopped and what was written is readable."""


class PlaybackError(RecorderError):
    """A bag that cannot be played."""
