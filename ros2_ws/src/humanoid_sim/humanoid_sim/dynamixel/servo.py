"""One emulated servo: its control table and the rules a real XM430 enforces."""

from __future__ import annotations

import math
import time

from . import control_table as ct
from .plant import Plant
from .protocol import Error

#: Speed when profile_velocity is 0 ("infinite" on a real servo): the no-load speed.
NO_LOAD_SPEED_RAD_S = 46 * 2 * math.pi / 60


class Servo:
    """A control table backed by a :class:`Plant` joint; present values come from it."""

    def __init__(self, dxl_id: int, plant: Plant) -> None:
        self.table = bytearray(ct.TABLE_SIZE)
        for field in ct.FIELDS:
            self._set(field, field.default)
        self._set(ct.BY_NAME["id"], dxl_id)
        self.plant = plant
        self.registered: tuple[int, bytes] | None = None
        self.connected = True  # False: unplugged, never answers
        self._started = time.monotonic()

    @property
    def dxl_id(self) -> int:
        return self.table[ct.BY_NAME["id"].address]

    def get(self, name: str) -> int:
        field = ct.BY_NAME[name]
        raw = bytes(self.table[field.address : field.address + field.size])
        return int.from_bytes(raw, "little", signed=field.signed)

    def _set(self, field: ct.Field, value: int) -> None:
        self.table[field.address : field.address + field.size] = value.to_bytes(
            field.size, "little", signed=field.signed
        )

    # -- reads ----------------------------------------------------------------------------

    def read(self, address: int, length: int) -> tuple[int, bytes]:
        if length < 1 or address + length > ct.TABLE_SIZE:
            return Error.DATA_RANGE, b""
        if address + length > ct.PRESENT_START:
            self._refresh()
        return Error.NONE, bytes(self.table[address : address + length])

    def _refresh(self) -> None:
        s = self.plant.state(self.dxl_id)
        ticks = round(s.position_rad * ct.TICKS_PER_RAD) + ct.CENTER_TICKS
        ticks -= self.get("homing_offset")
        rpm = s.velocity_rad_s * 60 / (2 * math.pi)
        f = ct.BY_NAME
        self._set(f["present_position"], ticks)
        self._set(f["present_velocity"], round(rpm / ct.RPM_PER_UNIT))
        self._set(f["present_current"], round(s.current_a / ct.AMP_PER_UNIT))
        self._set(f["present_temperature"], round(s.temperature_c))
        self._set(f["present_input_voltage"], round(s.voltage_v * 10))
        self._set(f["moving"], int(abs(s.velocity_rad_s) > 0.01))
        self._set(f["realtime_tick"], int((time.monotonic() - self._started) * 1000) % 32768)

    # -- writes ---------------------------------------------------------------------------

    def check_write(self, address: int, data: bytes) -> int:
        """The error a write would get, without doing it (REG_WRITE checks early too)."""
        if not data or address + len(data) > ct.TABLE_SIZE:
            return Error.DATA_RANGE
        fields = {ct.OWNER[a] for a in range(address, address + len(data))}
        if None in fields or any(not f.writable for f in fields if f is not None):
            return Error.ACCESS
        if address < ct.EEPROM_END and self.get("torque_enable"):
            return Error.ACCESS  # EEPROM is locked while torque is on
        trial = bytearray(self.table)
        trial[address : address + len(data)] = data
        goal = ct.BY_NAME["goal_position"]
        if address < goal.address + goal.size and address + len(data) > goal.address:
            value = int.from_bytes(trial[goal.address : goal.address + 4], "little", signed=True)
            if not self.get("min_position_limit") <= value <= self.get("max_position_limit"):
                return Error.DATA_LIMIT
        return Error.NONE

    def write(self, address: int, data: bytes) -> int:
        error = self.check_write(address, data)
        if error:
            return error
        self.table[address : address + len(data)] = data
        self._command()
        return Error.NONE

    def _command(self) -> None:
        profile = self.get("profile_velocity")
        speed = (profile * ct.RPM_PER_UNIT * 2 * math.pi / 60) if profile else NO_LOAD_SPEED_RAD_S
        goal_ticks = self.get("goal_position") + self.get("homing_offset")
        self.plant.command(
            self.dxl_id,
            torque=bool(self.get("torque_enable")),
            goal_rad=(goal_ticks - ct.CENTER_TICKS) / ct.TICKS_PER_RAD,
            max_speed_rad_s=speed,
        )

    def alert(self) -> int:
        """Bit 7 of every status error byte while a hardware error is latched."""
        return 0x80 if self.get("hardware_error_status") else 0
