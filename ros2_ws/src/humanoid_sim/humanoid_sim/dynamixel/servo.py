"""One emulated servo: its control table and the rules a real XM430 enforces on it.

A write is checked the way the e-Manual's status errors describe: an undefined or read-only
address, or EEPROM while torque is on, is an access error; a write that covers only part of
an item is a data length error; a value outside an item's range is a data range error; a
goal beyond its limit item (position limits in position control mode, PWM, current and
velocity limits) is a data limit error. A refused write changes nothing.

Indirect Data bytes stand for the bytes their Indirect Address items name: a read returns
the named byte, a write is checked and done as a write of the named bytes (so four Indirect
Data bytes mapped to Goal Position take a 4-byte goal, and two of them a data length
error). One level only: an Indirect Address naming an Indirect Data byte (the default)
makes that byte plain storage.
"""

from __future__ import annotations

import math
import struct

from . import control_table as ct
from .plant import Plant
from .protocol import Error

(_LOW_1, _HIGH_1), (_LOW_2, _HIGH_2) = ct.INDIRECT_DATA_SPANS
_ID = ct.BY_NAME["id"].address
#: The items a read of present values refreshes, and those it depends on.
_PRESENT = tuple(ct.BY_NAME[name] for name in (
    "present_position", "present_velocity", "present_current", "present_temperature",
    "present_input_voltage", "moving", "realtime_tick"))
#: How each of them is written into the table (little-endian, the item's size and sign).
_PRESENT_PACK = tuple(
    (struct.Struct("<" + {1: "b", 2: "h", 4: "i"}[f.size] if f.signed
                   else "<" + {1: "B", 2: "H", 4: "I"}[f.size]), f.address)
    for f in _PRESENT)
_HOMING, _MOVING_THRESHOLD = ct.BY_NAME["homing_offset"], ct.BY_NAME["moving_threshold"]
_TORQUE, _PROFILE_VELOCITY = ct.BY_NAME["torque_enable"], ct.BY_NAME["profile_velocity"]
_GOAL_POSITION, _MODE = ct.BY_NAME["goal_position"], ct.BY_NAME["operating_mode"]
_MIN_POSITION, _MAX_POSITION = ct.BY_NAME["min_position_limit"], ct.BY_NAME["max_position_limit"]
#: Each item by (address, size): a write of exactly one whole item (a driver's goals, torque)
#: is checked without the general path's per-byte bookkeeping (_check_one).
_WHOLE = {(f.address, f.size): f for f in ct.FIELDS}
#: The limit item each goal item is bounded by (control_table.GOAL_LIMITS), by goal name.
_GOAL_LIMIT = {goal: ct.BY_NAME[limit] for goal, limit in ct.GOAL_LIMITS.items()}
#: The items the plant's command is made of (names): a write of another leaves it as it is.
_COMMANDED = frozenset(f.name for f in (_TORQUE, _PROFILE_VELOCITY, _GOAL_POSITION, _HOMING))
#: Speed when profile_velocity is 0 ("infinite" on a real servo): the no-load speed.
NO_LOAD_SPEED_RAD_S = 46 * 2 * math.pi / 60


