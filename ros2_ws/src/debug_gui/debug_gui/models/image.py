"""The image view's data: a robot's camera as JPEG with its debug drawings, matched by stamp.

Feeds (only while the view is shown): ``camera/image_raw/compressed`` at the rate the view
displays, through throttle_publisher, so the robot encodes only the frames shown; and the
debug drawings (``ball/debug_markers``, ImageMarkerArray) at the robot's rate, because they
are small and a frame needs the drawing of *its* stamp: two independently throttled topics
would let different frames through.

The model keeps the last :data:`BUFFER_FRAMES` frames and drawings by stamp. Live, the frame
shown is the newest one whose drawing has arrived (or that waited :data:`GRACE_S` for one:
a robot that draws nothing still shows images). Paused, the feeds close (a paused view costs
the robot nothing) and :meth:`ImageModel.step` moves through the buffered frames.
A frame's wait is judged by stamps on the source's clock (:mod:`.ages`). Recorded (a
source that is not live), the newest drawn frame is shown, or the newest frame when none
held has a drawing: a paused playback's clock would never end a wait.
:meth:`ImageModel.reset` (a seek) forgets the buffers.
The JPEG quality is a parameter of the robot's compressor: a log cannot change it
(:class:`~debug_gui.errors.NotLive`).
The overlay is SVG (:func:`svg_overlay`) in image pixels, drawn over the JPEG by the browser.
"""

from __future__ import annotations

import html
import threading
from collections import OrderedDict, deque
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Any

from debug_probes import JPEG_QUALITY, Drawing, Shape, read_drawing
from efficient_comm import from_msg

from ..errors import NOT_LIVE, CallFailed, InvalidInput, NotLive
from ..robots import RobotId
from ..source import Source, Stream
from .ages import StampAges

IMAGE_TOPIC = "camera/image_raw/compressed"
MARKERS_TOPIC = "ball/debug_markers"
#: The robot's JpegCompressor node (relative to the robot's namespace): its jpeg_quality.
COMPRESSOR_NODE = "jpeg_compressor"
BUFFER_FRAMES = 60
#: How long a live frame waits for its drawing before it is shown without one.
GRACE_S = 0.15
DEFAULT_RATE_HZ = 30.0


@dataclass(frozen=True, slots=True)
class Frame:
    """One compressed camera frame as received."""

    seq: int
    stamp_ns: int
    jpeg: bytes
    received_s: float


