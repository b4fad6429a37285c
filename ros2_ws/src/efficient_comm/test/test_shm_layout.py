"""Which message types the shared-memory transport carries (efficient_comm.shm.layout).

The transport moves a message's one top-level array of numbers through shared memory and the
rest (its other fields) pickled next to it; these are the types the issue names, and two it
must leave to DDS.
"""

from __future__ import annotations

import os
import pickle

import numpy as np
import pytest
from sensor_msgs.msg import CompressedImage, Image, JointState, PointCloud2, PointField
from std_msgs.msg import Float32MultiArray, MultiArrayDimension, String, UInt8MultiArray

from efficient_comm.shm import Layout, _Rest, layout


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


def test_the_rest_of_a_message_round_trips_and_only_as_messages() -> None:
    """What travels beside the array (nested messages, strings, other sequences) comes
    back equal, with the array given by the reader; a chunk whose rest names anything but
    a message class (or array.array) is refused, not run."""
    image = Image(height=2, width=3, encoding="rgb8", step=9, data=bytes(18))
    image.header.frame_id = "cam"
    image.header.stamp.sec = 7
    cloud = PointCloud2(height=1, width=2, point_step=4, row_step=8, data=bytes(8),
                        fields=[PointField(name="x", offset=0, datatype=7, count=1)])
    floats = Float32MultiArray(data=[1.0, 2.0])
    floats.layout.dim = [MultiArrayDimension(label="n", size=2, stride=2)]
    for msg in (image, cloud, floats):
        rest = _Rest(type(msg), "data")
        back = rest.load(rest.dump(msg), msg.data)
        assert type(back) is type(msg) and back == msg
    rest = _Rest(Image, "data")
    with pytest.raises(pickle.UnpicklingError, match="not a message class"):
        rest.load(pickle.dumps((os.system,)), bytes(18))
