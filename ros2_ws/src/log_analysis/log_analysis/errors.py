"""Every error log_analysis raises, under one root::

    LogAnalysisError
    ├── LogSourceError        a log or video that cannot be read (missing, not a bag or
    │                         video, damaged) (OSError)
    ├── GeneratorError        an event generator that cannot be loaded or set up (ValueError)
    ├── SyncError             nothing to fit a video's clock on (ValueError)
    └── CompareError          an A/B comparison that cannot run: a variant that does not
                              load or start, no images of the robot (ValueError)

A generator that raises while it runs is not an error of the analysis: :func:`detect`
reports it and goes on with the others (``Detection.failures``).
"""

from __future__ import annotations


class LogAnalysisError(Exception):
    """Root of every error raised by log_analysis."""


class LogSourceError(LogAnalysisError, OSError):
    """A log that cannot be read: no bag there, not MCAP, damaged beyond its first records."""


class GeneratorError(LogAnalysisError, ValueError):
    """An event generator that cannot be loaded (a file that does not import, no
    ``GENERATORS`` in it, an entry point that fails) or is not a generator."""


class SyncError(LogAnalysisError, ValueError):
    """Nothing to fit a video's clock on: no ball track, no frame showing the ball, a ball
    that never moved, no anchors."""


class CompareError(LogAnalysisError, ValueError):
    """An A/B comparison that cannot run: a variant whose component does not load or start,
    two variants with one label, a log without the robot's images."""
