"""YAML values into messages, converted by the field's type (no DDS needed)."""

from __future__ import annotations

import re

import pytest
from builtin_interfaces.msg import Time
from geometry_msgs.msg import PoseStamped
from sensor_msgs.msg import CameraInfo
from std_msgs.msg import Bool, Byte, Int8, String, UInt64

from ros2_pip_cli._fill import set_message_fields
from ros2_pip_cli.errors import CliError


@pytest.mark.parametrize(("cls", "value", "expected"), [
    (PoseStamped, {"pose": {"position": {"x": "1.5"}}}, "x=1.5"),
    (Bool, {"data": "yes"}, "data=True"),
    (Bool, {"data": "false"}, "data=False"),
    (Int8, {"data": 3.7}, "data=3"),
    (UInt64, {"data": "7"}, "data=7"),
    (String, {"data": 5}, "data='5'"),
    (Byte, {"data": 65}, "data=b'A'"),
])
def test_values_convert_as_ros2cli_converts_them(cls, value, expected):
    msg = cls()
    set_message_fields(msg, value)
    assert expected in repr(msg)


@pytest.mark.parametrize(("cls", "value", "field"), [
    (PoseStamped, {"pose": {"position": {"x": "abc"}}}, "pose.position.x"),
    (Bool, {"data": "maybe"}, "data"),
    (Int8, {"data": 128}, "data"),
    (Int8, {"data": "1.5"}, "data"),
    (UInt64, {"data": -1}, "data"),
    (String, {"data": {"a": 1}}, "data"),
    (CameraInfo, {"k": [1.0]}, "k"),
    (CameraInfo, {"d": [1.0, "x"]}, "d[1]"),
    (PoseStamped, {"header": "auto"}, "header"),  # only topic pub expands it
])
def test_what_does_not_convert_is_refused_naming_the_field(cls, value, field):
    with pytest.raises(CliError, match=rf"Failed to populate field: .*{re.escape(field)}"):
        set_message_fields(cls(), value)


def test_header_auto_and_stamp_now_are_left_to_setters():
    msg = PoseStamped()
    setters = set_message_fields(msg, {"header": "auto"}, expand_stamps=True)
    for set_stamp in setters:
        set_stamp(Time(sec=12, nanosec=3))
    assert (msg.header.stamp.sec, msg.header.stamp.nanosec) == (12, 3)
    msg = PoseStamped()
    setters = set_message_fields(msg, {"header": {"stamp": "now", "frame_id": "map"}},
                                 expand_stamps=True)
    for set_stamp in setters:
        set_stamp(Time(sec=5))
    assert msg.header.stamp.sec == 5 and msg.header.frame_id == "map"
