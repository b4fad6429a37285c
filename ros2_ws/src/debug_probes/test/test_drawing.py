"""DebugDrawing on a test container: drawn only while someone looks, stamped with the image."""

from __future__ import annotations

from typing import Any

import pytest

from debug_probes import GREEN, DebugDrawing, DrawingError, read_drawing
from efficient_comm import to_msg
from efficient_comm.testing import TestHandle, test_container
from throttle_publisher import ThrottledSubscription, ThrottleOptions


def _draw(drawing: DebugDrawing) -> bool:
    if not drawing.wants():
        return False
    drawing.circle("choice", 10.0, 20.0, 5.0, color=GREEN, fill=(0.0, 1.0, 0.0, 0.2))
    drawing.point("choice", 10.0, 20.0)
    drawing.line("lines", 0, 0, 10, 20)
    drawing.polyline("contours", [(1, 1), (5, 1), (5, 5)], closed=True)
    drawing.points("candidates", [(3, 4), (6, 7)], size=2.0)
    drawing.text("internals", 4, 12, "3 contours", size=9.0)
    drawing.publish(to_msg(5_000_000_123), frame_id="head_camera")
    return True


def test_nothing_is_drawn_while_nobody_subscribes_and_the_images_are_counted() -> None:
    node = TestHandle("detector")
    drawing = DebugDrawing(node, "debug_markers")
    assert [_draw(drawing) for _ in range(3)] == [False] * 3
    assert (drawing.published, drawing.skipped) == (0, 3)
    assert node.published("debug_markers") == []
    drawing.circle("choice", 1, 1, 1)  # a forgotten `if`: a no-op, nothing piles up
    assert drawing._markers == []


def test_a_drawing_round_trips_with_the_images_stamp_on_every_element() -> None:
    container = test_container()
    drawing = DebugDrawing(TestHandle("detector", container=container), "debug_markers")
    got: list[Any] = []
    TestHandle("viewer", container=container).create_subscription(
        _msg_type(), "debug_markers", got.append)
    assert _draw(drawing)
    (msg,) = got
    assert {m.header.stamp.sec for m in msg.markers} == {5}
    assert {m.header.stamp.nanosec for m in msg.markers} == {123}
    assert {m.header.frame_id for m in msg.markers} == {"head_camera"}
    read = read_drawing(msg)
    assert read.stamp_ns == 5_000_000_123 and read.frame_id == "head_camera"
    assert read.layers == ["choice", "lines", "contours", "candidates", "internals"]
    by_kind = {s.kind: s for s in read.shapes}
    assert by_kind["circle"].points == ((10.0, 20.0),) and by_kind["circle"].size == 5.0
    assert by_kind["circle"].fill == pytest.approx((0.0, 1.0, 0.0, 0.2))
    assert by_kind["polygon"].points == ((1.0, 1.0), (5.0, 1.0), (5.0, 5.0))
    assert by_kind["text"].text == "3 contours" and by_kind["text"].size == 9.0
    ids = [(m.ns, m.id) for m in msg.markers]
    assert ids == [("choice", 0), ("choice", 1), ("lines", 0), ("contours", 0),
                   ("candidates", 0)]  # unique (ns, id) per image, as viewers key them


def test_a_throttled_viewer_gets_its_rate_and_the_rest_is_skipped_not_drawn() -> None:
    container = test_container()
    drawing = DebugDrawing(TestHandle("detector", container=container), "debug_markers")
    got: list[Any] = []
    ThrottledSubscription(TestHandle("viewer", container=container), _msg_type(),
                          "/debug_markers", got.append, options=ThrottleOptions(every_nth=3))
    drawn = [_draw(drawing) for _ in range(9)]
    assert drawn.count(True) == 3 and len(got) == 3
    assert drawing.skipped == 6


def test_bad_elements_are_refused_with_what_is_wrong() -> None:
    container = test_container()
    drawing = DebugDrawing(TestHandle("detector", container=container), "debug_markers")
    TestHandle("viewer", container=container).create_subscription(
        _msg_type(), "debug_markers", lambda _m: None)
    assert drawing.wants()
    with pytest.raises(DrawingError, match="layer"):
        drawing.circle("", 1, 1, 1)
    with pytest.raises(DrawingError, match="finite"):
        drawing.point("p", float("nan"), 1)
    with pytest.raises(DrawingError, match="colour"):
        drawing.line("l", 0, 0, 1, 1, color=(2.0, 0.0, 0.0, 1.0))
    with pytest.raises(DrawingError, match="radius"):
        drawing.circle("c", 1, 1, -1)


def _msg_type() -> type:
    from efficient_comm_interfaces.msg import ImageMarkerArray

    return ImageMarkerArray  # type: ignore[no-any-return]
