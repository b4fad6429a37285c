"""A small perception pipeline: camera -> spot detector -> tracker -> monitor.

The components show the patterns a real robot uses: a timer-driven sensor, a pure
message transformer, a stateful filter with a run-time tunable parameter, and a consumer
that measures end-to-end latency from header stamps. None of them knows whether it runs
standalone, composed or under test.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np
from geometry_msgs.msg import PointStamped
from sensor_msgs.msg import Image

from efficient_comm import ParameterError, from_msg, to_msg
from efficient_comm.handle import NodeHandle, ParameterValue


class Camera:
    """Publishes a mono image with one bright spot moving on a circle."""

    def __init__(self, node: NodeHandle) -> None:
        self._node = node
        rate = node.declare_parameter("rate_hz", 30.0, description="frame rate",
                                      range=(1.0, 1000.0))
        self._width = node.declare_parameter("width", 160, read_only=True)
        self._height = node.declare_parameter("height", 120, read_only=True)
        self._pub = node.create_publisher(Image, "image", qos=5)
        self._frame = 0
        node.create_timer(1.0 / rate, self._tick)

    def spot(self, frame: int) -> tuple[int, int]:
        """Where the spot is in ``frame`` (pixel column, row)."""
        angle = frame * 0.1
        return (
            int(self._width / 2 + self._width / 3 * math.cos(angle)),
            int(self._height / 2 + self._height / 3 * math.sin(angle)),
        )

    def _tick(self) -> None:
        pixels = np.zeros((self._height, self._width), dtype=np.uint8)
        x, y = self.spot(self._frame)
        pixels[max(0, y - 1) : y + 2, max(0, x - 1) : x + 2] = 255
        msg = Image(height=self._height, width=self._width, encoding="mono8",
                    step=self._width, data=pixels.tobytes())
        msg.header.stamp = to_msg(self._node.clock.now_ns())
        msg.header.frame_id = "camera"
        self._frame += 1
        self._pub.publish(msg)


class SpotDetector:
    """Finds the brightest pixel of each image."""

    def __init__(self, node: NodeHandle) -> None:
        self._pub = node.create_publisher(PointStamped, "spot")
        node.create_subscription(Image, "image", self._on_image, qos=5)

    def _on_image(self, image: Image) -> None:
        pixels = np.frombuffer(image.data, dtype=np.uint8).reshape(image.height, image.step)
        row, col = np.unravel_index(int(np.argmax(pixels)), pixels.shape)
        out = PointStamped()
        out.header = image.header  # shares the stamp: header objects are read-only here
        out.point.x, out.point.y = float(col), float(row)
        self._pub.publish(out)


class Tracker:
    """Exponential smoothing of the spot; ``alpha`` can be tuned while running."""

    def __init__(self, node: NodeHandle) -> None:
        self._alpha = node.declare_parameter("alpha", 0.5, description="0 < alpha <= 1")
        node.add_on_parameter_change(self._on_change)
        self._pub = node.create_publisher(PointStamped, "track")
        self._state: tuple[float, float] | None = None
        node.create_subscription(PointStamped, "spot", self._on_spot)

    def _on_change(self, changes: Mapping[str, ParameterValue]) -> None:
        if "alpha" in changes:
            alpha = float(changes["alpha"])  # type: ignore[arg-type]
            if not 0.0 < alpha <= 1.0:
                raise ParameterError(f"alpha must be in (0, 1], got {alpha}")
            self._alpha = alpha

    def _on_spot(self, spot: PointStamped) -> None:
        x, y = spot.point.x, spot.point.y
        if self._state is not None:
            a = self._alpha
            x, y = a * x + (1 - a) * self._state[0], a * y + (1 - a) * self._state[1]
        self._state = (x, y)
        out = PointStamped()
        out.header = spot.header
        out.point.x, out.point.y = x, y
        self._pub.publish(out)


class Monitor:
    """Counts tracks and measures camera-to-track latency from the header stamps."""

    def __init__(self, node: NodeHandle) -> None:
        self._node = node
        self.count = 0
        self.latencies_ns: list[int] = []
        node.create_subscription(PointStamped, "track", self._on_track)

    def _on_track(self, track: PointStamped) -> None:
        self.count += 1
        self.latencies_ns.append(self._node.clock.now_ns() - from_msg(track.header.stamp))
