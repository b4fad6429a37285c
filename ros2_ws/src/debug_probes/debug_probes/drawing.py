"""Debug drawings over a camera image: cheap to write while someone looks, free otherwise.

A component that works on images (a detector, a line finder) draws what it found and what
it tried, in layers, in image coordinates, stamped with the image's stamp, and publishes all
of one image's drawing as one ``efficient_comm_interfaces/ImageMarkerArray`` (every element a
``visualization_msgs/ImageMarker``; text, which ImageMarker cannot carry, as
``ImageMarkerText``). The publisher is a :class:`~throttle_publisher.ThrottledPublisher`, so
a viewer asks for the rate it displays, and with nobody looking :meth:`DebugDrawing.wants`
answers False and nothing is drawn at all.

:func:`read_drawing` is the reader of the same format (one owner per format): viewers turn a
message back into plain :class:`Shape` values with it.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any, Literal, TypeAlias

from builtin_interfaces.msg import Time
from geometry_msgs.msg import Point
from std_msgs.msg import ColorRGBA
from visualization_msgs.msg import ImageMarker

from efficient_comm import from_msg, to_msg
from efficient_comm.handle import NodeHandle, QoSLike
from throttle_publisher import ThrottledPublisher

from .errors import DrawingError

#: Red, green, blue, alpha, each 0..1.
Color: TypeAlias = tuple[float, float, float, float]
RED: Color = (1.0, 0.0, 0.0, 1.0)
GREEN: Color = (0.0, 1.0, 0.0, 1.0)
BLUE: Color = (0.2, 0.4, 1.0, 1.0)
YELLOW: Color = (1.0, 0.9, 0.0, 1.0)
CYAN: Color = (0.0, 0.9, 0.9, 1.0)
MAGENTA: Color = (1.0, 0.0, 1.0, 1.0)
WHITE: Color = (1.0, 1.0, 1.0, 1.0)

Kind: TypeAlias = Literal["circle", "points", "lines", "polyline", "polygon", "text"]
_KIND_OF_TYPE: dict[int, Kind] = {
    ImageMarker.CIRCLE: "circle",
    ImageMarker.POINTS: "points",
    ImageMarker.LINE_LIST: "lines",
    ImageMarker.LINE_STRIP: "polyline",
    ImageMarker.POLYGON: "polygon",
}
XY: TypeAlias = tuple[float, float]


def _msg_type() -> type:
    from efficient_comm_interfaces.msg import ImageMarkerArray

    return ImageMarkerArray  # type: ignore[no-any-return]


def _rgba(color: Color) -> ColorRGBA:
    if len(color) != 4 or not all(0.0 <= c <= 1.0 for c in color):
        raise DrawingError(f"a colour is (r, g, b, a) with each in 0..1, got {color!r}")
    return ColorRGBA(r=float(color[0]), g=float(color[1]), b=float(color[2]),
                     a=float(color[3]))


def _point(x: float, y: float) -> Point:
    if not (math.isfinite(x) and math.isfinite(y)):
        raise DrawingError(f"pixel coordinates must be finite, got ({x}, {y})")
    return Point(x=float(x), y=float(y), z=0.0)


class DebugDrawing:
    """One image's debug drawing at a time, published on ``topic`` (throttled).

    Once per image, ask :meth:`wants`; only if it answers True, draw and :meth:`publish`
    with the image's stamp::

        drawing = DebugDrawing(node, "ball/debug_markers")
        ...
        if drawing.wants():
            drawing.circle("choice", u, v, r, color=GREEN)
            drawing.text("internals", 4, 12, f"{n} contours")
            drawing.publish(image.header.stamp)

    A False answer counts the image as skipped for the throttled subscribers, so
    ``every_nth`` stays in phase with the images, and makes the drawing calls until the next
    :meth:`wants` no-ops (so a forgotten ``if`` costs the arguments only). Layer names are the
    markers' ``ns``; ids count from 0 within a layer in each image.
    """

    def __init__(self, node: NodeHandle, topic: str, *, qos: QoSLike = 5,
                 count_bytes: bool = False) -> None:
        self._out = ThrottledPublisher(node, _msg_type(), topic, qos=qos,
                                       count_bytes=count_bytes)
        self.topic_name = self._out.topic_name
        self._active = False
        self._markers: list[ImageMarker] = []
        self._texts: list[Any] = []
        self._ids: dict[str, int] = {}
        #: Drawings published, and images for which nobody wanted one.
        self.published = 0
        self.skipped = 0

    @property
    def publisher(self) -> ThrottledPublisher:
        """The throttled publisher underneath (its requests and per-subscriber counts)."""
        return self._out

    def wants(self) -> bool:
        """Does anyone want this image's drawing? Ask once per image, before drawing."""
        self._clear()
        self._active = self._out.wants()
        if not self._active:
            self._out.skip()
            self.skipped += 1
        return self._active

    # -- elements ------------------------------------------------------------------------

    def circle(self, layer: str, x: float, y: float, radius: float, *, color: Color = GREEN,
               width: float = 1.0, fill: Color | None = None) -> None:
        """A circle around (``x``, ``y``); ``fill`` fills it (use a low alpha)."""
        if not math.isfinite(radius) or radius < 0:
            raise DrawingError(f"a circle's radius must be finite and >= 0, got {radius}")
        marker = self._marker(layer, ImageMarker.CIRCLE, color, width)
        if marker is not None:
            marker.position = _point(x, y)
            marker.scale = float(2 * radius)  # ImageMarker: the diameter for a CIRCLE
            if fill is not None:
                marker.filled = 1
                marker.fill_color = _rgba(fill)

    def points(self, layer: str, points: Iterable[XY], *, color: Color = YELLOW,
               size: float = 3.0) -> None:
        """Dots of ``size`` pixels."""
        self._shape(layer, ImageMarker.POINTS, points, color, size)

    def point(self, layer: str, x: float, y: float, *, color: Color = YELLOW,
              size: float = 3.0) -> None:
        self.points(layer, [(x, y)], color=color, size=size)

    def line(self, layer: str, x0: float, y0: float, x1: float, y1: float, *,
             color: Color = CYAN, width: float = 1.0) -> None:
        self._shape(layer, ImageMarker.LINE_LIST, [(x0, y0), (x1, y1)], color, width)

    def polyline(self, layer: str, points: Iterable[XY], *, closed: bool = False,
                 color: Color = CYAN, width: float = 1.0) -> None:
        """Connected segments; ``closed`` joins the last point to the first (a polygon)."""
        kind = ImageMarker.POLYGON if closed else ImageMarker.LINE_STRIP
        self._shape(layer, kind, points, color, width)

    def text(self, layer: str, x: float, y: float, text: str, *, color: Color = WHITE,
             size: float = 10.0) -> None:
        """``text`` with the left end of its baseline at (``x``, ``y``), ``size`` pixels high."""
        if not self._active:
            return
        from efficient_comm_interfaces.msg import ImageMarkerText

        self._texts.append(ImageMarkerText(
            ns=self._layer(layer), id=self._next_id(layer), position=_point(x, y),
            text=str(text), scale=float(size), color=_rgba(color)))

    # -- publishing ----------------------------------------------------------------------

    def publish(self, stamp: Time | int, *, frame_id: str = "") -> None:
        """Send what was drawn since :meth:`wants`, stamped ``stamp`` (the image's)."""
        if not self._active:
            return
        header_stamp = to_msg(stamp) if isinstance(stamp, int) else stamp
        msg = _msg_type()(markers=self._markers, texts=self._texts)
        msg.header.stamp = header_stamp
        msg.header.frame_id = frame_id
        for marker in self._markers:
            marker.header.stamp = header_stamp
            marker.header.frame_id = frame_id
        self._out.publish(msg)
        self.published += 1
        self._active = False
        self._markers, self._texts = [], []
        self._ids.clear()

    def _clear(self) -> None:
        self._markers.clear()
        self._texts.clear()
        self._ids.clear()

    def _layer(self, layer: str) -> str:
        if not layer:
            raise DrawingError("every element needs a layer name (it becomes the marker's ns)")
        return layer

    def _next_id(self, layer: str) -> int:
        n = self._ids.get(layer, 0)
        self._ids[layer] = n + 1
        return n

    def _marker(self, layer: str, kind: int, color: Color, width: float) -> ImageMarker | None:
        if not self._active:
            return None
        if not math.isfinite(width) or width <= 0:
            raise DrawingError(f"a line width or point size must be > 0, got {width}")
        marker = ImageMarker(ns=self._layer(layer), id=self._next_id(layer), type=kind,
                             action=ImageMarker.ADD, scale=float(width),
                             outline_color=_rgba(color))
        self._markers.append(marker)
        return marker

    def _shape(self, layer: str, kind: int, points: Iterable[XY], color: Color,
               width: float) -> None:
        marker = self._marker(layer, kind, color, width)
        if marker is not None:
            marker.points = [_point(x, y) for x, y in points]


