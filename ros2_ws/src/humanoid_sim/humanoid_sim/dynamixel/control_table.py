"""The control table of a Dynamixel XM430-W350 (Protocol 2.0), at its documented addresses.

Addresses below 64 are EEPROM: writable only while torque is off. Units follow the
e-Manual: position 4096 ticks per turn (2048 = centre), velocity 0.229 rpm, current
2.69 mA, voltage 0.1 V, temperature 1 °C.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

MODEL_NUMBER = 1020  # XM430-W350
FIRMWARE_VERSION = 45
EEPROM_END = 64
TABLE_SIZE = 147

TICKS_PER_RAD = 4096 / (2 * math.pi)
CENTER_TICKS = 2048
RPM_PER_UNIT = 0.229
AMP_PER_UNIT = 0.00269


@dataclass(frozen=True)
class Field:
    name: str
    address: int
    size: int
    writable: bool
    default: int = 0
    signed: bool = False


FIELDS = [
    Field("model_number", 0, 2, False, MODEL_NUMBER),
    Field("model_information", 2, 4, False),
    Field("firmware_version", 6, 1, False, FIRMWARE_VERSION),
    Field("id", 7, 1, True, 1),
    Field("baud_rate", 8, 1, True, 1),
    Field("return_delay_time", 9, 1, True, 250),
    Field("drive_mode", 10, 1, True, 0),
    Field("operating_mode", 11, 1, True, 3),
    Field("secondary_id", 12, 1, True, 255),
    Field("protocol_type", 13, 1, True, 2),
    Field("homing_offset", 20, 4, True, 0, signed=True),
    Field("moving_threshold", 24, 4, True, 10),
    Field("temperature_limit", 31, 1, True, 80),
    Field("max_voltage_limit", 32, 2, True, 160),
    Field("min_voltage_limit", 34, 2, True, 95),
    Field("pwm_limit", 36, 2, True, 885),
    Field("current_limit", 38, 2, True, 1193),
    Field("velocity_limit", 44, 4, True, 200),
    Field("max_position_limit", 48, 4, True, 4095),
    Field("min_position_limit", 52, 4, True, 0),
    Field("shutdown", 63, 1, True, 52),
    Field("torque_enable", 64, 1, True, 0),
    Field("led", 65, 1, True, 0),
    Field("status_return_level", 68, 1, True, 2),
    Field("registered_instruction", 69, 1, False, 0),
    Field("hardware_error_status", 70, 1, False, 0),
    Field("velocity_i_gain", 76, 2, True, 1920),
    Field("velocity_p_gain", 78, 2, True, 100),
    Field("position_d_gain", 80, 2, True, 0),
    Field("position_i_gain", 82, 2, True, 0),
    Field("position_p_gain", 84, 2, True, 800),
    Field("feedforward_2nd_gain", 88, 2, True, 0),
    Field("feedforward_1st_gain", 90, 2, True, 0),
    Field("bus_watchdog", 98, 1, True, 0),
    Field("goal_pwm", 100, 2, True, 885, signed=True),
    Field("goal_current", 102, 2, True, 1193, signed=True),
    Field("goal_velocity", 104, 4, True, 0, signed=True),
    Field("profile_acceleration", 108, 4, True, 0),
    Field("profile_velocity", 112, 4, True, 0),
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
BY_NAME = {f.name: f for f in FIELDS}
#: For every byte address, the field it belongs to (None: reserved, reads as 0).
OWNER: list[Field | None] = [None] * TABLE_SIZE
for _f in FIELDS:
    for _a in range(_f.address, _f.address + _f.size):
        OWNER[_a] = _f
PRESENT_START = BY_NAME["realtime_tick"].address
