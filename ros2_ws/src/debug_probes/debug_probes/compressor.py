"""JPEG for viewers off the robot: encoded only while someone wants a frame.

A raw 320x240 rgb8 frame is 230 kB; as JPEG at quality 80 it is about 10-15 kB. Encoding
costs the robot about a millisecond per frame, which is why the compressor publishes through
a :class:`~throttle_publisher.ThrottledPublisher`: a viewer asks for the rate it displays,
and with nobody looking not a single frame is encoded (each is counted as skipped, so
``every_nth`` stays in phase with the camera).
"""

from __future__ import annotations

import time
from collections.abc import Mapping

import cv2
import numpy as np
from sensor_msgs.msg import CompressedImage, Image

from efficient_comm.handle import NodeHandle, ParameterValue
from efficient_comm.standalone import standalone_main
from throttle_publisher import ThrottledPublisher

#: What cv2 can convert to the BGR it encodes from, by ROS image encoding.
_TO_BGR = {"rgb8": cv2.COLOR_RGB2BGR, "bgr8": None, "mono8": None}


#: ``jpeg_quality``'s range, declared with the parameter: every backend refuses values
#: outside it, and ``ros2 param describe`` and the GUI read it from the descriptor.
JPEG_QUALITY = (1, 100)


class JpegCompressor:
    """``<input>`` (sensor_msgs/Image) -> ``<input>/compressed`` (CompressedImage, "jpeg").

    Parameters: ``input`` (default ``camera/image_raw``), ``jpeg_quality`` (1..100, default
    80, changeable at run time: the next frame uses it). The output keeps the input's header,
    so drawings stamped with the image's stamp match the compressed frame too.
    """

    def __init__(self, node: NodeHandle) -> None:
        self.node = node
        topic = node.declare_parameter(
            "input", "camera/image_raw", description="sensor_msgs/Image topic to compress",
            read_only=True)
        self.quality = node.declare_parameter(
            "jpeg_quality", 80, description="JPEG quality (higher: larger, sharper)",
            range=JPEG_QUALITY)
        node.add_on_parameter_change(self._on_parameters)
        self.out = ThrottledPublisher(node, CompressedImage, f"{topic.rstrip('/')}/compressed",
                                      qos=2)
        node.create_subscription(Image, topic, self._on_image, qos=2)
        #: Frames encoded, frames nobody wanted, frames of an encoding it cannot compress.
        self.encoded = 0
        self.skipped = 0
        self.rejected = 0
        self.encode_ns = 0

    def _on_parameters(self, changes: Mapping[str, ParameterValue]) -> None:
        if "jpeg_quality" in changes:
            quality = changes["jpeg_quality"]
            assert isinstance(quality, int)  # the store checked its type and JPEG_QUALITY
            self.quality = quality

    def _on_image(self, image: Image) -> None:
        if not self.out.wants():
            self.out.skip()
            self.skipped += 1
            return
        data = self.encode(image)
        if data is None:
            return
        msg = CompressedImage(header=image.header, format="jpeg")
        msg.data = data
        self.encoded += 1
        self.out.publish(msg)

    def encode(self, image: Image) -> bytes | None:
        """The image as JPEG at the current quality; None (logged, counted) if it cannot be."""
        channels = 1 if image.encoding == "mono8" else 3
        if (image.encoding not in _TO_BGR or image.step < image.width * channels
                or len(image.data) != image.height * image.step):
            self.rejected += 1
            self.node.logger.warning(
                f"not compressing a {image.width}x{image.height} {image.encoding!r} image with "
                f"{len(image.data)} bytes: need rgb8, bgr8 or mono8 with height * step bytes")
            return None
        started = time.perf_counter_ns()
        rows = np.frombuffer(image.data, dtype=np.uint8).reshape(image.height, image.step)
        pixels = rows[:, : image.width * channels].reshape(image.height, image.width, channels)
        conversion = _TO_BGR[image.encoding]
        bgr = pixels if conversion is None else cv2.cvtColor(pixels, conversion)
        ok, jpeg = cv2.imencode(".jpg", bgr, [cv2.IMWRITE_JPEG_QUALITY, self.quality])
        self.encode_ns += time.perf_counter_ns() - started
        if not ok:  # pragma: no cover - cv2 encodes every 8-bit image it is given
            self.rejected += 1
            return None
        return jpeg.tobytes()


#: ``ros2 run debug_probes jpeg_compressor``: the compressor as a node of its own.
main = standalone_main(JpegCompressor, name="jpeg_compressor")