class ImageModel:
    """A robot's camera image and debug drawings (activate to receive, deactivate to stop)."""

    def __init__(
        self,
        source: Source,
        robot: RobotId,
        *,
        rate_hz: float = DEFAULT_RATE_HZ,
        image_topic: str = IMAGE_TOPIC,
        markers_topic: str = MARKERS_TOPIC,
        buffer: int = BUFFER_FRAMES,
        clock: Callable[[], float] | None = None,
    ) -> None:
        if buffer < 1:
            raise InvalidInput(f"the frame buffer holds at least 1 frame, not {buffer}")
        self.source = source
        self.robot = robot
        self.image_topic = image_topic
        self.markers_topic = markers_topic
        self._rate_hz = rate_hz
        #: The source's clock (seconds): monotonic live, the log's time in a playback.
        self._clock = clock or source.now
        self._ages = StampAges(self._clock)
        self._unsubscribe_reset: Callable[[], None] | None = None
        self._lock = threading.Lock()  # the data; feeds' callbacks take it
        self._feeds_lock = threading.Lock()  # opening and closing the feeds
        self._frames: deque[Frame] = deque(maxlen=buffer)
        self._drawings: OrderedDict[int, Drawing] = OrderedDict()
        self._max_drawings = 2 * buffer
        self._layers: dict[str, None] = {}
        self._hidden_layers: set[str] = set()
        self._feeds: list[Stream] = []
        self._listeners: list[Callable[[], None]] = []
        self._seq = 0
        self._paused_at: int | None = None  # index into the frozen buffer while paused
        self._frozen: list[Frame] = []
        #: Changes whenever what the view shows may have changed (frames, pause, layers).
        self.version = 0
        self.received = 0
        self.drawings_received = 0

    # -- feeds ---------------------------------------------------------------------------

    def activate(self) -> None:
        """Subscribe (idempotent; not while paused: a paused view costs nothing)."""
        from sensor_msgs.msg import CompressedImage

        from efficient_comm_interfaces.msg import ImageMarkerArray

        # Not under self._lock: a feed may deliver (on_image takes that lock on the Hub's
        # thread) before the second one is made, and the Hub's thread must never wait for us.
        with self._feeds_lock:
            if self._feeds or self._paused_at is not None:
                return
            if self._unsubscribe_reset is None:
                self._unsubscribe_reset = self.source.on_reset(self.reset)
            self._feeds = [
                self.source.subscribe(self.robot, self.image_topic, CompressedImage,
                                   self.on_image, rate_hz=self._rate_hz, qos=2),
                self.source.subscribe(self.robot, self.markers_topic, ImageMarkerArray,
                                   self.on_markers, rate_hz=None, qos=5),
            ]

    def deactivate(self) -> None:
        """Close the feeds: the robot stops encoding and drawing for this view."""
        with self._feeds_lock:
            unsubscribe, self._unsubscribe_reset = self._unsubscribe_reset, None
        self._close_feeds()
        if unsubscribe is not None:
            unsubscribe()

    def _close_feeds(self) -> None:
        with self._feeds_lock:
            feeds, self._feeds = self._feeds, []
        for feed in feeds:
            feed.close()

    def reset(self) -> None:
        """Forget every frame and drawing, the frozen ones too (the source moved to
        another instant); the layers seen and hidden stay (the user's choice)."""
        with self._lock:
            self._frames.clear()
            self._drawings.clear()
            self._frozen = []
            if self._paused_at is not None:
                self._paused_at = 0
            self._ages.reset()
        self._changed()

    @property
    def active(self) -> bool:
        return bool(self._feeds)

    @property
    def rate_hz(self) -> float:
        return self._rate_hz

    def set_rate(self, rate_hz: float) -> None:
        """Display (and receive) at most ``rate_hz`` frames per second from now on."""
        from ..security import check_rate

        checked = check_rate(rate_hz)
        if checked is None:
            raise InvalidInput("the image view needs a rate")
        self._rate_hz = checked
        with self._feeds_lock:
            feeds = list(self._feeds)
        if feeds:
            feeds[0].set_rate(checked)

    def add_listener(self, callback: Callable[[], None]) -> Callable[[], None]:
        """Call ``callback`` (on a feed's thread) when something new may be shown."""
        with self._lock:
            self._listeners.append(callback)

        def remove() -> None:
            with self._lock:
                if callback in self._listeners:
                    self._listeners.remove(callback)

        return remove

    def _changed(self) -> None:
        with self._lock:
            self.version += 1
            listeners = list(self._listeners)
        for cb in listeners:
            cb()

    def on_image(self, msg: Any) -> None:
        """A CompressedImage (on the Hub's thread, or from tests)."""
        stamp_ns = from_msg(msg.header.stamp)
        with self._lock:
            self._seq += 1
            self._frames.append(Frame(self._seq, stamp_ns, bytes(msg.data),
                                      self._ages.heard(stamp_ns)))
            self.received += 1
        self._changed()

    def on_markers(self, msg: Any) -> None:
        """An ImageMarkerArray (on the Hub's thread, or from tests)."""
        drawing = read_drawing(msg)
        with self._lock:
            self._drawings[drawing.stamp_ns] = drawing
            while len(self._drawings) > self._max_drawings:
                self._drawings.popitem(last=False)
            for layer in drawing.layers:
                self._layers.setdefault(layer, None)
            self.drawings_received += 1
        self._changed()

    # -- what is shown -------------------------------------------------------------------

    def frames(self) -> list[Frame]:
        """The buffered frames, oldest first (the frozen ones while paused)."""
        with self._lock:
            return list(self._frozen) if self._paused_at is not None else list(self._frames)

    def has_camera(self) -> bool:
        """Whether the robot publishes the image topic now (a plain ROS 2 robot, or one
        without a camera, does not: its view says so rather than wait)."""
        return self.source.publishes(self.robot, self.image_topic)

    def drawing_for(self, stamp_ns: int) -> Drawing | None:
        with self._lock:
            return self._drawings.get(stamp_ns)

    def current(self) -> tuple[Frame, Drawing | None] | None:
        """The frame to show and its drawing (None before the first frame)."""
        with self._lock:
            if self._paused_at is not None:
                if not self._frozen:
                    return None
                frame = self._frozen[self._paused_at]
                return frame, self._drawings.get(frame.stamp_ns)
            if not self.source.live:
                return self._recorded_current()
            for frame in reversed(self._frames):
                drawing = self._drawings.get(frame.stamp_ns)
                if drawing is not None or self._ages.age_s(
                        frame.stamp_ns, delivered_s=frame.received_s) >= GRACE_S:
                    return frame, drawing
            return None

    def _recorded_current(self) -> tuple[Frame, Drawing | None] | None:
        """Recorded: the newest frame with its drawing if any frame held has one, else the
        newest frame. A paused playback's clock never ends a wait, and a log's drawing is
        there or never comes; playing, the drawn frame lags the newest by the drawing's
        delay at most, instead of the overlay blinking off for each new frame."""
        if not self._frames:
            return None
        for frame in reversed(self._frames):
            drawing = self._drawings.get(frame.stamp_ns)
            if drawing is not None:
                return frame, drawing
        return self._frames[-1], None

    def layers(self) -> list[str]:
        """Every layer seen so far, in order of first appearance."""
        with self._lock:
            return list(self._layers)

    def shown_layers(self) -> list[str]:
        with self._lock:
            return [name for name in self._layers if name not in self._hidden_layers]

    def show_layer(self, layer: str, shown: bool) -> None:
        if not isinstance(layer, str) or not layer or len(layer) > 200:
            raise InvalidInput(f"not a layer name: {layer!r}")
        with self._lock:
            if shown:
                self._hidden_layers.discard(layer)
            else:
                self._hidden_layers.add(layer)
        self._changed()

    def overlay(self, drawing: Drawing | None) -> str:
        """The SVG elements of ``drawing``'s shown layers."""
        if drawing is None:
            return ""
        with self._lock:
            hidden = set(self._hidden_layers)
        return svg_overlay(s for s in drawing.shapes if s.layer not in hidden)

    # -- pause and step ------------------------------------------------------------------

    @property
    def paused(self) -> bool:
        return self._paused_at is not None

    def pause(self) -> None:
        """Freeze on the frame shown now; the feeds close until :meth:`resume`."""
        shown = self.current()
        with self._lock:
            if self._paused_at is not None:
                return
            self._frozen = list(self._frames)
            index = len(self._frozen) - 1
            if shown is not None:
                index = next((i for i, f in enumerate(self._frozen) if f.seq == shown[0].seq),
                             index)
            self._paused_at = max(index, 0)
        self._close_feeds()  # still reset by a seek: its frozen frames are of this instant
        self._changed()

    def resume(self, *, shown: bool = True) -> None:
        """Back to live (subscribing again if the view is ``shown``)."""
        with self._lock:
            self._paused_at = None
            self._frozen = []
        if shown:
            self.activate()
        self._changed()

    def step(self, delta: int) -> Frame | None:
        """Paused: move ``delta`` frames through the buffer (clamped); the frame now shown."""
        if isinstance(delta, bool) or not isinstance(delta, int):
            raise InvalidInput(f"step by a whole number of frames, not {delta!r}")
        with self._lock:
            if self._paused_at is None or not self._frozen:
                return None
            self._paused_at = min(max(self._paused_at + delta, 0), len(self._frozen) - 1)
            frame = self._frozen[self._paused_at]
        self._changed()
        return frame

    def position(self) -> tuple[int, int] | None:
        """Paused: (index of the frame shown, frames buffered)."""
        with self._lock:
            if self._paused_at is None:
                return None
            return self._paused_at, len(self._frozen)

    # -- JPEG quality (a parameter of the robot's compressor) ------------------------------

    def _check_live(self, what: str) -> None:
        if not self.source.live:
            raise NotLive(f"{self.robot.label}: {NOT_LIVE}: a log cannot {what} the JPEG "
                          f"quality of its {COMPRESSOR_NODE}")

    def quality(self, *, timeout_s: float = 5.0) -> int:
        """The compressor's ``jpeg_quality`` (blocking: never on the UI's event loop)."""
        from rcl_interfaces.srv import GetParameters

        self._check_live("read")
        response = self.source.call(self.robot, f"{COMPRESSOR_NODE}/get_parameters",
                                 GetParameters, GetParameters.Request(names=["jpeg_quality"]),
                                 timeout_s=timeout_s)
        if not response.values or response.values[0].type != 2:  # PARAMETER_INTEGER
            raise CallFailed(f"{self.robot.label}: {COMPRESSOR_NODE} has no jpeg_quality")
        return int(response.values[0].integer_value)

    def set_quality(self, quality: int, *, timeout_s: float = 5.0) -> None:
        """Set the compressor's ``jpeg_quality`` (within JPEG_QUALITY; blocking). The caller
        checks the writer's token first (it is a change to the robot)."""
        from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
        from rcl_interfaces.srv import SetParameters

        self._check_live("set")
        low, high = JPEG_QUALITY
        if isinstance(quality, bool) or not isinstance(quality, int) or not low <= quality <= high:
            raise InvalidInput(f"JPEG quality is an integer {low}..{high}, not {quality!r}")
        value = ParameterValue(type=ParameterType.PARAMETER_INTEGER, integer_value=quality)
        request = SetParameters.Request(parameters=[Parameter(name="jpeg_quality", value=value)])
        response = self.source.call(self.robot, f"{COMPRESSOR_NODE}/set_parameters", SetParameters,
                                 request, timeout_s=timeout_s)
        result = response.results[0] if response.results else None
        if result is None or not result.successful:
            reason = result.reason if result is not None else "no result"
            raise CallFailed(f"{self.robot.label}: jpeg_quality {quality} refused: {reason}")


