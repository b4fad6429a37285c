"""What the servos move: the interface the bus talks to, and a simple test double.

The MuJoCo model implements :class:`Plant` for the simulated robot; :class:`IdealPlant`
is shipped for tests that need servos but no physics.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol


@dataclass(frozen=True)
class JointState:
    position_rad: float
    velocity_rad_s: float
    current_a: float
    temperature_c: float = 30.0
    voltage_v: float = 12.0


class Plant(Protocol):
    def command(self, dxl_id: int, *, torque: bool, goal_rad: float, max_speed_rad_s: float
                ) -> None:
        """Torque on: hold ``goal_rad``, moving at most ``max_speed_rad_s``; off: limp."""
        ...

    def state(self, dxl_id: int) -> JointState: ...

    @property
    def time_s(self) -> float:
        """The plant's time (s): what the servos' Realtime Tick counts. Simulated time, so
        a lockstep run reads the same ticks however fast the machine runs it."""
        ...


class IdealPlant:
    """Joints that move straight to their goal at the allowed speed; limp ones stay put."""

    def __init__(self) -> None:
        self._pos: dict[int, float] = {}
        self._vel: dict[int, float] = {}
        self._cmd: dict[int, tuple[bool, float, float]] = {}
        self._time_s = 0.0

    @property
    def time_s(self) -> float:
        return self._time_s

    def command(self, dxl_id: int, *, torque: bool, goal_rad: float, max_speed_rad_s: float
                ) -> None:
        self._cmd[dxl_id] = (torque, goal_rad, max_speed_rad_s)

    def state(self, dxl_id: int) -> JointState:
        return JointState(self._pos.get(dxl_id, 0.0), self._vel.get(dxl_id, 0.0), 0.0)

    def step(self, dt: float) -> None:
        self._time_s += dt
        for dxl_id, (torque, goal, speed) in self._cmd.items():
            pos = self._pos.get(dxl_id, 0.0)
            if not torque:
                self._vel[dxl_id] = 0.0
                continue
            move = max(-speed * dt, min(speed * dt, goal - pos))
            self._pos[dxl_id] = pos + move
            self._vel[dxl_id] = move / dt if dt else 0.0
