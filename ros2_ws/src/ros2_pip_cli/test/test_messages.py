"""Message text as ros2cli prints it (no DDS needed)."""

from __future__ import annotations

import pytest
from geometry_msgs.msg import Pose, PoseArray, PoseStamped
from sensor_msgs.msg import CameraInfo, Image

from efficient_comm import element_type
from ros2_pip_cli._messages import message_to_csv, message_to_yaml


@pytest.mark.parametrize(("field_type", "expected"), [
    ("sequence<uint8>", "uint8"),
    ("sequence<uint8, 5>", "uint8"),
    ("double[9]", "double"),
    ("sequence<geometry_msgs/Pose>", "geometry_msgs/msg/Pose"),
    ("sequence<string<=10>", "string"),
])
def test_element_type_names_the_elements_as_ros2cli_does(field_type, expected):
    assert element_type(field_type) == expected


def test_no_arr_summarises_sequences_by_their_element_type():
    image = message_to_yaml(Image(data=bytes(19200)), no_arr=True)
    assert "data: '<sequence type: uint8, length: 19200>'" in image
    poses = message_to_yaml(PoseArray(poses=[Pose(), Pose()]), no_arr=True)
    assert "poses: '<sequence type: geometry_msgs/msg/Pose, length: 2>'" in poses


def test_no_arr_names_fixed_size_arrays_as_rosidl_runtime_py_does():
    assert "k: '<array type: double[9]>'" in message_to_yaml(CameraInfo(), no_arr=True)


def test_csv_flattens_every_field_in_definition_order():
    pose = PoseStamped()
    pose.header.frame_id = "map"
    pose.pose.position.x = 1.5
    assert message_to_csv(pose) == "0,0,map,1.5,0.0,0.0,0.0,0.0,0.0,1.0"
    info = CameraInfo(d=[1.0, 2.5])
    assert message_to_csv(info, truncate_length=1).startswith("0,0,,0,0,,1.0,...,0.0,...")
    assert ",<sequence type: double, length: 2>,<array type: double[9]>," in \
        message_to_csv(info, no_arr=True)
