"""One emulated servo: its control table and the rules a real XM430 enforces on it.

A write is checked the way the e-Manual's status errors describe: an undefined or read-only
address, or EEPROM while torque is on, is an access error; a write that covers only part of
an item is a data length error; a value outside an item's range is a data range error; a
goal beyond its limit item (position limits in position control mode, PWM, current and
velocity limits) is a data limit error. A refused write changes nothing.
"""

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
        """``dxl_id`` is the servo's factory ID and the plant joint it is mounted on.

        The joint stays the same if a driver writes another ID: it is the wiring.
        """
        self.joint = dxl_id
        self.table = bytearray(ct.TABLE_SIZE)
        self.plant = plant
        self.registered: tuple[int, bytes] | None = None
        self.connected = True  # False: unplugged, never answers
        self._started = time.monotonic()
        self._set(ct.BY_NAME["id"], dxl_id)
        self.reset(keep=("id",))

    @property
    def dxl_id(self) -> int:
        return self.table[ct.BY_NAME["id"].address]

    def get(self, name: str) -> int:
        return self._value(self.table, ct.BY_NAME[name])

    @staticmethod
    def _value(table: bytearray, field: ct.Field) -> int:
        raw = bytes(table[field.address : field.address + field.size])
        return int.from_bytes(raw, "little", signed=field.signed)

    def _set(self, field: ct.Field, value: int) -> None:
        self.table[field.address : field.address + field.size] = value.to_bytes(
            field.size, "little", signed=field.signed
        )

    def set_hardware_error(self, bits: int) -> None:
        """Latch hardware error bits (overload 0x20, overheating 0x04, ...), as a fault would.

        Every status packet then carries the alert bit, and torque goes off, as with the
        default Shutdown setting; REBOOT clears them.
        """
        self._set(ct.BY_NAME["hardware_error_status"], bits)
        if bits:
            self._set(ct.BY_NAME["torque_enable"], 0)
            self._command()

    def reset(self, *, keep: tuple[str, ...], ram_only: bool = False) -> None:
        """Back to the defaults (all, or the RAM area as on REBOOT), keeping ``keep`` items."""
        for field in ct.FIELDS:
            if field.name not in keep and not (ram_only and field.address < ct.EEPROM_END):
                self._set(field, field.default)
        self.registered = None
        self._command()

    # -- reads ----------------------------------------------------------------------------

    def read(self, address: int, length: int) -> tuple[int, bytes]:
        if length < 1:
            return Error.DATA_RANGE, b""
        if address + length > ct.TABLE_SIZE:
            return Error.ACCESS, b""  # past the emulated table: an undefined address
        if address + length > ct.PRESENT_START:
            self._refresh()
        return Error.NONE, bytes(self.table[address : address + length])

    def _refresh(self) -> None:
        s = self.plant.state(self.joint)
        # e-Manual: Present Position = Actual Position + Homing Offset.
        ticks = round(s.position_rad * ct.TICKS_PER_RAD) + ct.CENTER_TICKS
        velocity = round(s.velocity_rad_s * 60 / (2 * math.pi) / ct.RPM_PER_UNIT)
        f = ct.BY_NAME
        self._set(f["present_position"], ticks + self.get("homing_offset"))
        self._set(f["present_velocity"], velocity)
        self._set(f["present_current"], round(s.current_a / ct.AMP_PER_UNIT))
        self._set(f["present_temperature"], round(s.temperature_c))
        self._set(f["present_input_voltage"], round(s.voltage_v * 10))
        self._set(f["moving"], int(abs(velocity) > self.get("moving_threshold")))
        self._set(f["realtime_tick"], int((time.monotonic() - self._started) * 1000) % 32768)

    # -- writes ---------------------------------------------------------------------------

    def check_write(self, address: int, data: bytes) -> int:
        """The error a write would get, without doing it (REG_WRITE checks early too)."""
        end = address + len(data)
        if not data:
            return Error.DATA_LENGTH
        if end > ct.TABLE_SIZE:
            return Error.ACCESS
        first, last = ct.OWNER[address], ct.OWNER[end - 1]
        if (first is not None and first.address < address) or (
            last is not None and last.address + last.size > end
        ):
            return Error.DATA_LENGTH  # e.g. two bytes of a four-byte item
        fields = {ct.OWNER[a] for a in range(address, end)}
        if None in fields or any(not f.writable for f in fields if f is not None):
            return Error.ACCESS
        if address < ct.EEPROM_END and self.get("torque_enable"):
            return Error.ACCESS  # EEPROM is locked while torque is on
        trial = bytearray(self.table)
        trial[address:end] = data
        written = [f for f in fields if f is not None]
        for f in written:
            value = self._value(trial, f)
            if (f.low is not None and value < f.low) or (f.high is not None and value > f.high):
                return Error.DATA_RANGE
        return self._check_limits(trial, {f.name for f in written})

    def _check_limits(self, trial: bytearray, written: set[str]) -> int:
        f = ct.BY_NAME
        for goal, limit in ct.GOAL_LIMITS.items():
            if goal in written and abs(self._value(trial, f[goal])) > self.get(limit):
                return Error.DATA_LIMIT
        if "goal_position" in written and self.get("operating_mode") == ct.POSITION_MODE:
            value = self._value(trial, f["goal_position"])
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
        goal_ticks = self.get("goal_position") - self.get("homing_offset")
        self.plant.command(
            self.joint,
            torque=bool(self.get("torque_enable")),
            goal_rad=(goal_ticks - ct.CENTER_TICKS) / ct.TICKS_PER_RAD,
            max_speed_rad_s=speed,
        )

    def alert(self) -> int:
        """Bit 7 of every status error byte while a hardware error is latched."""
        return 0x80 if self.get("hardware_error_status") else 0
