"""Type name <-> class: one owner, both directions, every kind, clear errors."""

from __future__ import annotations

import pytest
from rcl_interfaces.srv import GetParameters
from rclpy.qos import QoSProfile
from std_msgs.msg import String

from efficient_comm import (
    EfficientCommError,
    UnknownTypeError,
    import_type,
    type_name,
)


@pytest.mark.parametrize(("cls", "name"), [
    (String, "std_msgs/msg/String"),
    (GetParameters, "rcl_interfaces/srv/GetParameters"),
])
def test_class_to_name_and_back(cls: type, name: str) -> None:
    assert type_name(cls) == name
    kind = name.split("/")[1]
    assert import_type(name, kind=kind) is cls
    assert import_type(name.replace(f"/{kind}/", "/"), kind=kind) is cls


@pytest.mark.parametrize(("name", "kind", "says"), [
    ("std_msgs/msg/NoSuchType", "msg", "no msg type 'NoSuchType'"),
    ("no_such_pkg/msg/String", "msg", "'no_such_pkg' of 'no_such_pkg/msg/String' is not installed"),
    ("std_msgs/String/extra", "msg", "must be pkg/msg/Name"),
    ("rcl_interfaces/srv/GetParameters", "msg", "is a srv type, expected pkg/msg/Name"),
    ("std_msgs/msg/String", "srv", "is a msg type, expected pkg/srv/Name"),
    ("", "msg", "must be pkg/msg/Name"),
])
def test_unknown_or_malformed_names_raise_one_clear_error(name: str, kind: str,
                                                         says: str) -> None:
    with pytest.raises(UnknownTypeError, match=None) as info:
        import_type(name, kind=kind)
    assert says in str(info.value)
    assert isinstance(info.value, EfficientCommError) and isinstance(info.value, LookupError)


def test_a_class_that_is_not_generated_has_no_type_name() -> None:
    with pytest.raises(UnknownTypeError, match="not a generated ROS interface class"):
        type_name(QoSProfile)

