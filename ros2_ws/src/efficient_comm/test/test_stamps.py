"""Stamp <-> nanoseconds: one owner (efficient_comm's from_msg/to_msg), exact both ways."""

from __future__ import annotations

import pytest
from builtin_interfaces.msg import Time

from efficient_comm import from_msg, to_msg


@pytest.mark.parametrize("ns", [0, 1, 999_999_999, 1_000_000_000, 1_732_500_000_123_456_789])
def test_nanoseconds_to_a_stamp_and_back_is_exact(ns: int) -> None:
    stamp = to_msg(ns)
    assert isinstance(stamp, Time) and 0 <= stamp.nanosec < 1_000_000_000
    assert from_msg(stamp) == ns


def test_a_stamp_is_read_as_rclpy_writes_it() -> None:
    assert from_msg(Time(sec=12, nanosec=345)) == 12_000_000_345
