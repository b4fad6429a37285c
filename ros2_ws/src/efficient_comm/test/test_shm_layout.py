"""Which message types the shared-memory transport carries (efficient_comm.shm.layout).

The transport moves a message's one top-level array of numbers through shared memory and the
rest in CDR; these are the types the issue names, and two it must leave to DDS.
"""

from __future__ import annotations

import numpy as np
import pytest
from sensor_msgs.msg import CompressedImage, Image, JointState, PointCloud2
from std_msgs.msg import Float32MultiArray, String, UInt8MultiArray

from efficient_comm.shm import Layout, layout


@pytest.mark.parametrize(("msg_type", "field", "dtype"), [
    (Image, "data", np.uint8),
    (CompressedImage, "data", np.uint8),
    (PointCloud2, "data", np.uint8),
    (UInt8MultiArray, "data", np.uint8),
    (Float32MultiArray, "data", np.float32),
])
def test_big_array_types_fit(msg_type: type, field: str, dtype: type) -> None:
    assert layout(msg_type) == Layout(field, np.dtype(dtype))


@pytest.mark.parametrize(("msg_type", "count"), [(String, 0), (JointState, 3)])
def test_types_without_exactly_one_array_do_not(msg_type: type, count: int) -> None:
    why = layout(msg_type)
    assert isinstance(why, str) and f"has {count} top-level arrays" in why