class Servo:
    """A control table backed by a :class:`Plant` joint; present values come from it."""

    def __init__(self, dxl_id: int, plant: Plant, *,
                 firmware_version: int = ct.FIRMWARE_VERSION) -> None:
        """``dxl_id`` is the servo's factory ID and the plant joint it is mounted on.

        The joint stays the same if a driver writes another ID: it is the wiring.
        ``firmware_version`` decides what the servo understands (Fast Sync Read from
        :data:`~.control_table.FAST_READ_FIRMWARE` on).
        """
        self.joint = dxl_id
        self.firmware_version = firmware_version
        self.table = bytearray(ct.TABLE_SIZE)
        self.plant = plant
        self.registered: tuple[int, bytes] | None = None
        self.connected = True  # False: unplugged, never answers
        self._set(ct.BY_NAME["id"], dxl_id)
        self.reset(keep=("id",))

    @property
    def dxl_id(self) -> int:
        return self.table[_ID]

    def get(self, name: str) -> int:
        return self._value(self.table, ct.BY_NAME[name])

    @staticmethod
    def _value(table: bytearray, field: ct.Field) -> int:
        return int.from_bytes(table[field.address : field.address + field.size], "little",
                              signed=field.signed)

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
        self._set(ct.BY_NAME["firmware_version"], self.firmware_version)
        self.registered = None
        self._command()

    # -- reads ----------------------------------------------------------------------------

    @property
    def fast_read(self) -> bool:
        """Whether this servo answers Fast Sync Read and Fast Bulk Read."""
        return self.firmware_version >= ct.FAST_READ_FIRMWARE

    def _physical(self, address: int) -> int:
        """The table byte ``address`` stands for (itself, or what its Indirect Address names)."""
        pointer = ct.INDIRECT_DATA.get(address)
        if pointer is None:
            return address
        target = int.from_bytes(self.table[pointer : pointer + 2], "little")
        return address if target in ct.INDIRECT_DATA else target

    def _map(self, address: int, length: int) -> list[int] | None:
        """The table bytes a read or write of ``address``.. covers; None: all are direct."""
        end = address + length
        if not (end > _LOW_1 and address < _HIGH_1) and not (end > _LOW_2 and address < _HIGH_2):
            return None  # the common case, checked without a loop: every read passes here
        return [self._physical(a) for a in range(address, end)]

    def read(self, address: int, length: int) -> tuple[int, bytes]:
        if length < 1:
            return Error.DATA_RANGE, b""
        if address + length > ct.TABLE_SIZE:
            return Error.ACCESS, b""  # past the control table: an undefined address
        mapped = self._map(address, length)
        if mapped is None:
            if address < ct.PRESENT_END and address + length > ct.PRESENT_START:
                self._refresh()
            return Error.NONE, bytes(self.table[address : address + length])
        if any(ct.PRESENT_START <= a < ct.PRESENT_END for a in mapped):
            self._refresh()
        return Error.NONE, bytes(self.table[a] for a in mapped)

    def _refresh(self) -> None:
        s = self.plant.state(self.joint)
        # e-Manual: Present Position = Actual Position + Homing Offset.
        ticks = round(s.position_rad * ct.TICKS_PER_RAD) + ct.CENTER_TICKS
        velocity = round(s.velocity_rad_s * 60 / (2 * math.pi) / ct.RPM_PER_UNIT)
        table = self.table
        moving = abs(velocity) > self._value(table, _MOVING_THRESHOLD)
        values = (ticks + self._value(table, _HOMING), velocity,
                  round(s.current_a / ct.AMP_PER_UNIT), round(s.temperature_c),
                  round(s.voltage_v * 10), int(moving),
                  # Milliseconds of the plant's time, not the wall clock's: in lockstep a
                  # driver that reads the tick must read the same whatever the load.
                  round(self.plant.time_s * 1000) % 32768)
        for (packer, address), value in zip(_PRESENT_PACK, values, strict=True):
            packer.pack_into(table, address, value)

    # -- writes ---------------------------------------------------------------------------

    def check_write(self, address: int, data: bytes) -> int:
        """The error a write would get, without doing it (REG_WRITE checks early too)."""
        return self._plan(address, data)[0]

    def _plan(self, address: int, data: bytes) -> tuple[int, dict[int, int]]:
        """(error, the bytes the write would put where) of a write of ``data``."""
        if not data:
            return Error.DATA_LENGTH, {}
        if address + len(data) > ct.TABLE_SIZE:
            return Error.ACCESS, {}
        writes = self._bytes(address, data)
        return self._check(writes), writes

    def _bytes(self, address: int, data: bytes) -> dict[int, int]:
        """What a write of ``data`` at ``address`` puts where, Indirect Data resolved."""
        mapped = self._map(address, len(data))
        if mapped is None:
            return dict(zip(range(address, address + len(data)), data, strict=True))
        return dict(zip(mapped, data, strict=True))

    def _check(self, writes: dict[int, int]) -> int:
        fields = {ct.OWNER[a] for a in writes}
        written = [f for f in fields if f is not None]
        if any(a not in writes for f in written for a in range(f.address, f.address + f.size)):
            return Error.DATA_LENGTH  # e.g. two bytes of a four-byte item
        if None in fields or any(not f.writable for f in written):
            return Error.ACCESS
        if min(writes) < ct.EEPROM_END and self.get("torque_enable"):
            return Error.ACCESS  # EEPROM is locked while torque is on
        trial = bytearray(self.table)
        for a, byte in writes.items():
            trial[a] = byte
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
        field = _WHOLE.get((address, len(data)))
        if field is not None and self._map(address, len(data)) is None:
            error = self._check_one(field, data)
            if error:
                return error
            self.table[address : address + len(data)] = data
            if field.name in _COMMANDED:
                self._command()
            return Error.NONE
        error, writes = self._plan(address, data)
        if error:
            return error
        for a, byte in writes.items():
            self.table[a] = byte
        self._command()
        return Error.NONE

    def _check_one(self, field: ct.Field, data: bytes) -> int:
        """:meth:`_check` of a write of exactly ``field``, the same rules in the same order:
        a driver writes its goals to twenty servos a hundred times a second, and the
        general path (a trial copy of the table, the items owning each byte) was most of
        the emulator's work."""
        if not field.writable:
            return Error.ACCESS
        table = self.table
        if field.address < ct.EEPROM_END and table[_TORQUE.address]:
            return Error.ACCESS  # EEPROM is locked while torque is on
        value = int.from_bytes(data, "little", signed=field.signed)
        if (field.low is not None and value < field.low) or (
                field.high is not None and value > field.high):
            return Error.DATA_RANGE
        limit = _GOAL_LIMIT.get(field.name)
        if limit is not None and abs(value) > self._value(table, limit):
            return Error.DATA_LIMIT
        if field is _GOAL_POSITION and self._value(table, _MODE) == ct.POSITION_MODE and not (
                self._value(table, _MIN_POSITION) <= value <= self._value(table, _MAX_POSITION)):
            return Error.DATA_LIMIT
        return Error.NONE

    def _command(self) -> None:
        table = self.table
        profile = self._value(table, _PROFILE_VELOCITY)
        speed = (profile * ct.RPM_PER_UNIT * 2 * math.pi / 60) if profile else NO_LOAD_SPEED_RAD_S
        goal_ticks = self._value(table, _GOAL_POSITION) - self._value(table, _HOMING)
        self.plant.command(
            self.joint,
            torque=bool(table[_TORQUE.address]),
            goal_rad=(goal_ticks - ct.CENTER_TICKS) / ct.TICKS_PER_RAD,
            max_speed_rad_s=speed,
        )

    def alert(self) -> int:
        """Bit 7 of every status error byte while a hardware error is latched."""
        return 0x80 if self.get("hardware_error_status") else 0
