"""Ball detection: the largest orange blob in the image, as angles from the image centre.

Angles rather than pixels make the result independent of the camera's resolution; the
pinhole model comes from ``camera/camera_info``. The image is read in place (a numpy view of
the shared message, never copied or modified).

While someone looks (a debug view), the detector draws on ``ball/debug_markers`` what it saw,
stamped with the image's stamp, in layers: ``contours`` (the outlines of the ball-coloured
blobs), ``candidates`` (their enclosing circles; red: too small), ``choice`` (the ball it
reports) and ``internals`` (contour count, thresholds, radius as text). Nobody looking costs
one demand query per image. The thresholds are parameters that take effect at the next
image when changed at run time (an operator tuning them watches the drawing change).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import cv2
import numpy as np
from geometry_msgs.msg import PointStamped
from sensor_msgs.msg import CameraInfo, Image

from debug_probes import CYAN, GREEN, MAGENTA, RED, WHITE, YELLOW, DebugDrawing
from efficient_comm import latched_qos
from efficient_comm.handle import NodeHandle, ParameterValue

from ..errors import SimConfigError

#: Vertical field of view assumed before ``camera_info`` arrives (the head camera's).
FALLBACK_FOVY_DEG = 70.0
#: The largest blobs drawn (by area): enough to see what went wrong, a bounded message.
MAX_DRAWN_CONTOURS = 20
#: Points per drawn contour outline at most.
MAX_OUTLINE_POINTS = 40


class BallDetector:
    def __init__(self, node: NodeHandle) -> None:
        self.node = node
        self.hue = node.declare_parameter("hue_range", [5, 22])  # OpenCV hue, 0..180
        self.min_saturation = node.declare_parameter("min_saturation", 120, range=(0, 255))
        self.min_value = node.declare_parameter("min_value", 70, range=(0, 255))
        self.min_radius_px = node.declare_parameter("min_radius_px", 1.5, range=(0.0, 100.0))
        _check_hue(self.hue)
        node.add_on_parameter_change(self._on_parameters)
        self.fx = self.fy = self.cx = self.cy = 0.0
        self.frames = 0
        self.detections = 0
        self.rejected = 0
        self.pub = node.create_publisher(PointStamped, "ball/detection", qos=10)
        self.drawing = DebugDrawing(node, "ball/debug_markers")
        node.create_subscription(
            CameraInfo, "camera/camera_info", self._on_info,
            qos=latched_qos(),
        )
        node.create_subscription(Image, "camera/image_raw", self._on_image, qos=1)

    def _on_parameters(self, changes: Mapping[str, ParameterValue]) -> None:
        """Thresholds changed at run time apply from the next image (invalid ones vetoed)."""
        if "hue_range" in changes:
            hue = changes["hue_range"]
            assert isinstance(hue, list)
            _check_hue(hue)
            self.hue = [int(h) for h in hue]
        for name in ("min_saturation", "min_value", "min_radius_px"):
            if name in changes:
                setattr(self, name, changes[name])

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
        contours = self._contours(pixels)
        found = self._choose(contours)
        if self.drawing.wants():
            self._draw(contours, found)
            self.drawing.publish(image.header.stamp, frame_id=image.header.frame_id)
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
        return self._choose(self._contours(rgb))

    def _contours(self, rgb: np.ndarray) -> Sequence[Any]:
        hsv = cv2.cvtColor(rgb, cv2.COLOR_RGB2HSV)
        mask = cv2.inRange(hsv, (self.hue[0], self.min_saturation, self.min_value),
                           (self.hue[1], 255, 255))
        contours, _ = cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
        return contours

    def _choose(self, contours: Sequence[Any]) -> tuple[float, float, float] | None:
        if not contours:
            return None
        (u, v), r = cv2.minEnclosingCircle(max(contours, key=cv2.contourArea))
        if r < self.min_radius_px:
            return None
        return float(u), float(v), float(r)

    def _draw(self, contours: Sequence[Any],
              found: tuple[float, float, float] | None) -> None:
        """What this image showed the detector, in layers (only while someone looks)."""
        d = self.drawing
        for contour in sorted(contours, key=cv2.contourArea, reverse=True)[:MAX_DRAWN_CONTOURS]:
            outline = contour.reshape(-1, 2)[:: max(1, len(contour) // MAX_OUTLINE_POINTS)]
            d.polyline("contours", [(float(x), float(y)) for x, y in outline], closed=True,
                       color=YELLOW)
            (u, v), r = cv2.minEnclosingCircle(contour)
            d.circle("candidates", float(u), float(v), float(r),
                     color=MAGENTA if r >= self.min_radius_px else RED)
        if found is not None:
            u, v, r = found
            d.circle("choice", u, v, r, color=GREEN, width=2.0, fill=(0.0, 1.0, 0.0, 0.25))
            d.point("choice", u, v, color=GREEN, size=4.0)
            d.line("choice", self.cx, self.cy, u, v, color=CYAN)
        d.text("internals", 4, 12, f"{len(contours)} contours", color=WHITE)
        d.text("internals", 4, 24, f"hue {self.hue[0]}..{self.hue[1]} S>={self.min_saturation} "
               f"V>={self.min_value} r>={self.min_radius_px:g}", color=WHITE)
        d.text("internals", 4, 36, "no ball" if found is None else f"ball r={found[2]:.1f} px",
               color=WHITE)


def _check_hue(hue: Any) -> None:
    if len(hue) != 2 or not 0 <= hue[0] <= hue[1] <= 180:
        raise SimConfigError(f"hue_range must be [low, high] within 0..180, got {hue}")


class BlobBallDetector(BallDetector):
    """The ball as the roundest ball-coloured blob rather than the largest.

    A second algorithm beside :class:`BallDetector`, for comparing the two on the same
    log (``ros2 run log_analysis compare``): the colour detector takes the largest orange
    blob, so an orange thing bigger than the ball (a red robot's edge against the turf, a
    shirt) wins over the ball; this one scores each blob by how well it fills its
    enclosing circle (1 for a disc, little for a bar) times the square root of its area,
    and takes none that fills less than ``min_fill``. Same thresholds, topics and
    drawing as the colour detector.
    """

    def __init__(self, node: NodeHandle) -> None:
        super().__init__(node)
        self.min_fill = node.declare_parameter("min_fill", 0.35, range=(0.0, 1.0))

    def _on_parameters(self, changes: Mapping[str, ParameterValue]) -> None:
        super()._on_parameters(changes)
        if "min_fill" in changes:
            value = changes["min_fill"]
            assert isinstance(value, (int, float))  # the declared range vetoed the rest
            self.min_fill = float(value)

    def _choose(self, contours: Sequence[Any]) -> tuple[float, float, float] | None:
        best, score = None, 0.0
        for contour in contours:
            (u, v), r = cv2.minEnclosingCircle(contour)
            if r < self.min_radius_px:
                continue
            # A blob of a few pixels: its pixel count, not its outline's area (which is 0
            # for a one-pixel-wide blob).
            area = max(cv2.contourArea(contour), float(len(contour)))
            fill = min(area / (math.pi * r * r), 1.0)
            if fill >= self.min_fill and fill * math.sqrt(area) > score:
                best, score = (float(u), float(v), float(r)), fill * math.sqrt(area)
        return best
