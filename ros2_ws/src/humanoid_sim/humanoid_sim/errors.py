"""The exceptions of humanoid_sim: catch :class:`HumanoidSimError` for all of them.

::

    HumanoidSimError
    ├── ProcessError      a process of the robot did not start (the split robot's perception)
    ├── RenderError       no offscreen OpenGL, or a camera the model cannot render
    ├── SimConfigError    a parameter a component cannot work with (also a ValueError)
    ├── TeamMessageError  a team message no robot could have sent (also a ValueError)
    └── VideoError        the match video cannot be written or its sidecar read (also an OSError)
"""

from __future__ import annotations


class HumanoidSimError(Exception):
    """Root of every error this package raises on purpose."""


class ProcessError(HumanoidSimError, OSError):
    """A process of the robot did not start or is gone (the split robot's perception)."""


class RenderError(HumanoidSimError):
    """No offscreen OpenGL (neither EGL nor OSMesa), or a camera the model cannot render."""


class SimConfigError(HumanoidSimError, ValueError):
    """A parameter the simulator, the driver or a soccer component cannot work with."""


class TeamMessageError(HumanoidSimError, ValueError):
    """A team message no robot could have sent (non-finite pose, negative sigma, ...)."""


class VideoError(HumanoidSimError, OSError):
    """The match video or its sidecar cannot be written, or a sidecar cannot be read."""