# -- SVG ----------------------------------------------------------------------------------------


def _css(color: tuple[float, float, float, float]) -> str:
    r, g, b, a = color
    return f"rgba({round(r * 255)},{round(g * 255)},{round(b * 255)},{a:.3g})"


def _pts(points: Iterable[tuple[float, float]]) -> str:
    return " ".join(f"{x:.1f},{y:.1f}" for x, y in points)


def svg_shape(shape: Shape) -> str:
    """One shape as an SVG element in image pixels (layer in ``data-layer``)."""
    layer = html.escape(shape.layer, quote=True)
    stroke = _css(shape.color)
    if shape.kind == "circle":
        (x, y), = shape.points
        fill = _css(shape.fill) if shape.fill is not None else "none"
        return (f'<circle data-layer="{layer}" cx="{x:.1f}" cy="{y:.1f}" r="{shape.size:.1f}" '
                f'stroke="{stroke}" fill="{fill}" stroke-width="1.5"/>')
    if shape.kind == "text":
        (x, y), = shape.points
        return (f'<text data-layer="{layer}" x="{x:.1f}" y="{y:.1f}" fill="{stroke}" '
                f'font-size="{shape.size:.1f}" font-family="monospace">'
                f"{html.escape(shape.text)}</text>")
    if shape.kind == "points":
        r = shape.size / 2
        return "".join(f'<circle data-layer="{layer}" cx="{x:.1f}" cy="{y:.1f}" r="{r:.1f}" '
                       f'fill="{stroke}"/>' for x, y in shape.points)
    if shape.kind == "lines":
        pairs = zip(shape.points[::2], shape.points[1::2], strict=False)
        return "".join(
            f'<line data-layer="{layer}" x1="{a[0]:.1f}" y1="{a[1]:.1f}" x2="{b[0]:.1f}" '
            f'y2="{b[1]:.1f}" stroke="{stroke}" stroke-width="{shape.size:.1f}"/>'
            for a, b in pairs)
    tag = "polygon" if shape.kind == "polygon" else "polyline"
    return (f'<{tag} data-layer="{layer}" points="{_pts(shape.points)}" fill="none" '
            f'stroke="{stroke}" stroke-width="{shape.size:.1f}"/>')


def svg_overlay(shapes: Iterable[Shape]) -> str:
    """The SVG elements of ``shapes`` (to go inside an ``<svg>`` with the image's viewBox)."""
    return "".join(svg_shape(s) for s in shapes)
