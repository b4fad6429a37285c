"""The control table of a Dynamixel XM430-W350 (Protocol 2.0), at its documented addresses.

Addresses, sizes, access, defaults and value ranges follow the e-Manual's XM430-W350 page.
Addresses below 64 are EEPROM: writable only while torque is off. Units: position 4096
ticks per turn (2048 = centre), velocity 0.229 rpm, current 2.69 mA, voltage 0.1 V,
temperature 1 °C.

The indirect address area lets a driver gather scattered items into one contiguous block
(one sync read instead of several): Indirect Address n (2 bytes, 64..661, RAM only) names
a control table byte, and Indirect Data n reads and writes that byte with its item's size,
range and access rules. Items 1-28 are at 168/224, items 29-56 at 578/634; by default each
Indirect Address points at its own Indirect Data byte, which then is plain storage.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

MODEL_NUMBER = 1020  # XM430-W350
FIRMWARE_VERSION = 45
#: Fast Sync Read and Fast Bulk Read exist from this firmware on (e-Manual, Protocol 2.0:
#: "X430/540 Series (Fw v45 or above)"); older servos ignore them like any unknown broadcast.
FAST_READ_FIRMWARE = 45
EEPROM_END = 64
TABLE_SIZE = 662  # up to Indirect Data 56 (661)
POSITION_MODE = 3  # the operating mode whose goals the position limits bound

TICKS_PER_RAD = 4096 / (2 * math.pi)
CENTER_TICKS = 2048
RPM_PER_UNIT = 0.229
AMP_PER_UNIT = 0.00269


@dataclass(frozen=True)
class Field:
    """One control table item; ``low``/``high`` bound what a WRITE may put there."""

    name: str
    address: int
    size: int
    writable: bool
    default: int = 0
    signed: bool = False
    low: int | None = None
    high: int | None = None


_GAIN_MAX = 16383
FIELDS = [
    Field("model_number", 0, 2, False, MODEL_NUMBER),
    Field("model_information", 2, 4, False),
    Field("firmware_version", 6, 1, False, FIRMWARE_VERSION),
    Field("id", 7, 1, True, 1, low=0, high=252),
    Field("baud_rate", 8, 1, True, 1, low=0, high=7),
    Field("return_delay_time", 9, 1, True, 250, low=0, high=254),
    Field("drive_mode", 10, 1, True, 0),
    Field("operating_mode", 11, 1, True, POSITION_MODE, low=0, high=16),
    Field("secondary_id", 12, 1, True, 255),
    Field("protocol_type", 13, 1, True, 2, low=1, high=2),
    Field("homing_offset", 20, 4, True, 0, signed=True, low=-1_044_479, high=1_044_479),
    Field("moving_threshold", 24, 4, True, 10, low=0, high=1023),
    Field("temperature_limit", 31, 1, True, 80, low=0, high=100),
    Field("max_voltage_limit", 32, 2, True, 160),
    Field("min_voltage_limit", 34, 2, True, 95),
    Field("pwm_limit", 36, 2, True, 885, low=0, high=885),
    Field("current_limit", 38, 2, True, 1193, low=0, high=1193),
    Field("velocity_limit", 44, 4, True, 200, low=0, high=1023),
    Field("max_position_limit", 48, 4, True, 4095, low=0, high=4095),
    Field("min_position_limit", 52, 4, True, 0, low=0, high=4095),
    Field("shutdown", 63, 1, True, 52),
    Field("torque_enable", 64, 1, True, 0, low=0, high=1),
    Field("led", 65, 1, True, 0, low=0, high=1),
    Field("status_return_level", 68, 1, True, 2, low=0, high=2),
    Field("registered_instruction", 69, 1, False, 0),
    Field("hardware_error_status", 70, 1, False, 0),
    Field("velocity_i_gain", 76, 2, True, 1920, low=0, high=_GAIN_MAX),
    Field("velocity_p_gain", 78, 2, True, 100, low=0, high=_GAIN_MAX),
    Field("position_d_gain", 80, 2, True, 0, low=0, high=_GAIN_MAX),
    Field("position_i_gain", 82, 2, True, 0, low=0, high=_GAIN_MAX),
    Field("position_p_gain", 84, 2, True, 800, low=0, high=_GAIN_MAX),
    Field("feedforward_2nd_gain", 88, 2, True, 0, low=0, high=_GAIN_MAX),
    Field("feedforward_1st_gain", 90, 2, True, 0, low=0, high=_GAIN_MAX),
    Field("bus_watchdog", 98, 1, True, 0, low=0, high=127),
    Field("goal_pwm", 100, 2, True, 885, signed=True),
    Field("goal_current", 102, 2, True, 1193, signed=True),
    Field("goal_velocity", 104, 4, True, 0, signed=True),
    Field("profile_acceleration", 108, 4, True, 0, low=0, high=32767),
    Field("profile_velocity", 112, 4, True, 0, low=0, high=32767),
    Field("goal_position", 116, 4, True, CENTER_TICKS, signed=True),
    Field("realtime_tick", 120, 2, False),
    Field("moving", 122, 1, False),
    Field("moving_status", 123, 1, False),
    Field("present_pwm", 124, 2, False, signed=True),
    Field("present_current", 126, 2, False, signed=True),
    Field("present_velocity", 128, 4, False, signed=True),
    Field("present_position", 132, 4, False, CENTER_TICKS, signed=True),
    Field("velocity_trajectory", 136, 4, False, signed=True),
    Field("position_trajectory", 140, 4, False, signed=True),
    Field("present_input_voltage", 144, 2, False, 120),
    Field("present_temperature", 146, 1, False, 30),
]
#: (first Indirect Address, first Indirect Data, count) of the two indirect areas.
INDIRECT_AREAS = ((168, 224, 28), (578, 634, 28))
#: What an Indirect Address may name: the RAM area (e-Manual, "Indirect Address Range").
INDIRECT_TARGETS = (EEPROM_END, TABLE_SIZE - 1)
_number = 0
for _address_at, _data_at, _count in INDIRECT_AREAS:
    for _k in range(_count):
        _number += 1
        FIELDS.append(Field(f"indirect_address_{_number}", _address_at + 2 * _k, 2, True,
                            _data_at + _k, low=INDIRECT_TARGETS[0], high=INDIRECT_TARGETS[1]))
        FIELDS.append(Field(f"indirect_data_{_number}", _data_at + _k, 1, True))
#: Indirect Data byte address -> the address of the Indirect Address item that maps it.
INDIRECT_DATA = {
    data_at + k: address_at + 2 * k
    for address_at, data_at, count in INDIRECT_AREAS for k in range(count)
}
INDIRECT_DATA_SPANS = tuple((data_at, data_at + count) for _, data_at, count in INDIRECT_AREAS)
BY_NAME = {f.name: f for f in FIELDS}
#: For every byte address, the field it belongs to (None: reserved, reads as 0).
OWNER: list[Field | None] = [None] * TABLE_SIZE
for _f in FIELDS:
    for _a in range(_f.address, _f.address + _f.size):
        OWNER[_a] = _f
#: The items the plant's state refreshes before a read: [PRESENT_START, PRESENT_END).
PRESENT_START = BY_NAME["realtime_tick"].address
PRESENT_END = BY_NAME["present_temperature"].address + 1
#: Goals whose magnitude another item bounds (a write beyond it is a Data Limit Error).
GOAL_LIMITS = {
    "goal_pwm": "pwm_limit",
    "goal_current": "current_limit",
    "goal_velocity": "velocity_limit",
}
