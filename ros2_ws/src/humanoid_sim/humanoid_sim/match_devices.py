"""What crosses between the team match's world process and a robot process besides
``/clock``: where a robot's devices arrive on its domain, and the IMU's history. Both ends
import it; a module of its own so that a robot process does not import the world (MuJoCo,
the video encoder) for two constants."""

from __future__ import annotations

__all__ = ["DEVICE", "IMU_DEPTH"]

#: Where a robot's devices arrive on its domain (``/<robot>/device/imu/data``, ...); the
#: robot's :class:`~.match_robot.DeviceInput` takes each once from DDS and publishes it
#: in-process under the usual name.
DEVICE = "device"
#: The IMU's history on a robot's domain (both ends): at 100 Hz, half a second. A loaded
#: robot takes DDS samples only between its callbacks; with 10, the writer overwrote what
#: the robot had not taken yet.
IMU_DEPTH = 50