# -- reading ---------------------------------------------------------------------------------


@dataclass(frozen=True)
class Shape:
    """One drawn element, as a viewer needs it.

    ``points``: the centre (circle, text) or the vertices; ``size``: a circle's radius, a
    line's width, a dot's size or the text's height, in pixels; ``fill`` for filled circles.
    """

    layer: str
    kind: Kind
    points: tuple[XY, ...]
    color: Color
    size: float
    fill: Color | None = None
    text: str = ""


@dataclass(frozen=True)
class Drawing:
    """A debug drawing read back: the image stamp it belongs to and its shapes."""

    stamp_ns: int
    frame_id: str
    shapes: tuple[Shape, ...]

    @property
    def layers(self) -> list[str]:
        """Layer names in the order they first appear."""
        return list(dict.fromkeys(s.layer for s in self.shapes))


def _color(c: Any) -> Color:
    return (float(c.r), float(c.g), float(c.b), float(c.a))


def read_drawing(msg: Any) -> Drawing:
    """An ``ImageMarkerArray`` as plain values; markers of unknown type or REMOVE are left out.

    The stamp is the message header's, or the first marker's when a sender left the header
    empty (as a foxglove_msgs/ImageMarkerArray-style sender would).
    """
    shapes: list[Shape] = []
    for m in msg.markers:
        kind = _KIND_OF_TYPE.get(m.type)
        if kind is None or m.action != ImageMarker.ADD:
            continue
        if kind == "circle":
            shapes.append(Shape(m.ns, kind, ((m.position.x, m.position.y),),
                                _color(m.outline_color), m.scale / 2,
                                _color(m.fill_color) if m.filled else None))
        else:
            shapes.append(Shape(m.ns, kind, tuple((p.x, p.y) for p in m.points),
                                _color(m.outline_color), m.scale))
    shapes.extend(Shape(t.ns, "text", ((t.position.x, t.position.y),), _color(t.color),
                        t.scale, text=t.text) for t in msg.texts)
    stamp = from_msg(msg.header.stamp)
    frame = msg.header.frame_id
    if stamp == 0 and msg.markers:
        stamp, frame = from_msg(msg.markers[0].header.stamp), msg.markers[0].header.frame_id
    return Drawing(stamp, frame, tuple(shapes))


def layer_names(drawings: Sequence[Drawing]) -> list[str]:
    """Every layer of ``drawings``, in order of first appearance."""
    return list(dict.fromkeys(layer for d in drawings for layer in d.layers))
