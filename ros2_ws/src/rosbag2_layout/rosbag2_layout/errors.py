"""Every error rosbag2_layout raises, under one root.

Catch :class:`Rosbag2Error` to handle anything this package raises::

    Rosbag2Error
    ├── BagFormatError    an input is not MCAP in the ros2 profile, is damaged, or its
    │                     metadata.yaml is not rosbag2 metadata (ValueError)
    ├── BagNotFoundError  no bag, or a file its metadata.yaml lists, where one was named
    │                     (FileNotFoundError)
    ├── BagConfigError    a writer option, target or topic the writer refuses before
    │                     writing anything (ValueError)
    ├── BagWriteError     writing failed (disk full, free-space guard, I/O error); what was
    │                     written before stays readable (OSError)
    ├── UnknownTypeError  a message type whose module or .msg definition is not installed
    │                     (LookupError)
    └── UnsupportedFieldError  a field type whose exact CDR length cdr.py cannot compute
                          (wstring, ...; it falls back to serializing) (TypeError)

Each also derives from the builtin named, so callers that only know Python's exceptions
still catch them.
"""

from __future__ import annotations

__all__ = ["BagConfigError", "BagFormatError", "BagNotFoundError", "BagWriteError",
           "Rosbag2Error", "UnknownTypeError", "UnsupportedFieldError"]


class Rosbag2Error(Exception):
    """Root of every error raised by rosbag2_layout."""


class BagFormatError(Rosbag2Error, ValueError):
    """A bag or file that cannot be read: not MCAP, not the ros2 profile, or damaged."""


class BagNotFoundError(Rosbag2Error, FileNotFoundError):
    """No bag at the path given, or a file listed in its metadata.yaml is missing."""


class BagConfigError(Rosbag2Error, ValueError):
    """A writer option, target path or topic the writer refuses (nothing was written)."""


class BagWriteError(Rosbag2Error, OSError):
    """Writing failed; the bag is closed and what it holds so far is readable."""


class UnknownTypeError(Rosbag2Error, LookupError):
    """A message type that is not installed (no Python module or no .msg file)."""


class UnsupportedFieldError(Rosbag2Error, TypeError):
    """A field type whose exact CDR length :mod:`rosbag2_layout.cdr` cannot compute."""
