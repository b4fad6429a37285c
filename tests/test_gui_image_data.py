"""The image view's data side: without a browser, against a robot in its own process.

The model logic (matching by stamp, layers, pause and step, the SVG) is checked on messages
made here; the feeds, the throttling and the JPEG quality against the real ball detector
and JPEG compressor of a light robot whose camera draws its picture
(tests/_gui_camera_robot.py: the simulation would add nothing here but start-up and CPU).
"""

from __future__ import annotations

import statistics
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest
from sensor_msgs.msg import CompressedImage

from debug_gui import Feed, Hub, RobotId
from debug_gui.errors import InvalidInput
from debug_gui.models.image import GRACE_S, IMAGE_TOPIC, MARKERS_TOPIC, ImageModel, svg_overlay
from debug_gui.testing import FakeSource
from debug_gui.ui.image import frame_message
from debug_probes import DebugDrawing
from efficient_comm import to_msg
from efficient_comm.testing import TestHandle, isolated_domain_id, test_container

from ._gui import camera_robot, wait_for


class _Clock:
    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


def _jpeg(stamp_ns: int) -> CompressedImage:
    msg = CompressedImage(format="jpeg")
    msg.header.stamp = to_msg(stamp_ns)
    ok, data = cv2.imencode(".jpg", np.zeros((24, 32, 3), np.uint8))
    assert ok
    msg.data = data.tobytes()
    return msg


def _drawings(stamps: list[int], text: str = "<b>&") -> list[Any]:
    """Drawings as the robot's DebugDrawing publishes them, one per stamp."""
    container = test_container()
    drawing = DebugDrawing(TestHandle("detector", container=container), "m")
    got: list[Any] = []
    from efficient_comm_interfaces.msg import ImageMarkerArray

    TestHandle("viewer", container=container).create_subscription(ImageMarkerArray, "m",
                                                                   got.append)
    for stamp in stamps:
        assert drawing.wants()
        drawing.circle("choice", 10, 12, 3)
        drawing.text("internals", 1, 9, f"{text} {stamp}")
        drawing.publish(stamp)
    return got


def _model(clock: _Clock, buffer: int = 60) -> ImageModel:
    return ImageModel(FakeSource(), RobotId(0, "/robot"), clock=clock, buffer=buffer)


def test_the_frame_shown_carries_the_drawing_of_its_own_stamp() -> None:
    clock = _Clock()
    model = _model(clock)
    assert model.current() is None
    d1, d2 = _drawings([1_000, 2_000])
    model.on_image(_jpeg(1_000))
    model.on_markers(d1)
    model.on_image(_jpeg(2_000))  # its drawing has not arrived yet
    frame, drawing = model.current() or pytest.fail("no frame")
    assert frame.stamp_ns == 1_000 and drawing is not None and drawing.stamp_ns == 1_000
    clock.now += GRACE_S  # waited long enough: shown without a drawing
    frame, drawing = model.current() or pytest.fail("no frame")
    assert frame.stamp_ns == 2_000 and drawing is None
    model.on_markers(d2)
    frame, drawing = model.current() or pytest.fail("no frame")
    assert frame.stamp_ns == 2_000 and drawing is not None and drawing.stamp_ns == 2_000
    # What goes to the browser: that frame's JPEG and its own overlay, stamps as strings.
    out = frame_message(model)
    assert out is not None
    size = int.from_bytes(out[1][:4], "big")
    import json

    meta = json.loads(out[1][4 : 4 + size])
    assert meta["stamp_ns"] == meta["overlay_stamp_ns"] == "2000"
    assert out[1][4 + size :] == bytes(_jpeg(2_000).data)
    assert "&lt;b&gt;&amp; 2000" in meta["svg"]  # the robot's text is escaped


def test_layers_can_be_hidden_and_pause_steps_through_the_frozen_buffer() -> None:
    clock = _Clock()
    model = _model(clock, buffer=5)
    stamps = [i * 1_000 for i in range(1, 9)]
    for stamp, drawing in zip(stamps, _drawings(stamps), strict=True):
        model.on_image(_jpeg(stamp))
        model.on_markers(drawing)
    assert model.layers() == ["choice", "internals"]
    shown = model.current()
    assert shown is not None
    assert "<circle" in model.overlay(shown[1]) and "<text" in model.overlay(shown[1])
    model.show_layer("internals", False)
    assert "<text" not in model.overlay(shown[1]) and "<circle" in model.overlay(shown[1])
    with pytest.raises(InvalidInput):
        model.show_layer("", True)

    model.pause()  # (no feeds to close here)
    assert model.position() == (4, 5)  # the newest of the 5 buffered frames
    model.on_image(_jpeg(99_000))  # arrives after the pause: not in the frozen buffer
    assert [f.stamp_ns for f in model.frames()] == stamps[-5:]
    assert (model.step(-2) or pytest.fail()).stamp_ns == 6_000
    assert (model.step(-10) or pytest.fail()).stamp_ns == 4_000  # clamped at the oldest
    shown = model.current()
    assert shown is not None and shown[1] is not None and shown[1].stamp_ns == 4_000
    assert (model.step(1) or pytest.fail()).stamp_ns == 5_000
    model.resume(shown=False)
    assert not model.paused and model.step(1) is None


