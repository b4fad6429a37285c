"""Every error log_analysis raises, under one root::

    LogAnalysisError
    ├── LogSourceError        a log that cannot be read (missing, not a bag, damaged) (OSError)
    └── GeneratorError        an event generator that cannot be loaded or set up (ValueError)

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
