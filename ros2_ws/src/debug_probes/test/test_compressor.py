"""JpegCompressor on a test container: encodes only on demand, at the quality asked for."""

from __future__ import annotations

import array
from typing import Any

import cv2
import numpy as np
import pytest
from sensor_msgs.msg import CompressedImage, Image

from debug_probes import JPEG_QUALITY, JpegCompressor
from efficient_comm import ParameterError, Standalone, to_msg
from efficient_comm.testing import TestHandle, isolated_domain_id, test_container
from throttle_publisher import ThrottledSubscription, ThrottleOptions

W, H = 320, 240


def _image(stamp_ns: int = 7) -> Image:
    rng = np.random.default_rng(1)
    pixels = rng.integers(0, 255, (H, W, 3), dtype=np.uint8)  # noise: quality shows in size
    cv2.circle(pixels, (200, 80), 30, (255, 115, 0), -1)
    image = Image(height=H, width=W, encoding="rgb8", step=W * 3)
    image.header.stamp = to_msg(stamp_ns)
    image.header.frame_id = "head_camera"
    image.data = array.array("B", pixels.tobytes())
    return image


def _setup(**parameters: Any) -> tuple[TestHandle, JpegCompressor, list[CompressedImage]]:
    container = test_container()
    camera = TestHandle("camera", container=container)
    camera.create_publisher(Image, "camera/image_raw", qos=2)
    node = TestHandle("jpeg_compressor", container=container, parameters=parameters)
    compressor = JpegCompressor(node)
    got: list[CompressedImage] = []
    TestHandle("viewer", container=container).create_subscription(
        CompressedImage, "camera/image_raw/compressed", got.append)
    return camera, compressor, got


def test_frames_are_encoded_as_jpeg_with_the_images_header() -> None:
    camera, compressor, got = _setup()
    camera.inject("camera/image_raw", _image(stamp_ns=42))
    (msg,) = got
    assert msg.format == "jpeg" and msg.header.stamp.nanosec == 42
    assert msg.header.frame_id == "head_camera"
    decoded = cv2.imdecode(np.frombuffer(bytes(msg.data), np.uint8), cv2.IMREAD_COLOR)
    assert decoded is not None and decoded.shape == (H, W, 3)
    b, _g, r = decoded[80, 200]  # the orange disc, back in BGR: red high, blue low
    assert r > 200 and b < 60
    assert compressor.encoded == 1 and compressor.skipped == 0


def test_quality_is_applied_and_changes_at_run_time() -> None:
    camera, compressor, got = _setup(jpeg_quality=95)
    camera.inject("camera/image_raw", _image())
    compressor.node.set_parameter("jpeg_quality", 10)
    camera.inject("camera/image_raw", _image())
    high, low = (len(m.data) for m in got)
    assert low < high / 3
    assert compressor.quality == 10
    with pytest.raises(ParameterError):
        compressor.node.set_parameter("jpeg_quality", 0)
    assert compressor.quality == 10


def test_nothing_is_encoded_while_nobody_wants_it_and_skips_are_counted() -> None:
    container = test_container()
    camera = TestHandle("camera", container=container)
    camera.create_publisher(Image, "camera/image_raw", qos=2)
    compressor = JpegCompressor(TestHandle("jpeg_compressor", container=container))
    camera.inject("camera/image_raw", _image(), _image(), _image())
    assert (compressor.encoded, compressor.skipped) == (0, 3)
    got: list[Any] = []
    ThrottledSubscription(TestHandle("viewer", container=container), CompressedImage,
                          "/camera/image_raw/compressed", got.append,
                          options=ThrottleOptions(every_nth=2))
    camera.inject("camera/image_raw", *[_image() for _ in range(4)])
    assert compressor.encoded == len(got) == 2 and compressor.skipped == 5


def test_a_bad_quality_or_image_is_refused_with_a_reason() -> None:
    with pytest.raises(Exception, match=r"'jpeg_quality': 101 is out of range \[1, 100\]"):
        _setup(jpeg_quality=101)
    camera, compressor, got = _setup()
    bad = _image()
    bad.encoding = "32FC1"
    camera.inject("camera/image_raw", bad)
    assert got == [] and compressor.rejected == 1
    assert isinstance(compressor.node, TestHandle)
    assert any("not compressing" in text for _level, text in compressor.node.records)


def test_the_quality_range_is_in_the_descriptor_tools_read() -> None:
    """What ``ros2 param describe`` prints and the GUI pre-checks: the range, declared once."""
    with Standalone(JpegCompressor, name="jpeg_compressor", domain_id=isolated_domain_id(),
                    stats_period_s=0) as node:
        descriptor = node.node.describe_parameter("jpeg_quality")
    assert [(r.from_value, r.to_value) for r in descriptor.integer_range] == [JPEG_QUALITY]
