"""The exceptions of humanoid_sim: catch :class:`HumanoidSimError` for all of them."""

from __future__ import annotations


class HumanoidSimError(Exception):
    """Root of every error this package raises on purpose."""


class RenderError(HumanoidSimError):
    """No offscreen OpenGL (neither EGL nor OSMesa), or a camera the model cannot render."""


class SimConfigError(HumanoidSimError, ValueError):
    """A parameter the simulator or a soccer component cannot work with."""
