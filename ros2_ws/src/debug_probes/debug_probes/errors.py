"""Every error debug_probes raises, under one root (see ARCHITECTURE.md, "Errors").

    DebugProbesError
    ├── DrawingError           a drawing call with arguments that cannot be drawn
    └── ProbeConfigError       a probe's parameter out of range (JPEG quality, ...)
"""

from __future__ import annotations


class DebugProbesError(Exception):
    """Root of all debug_probes errors."""


class DrawingError(DebugProbesError, ValueError):
    """A drawing element with a bad argument (no layer name, a non-finite coordinate, ...)."""


class ProbeConfigError(DebugProbesError, ValueError):
    """A probe's parameter that is out of range."""