def test_svg_of_every_kind_of_shape() -> None:
    from debug_probes import Shape

    svg = svg_overlay([
        Shape("a", "circle", ((1, 2),), (1, 0, 0, 1), 3, fill=(0, 1, 0, 0.5)),
        Shape("a", "points", ((1, 2), (3, 4)), (1, 1, 0, 1), 2),
        Shape("b", "lines", ((0, 0), (1, 1), (2, 2), (3, 3)), (0, 1, 1, 1), 1),
        Shape("b", "polyline", ((0, 0), (1, 1)), (0, 1, 1, 1), 1),
        Shape("c", "polygon", ((0, 0), (1, 1), (2, 0)), (0, 1, 1, 1), 1),
    ])
    assert svg.count("<circle") == 3 and svg.count("<line ") == 2
    assert "<polyline" in svg and "<polygon" in svg and 'fill="rgba(0,255,0,0.5)"' in svg


def test_against_a_robot_frames_match_drawings_quality_applies_and_hidden_costs_nothing(
    tmp_path: Path,
) -> None:
    domain = isolated_domain_id()
    with camera_robot(tmp_path, domain_id=domain, namespace="/robot") as proc, \
            Hub(domains=[domain]) as hub:
        bot = RobotId(domain, "/robot")
        wait_for(lambda: bot in hub.robots(), what="the robot", alive=[proc], timeout_s=60)
        model = ImageModel(hub, bot, rate_hz=10.0)
        model.activate()
        wait_for(lambda: model.received >= 5 and model.drawings_received >= 5,
                 what="frames and drawings", alive=[proc], timeout_s=60)
        # the robot limits what it sends
        assert all(isinstance(feed, Feed) and feed.throttled for feed in model._feeds)

        def matched() -> Any:
            shown = model.current()
            return shown if shown is not None and shown[1] is not None else None

        frame, drawing = wait_for(matched, what="a frame with its drawing", alive=[proc])
        assert drawing.stamp_ns == frame.stamp_ns
        assert {"choice", "internals", "candidates"} <= set(model.layers())
        image = cv2.imdecode(np.frombuffer(frame.jpeg, np.uint8), cv2.IMREAD_COLOR)
        assert image is not None and image.shape == (240, 320, 3)

        # JPEG quality: a parameter of the robot's compressor, set and read back.
        model.set_quality(95)
        assert model.quality() == 95
        seen = model.received
        wait_for(lambda: model.received >= seen + 5, what="frames at 95", alive=[proc])
        high = statistics.median(len(f.jpeg) for f in model.frames()[-4:])
        model.set_quality(10)
        seen = model.received
        wait_for(lambda: model.received >= seen + 5, what="frames at 10", alive=[proc])
        low = statistics.median(len(f.jpeg) for f in model.frames()[-4:])
        assert low < high / 2, (low, high)
        with pytest.raises(InvalidInput):
            model.set_quality(0)

        # Hidden: the feeds close, and the robot has no reader left to encode or draw for.
        with graph(domain) as node:
            wait_for(lambda: view_readers(node, bot) == 2, what="the view's two readers",
                     alive=[proc])
            model.deactivate()
            wait_for(lambda: view_readers(node, bot) == 0, what="no reader left", alive=[proc])
        assert not model.active


def view_readers(node: Any, bot: RobotId) -> int:
    """Readers of the image view's throttled replies (JPEG and drawings) on the robot."""
    prefixes = tuple(f"{bot.resolve(t)}/_throttle_" for t in (IMAGE_TOPIC, MARKERS_TOPIC))
    return sum(node.count_subscribers(name)
               for name, _types in node.get_topic_names_and_types()
               if name.startswith(prefixes))


@contextmanager
def graph(domain: int) -> Iterator[Any]:
    """A plain rclpy node on ``domain``, to look at the DDS graph as an outsider."""
    import rclpy
    from rclpy.context import Context

    context = Context()
    rclpy.init(context=context, domain_id=domain)
    try:
        yield rclpy.create_node("image_test_probe", context=context)
    finally:
        rclpy.shutdown(context=context)
