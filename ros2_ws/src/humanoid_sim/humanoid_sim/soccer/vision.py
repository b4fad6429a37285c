"""Ball detection: the largest orange blob in the image, as angles from the image centre.

Angles rather than pixels make the result independent of the camera's resolution; the
pinhole model comes from ``camera/camera_info``. The image is read in place (a numpy view of
the shared message, never copied or modified).
"""

from __future__ import annotations

import math

import cv2
import numpy as np
from geometry_msgs.msg import PointStamped
from rclpy.qos import DurabilityPolicy, QoSProfile
from sensor_msgs.msg import CameraInfo, Image

from efficient_comm.handle import NodeHandle

from ..errors import SimConfigError

#: Vertical field of view assumed before ``camera_info`` arrives (the head camera's).
FALLBACK_FOVY_DEG = 70.0


class BallDetector:
    def __init__(self, node: NodeHandle) -> None:
        self.node = node
        self.hue = node.declare_parameter("hue_range", [5, 22])  # OpenCV hue, 0..180
        self.min_saturation = node.declare_parameter("min_saturation", 120)
        self.min_value = node.declare_parameter("min_value", 70)
        self.min_radius_px = node.declare_parameter("min_radius_px", 1.5)
        if len(self.hue) != 2 or not 0 <= self.hue[0] <= self.hue[1] <= 180:
            raise SimConfigError(f"hue_range must be [low, high] within 0..180, got {self.hue}")
        self.fx = self.fy = self.cx = self.cy = 0.0
        self.frames = 0
        self.detections = 0
        self.rejected = 0
        self.pub = node.create_publisher(PointStamped, "ball/detection", qos=10)
        node.create_subscription(
            CameraInfo, "camera/camera_info", self._on_info,
            qos=QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL),
        )
        node.create_subscription(Image, "camera/image_raw", self._on_image, qos=1)

    def _on_info(self, info: CameraInfo) -> None:
        self.fx, self.cx, self.fy, self.cy = info.k[0], info.k[2], info.k[4], info.k[5]

    def _on_image(self, image: Image) -> None:
        self.frames += 1
        if image.encoding != "rgb8" or len(image.data) != image.height * image.step:
            self.rejected += 1
            self.node.logger.warning(
                f"skipping a {image.width}x{image.height} {image.encoding!r} image with "
                f"{len(image.data)} bytes: need rgb8 with height * step bytes"
            )
            return
        if self.fx <= 0:  # until camera_info arrives: the head camera's 70° vertical view
            self.fx = self.fy = image.height / (2 * math.tan(math.radians(FALLBACK_FOVY_DEG / 2)))
            self.cx, self.cy = image.width / 2, image.height / 2
        pixels = np.frombuffer(image.data, dtype=np.uint8).reshape(
            image.height, image.step // 3, 3)[:, : image.width]
        found = self.find(pixels)
        if found is None:
            return
        u, v, r = found
        self.detections += 1
        out = PointStamped()
        out.header.stamp = image.header.stamp  # shared, never modified
        out.header.frame_id = image.header.frame_id
        out.point.x = math.atan2(self.cx - u, self.fx)
        out.point.y = math.atan2(v - self.cy, self.fy)
        out.point.z = math.atan2(r, self.fx)
        self.pub.publish(out)

    def find(self, rgb: np.ndarray) -> tuple[float, float, float] | None:
        """Centre and radius (pixels) of the largest ball-coloured blob, or None."""
        hsv = cv2.cvtColor(rgb, cv2.COLOR_RGB2HSV)
        mask = cv2.inRange(hsv, (self.hue[0], self.min_saturation, self.min_value),
                           (self.hue[1], 255, 255))
        contours, _ = cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
        if not contours:
            return None
        (u, v), r = cv2.minEnclosingCircle(max(contours, key=cv2.contourArea))
        if r < self.min_radius_px:
            return None
        return float(u), float(v), float(r)
