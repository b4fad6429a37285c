"""The core on a TestHandle (a real rclpy node, so its real logger) with a fake adapter:
references, loops, throttling, stats; and which topics count as bridged."""

from __future__ import annotations

import contextlib
from collections.abc import Iterator, Sequence
from typing import Any

import pytest
from std_msgs.msg import String

from efficient_comm.testing import TestHandle, unique_topic
from rf_bridge import BridgeNode, parse_config
from rf_bridge.core.adapter import Deliver, Route
from rf_bridge.testing import CapturedLogs, rclpy_test_handle


class FakeAdapter:
    name = "ros1"

    def __init__(self) -> None:
        self.sent: list[Any] = []
        self.deliver: Deliver | None = None
        self.routes: list[Route] = []

    def start(self, routes: Sequence[Route], deliver: Deliver) -> Sequence[Route]:
        self.routes = list(routes)
        self.deliver = deliver
        return routes

    def send(self, route: Route, msg: Any, received_ns: int) -> None:
        self.sent.append(msg)
        route.stats_out.delivered(1)

    def close(self) -> None:
        pass


_handles: list[TestHandle] = []


@pytest.fixture(autouse=True)
def _rclpy_nodes() -> Iterator[None]:
    """Every handle :func:`make` gives is a real rclpy node, closed after the test."""
    with contextlib.ExitStack() as stack:
        _handles.append(stack.enter_context(rclpy_test_handle()))
        yield
        _handles.clear()


def make(topics: list[dict[str, Any]], **extra: Any) -> tuple[TestHandle, BridgeNode, FakeAdapter]:
    fake = FakeAdapter()
    config = parse_config(
        {"ros1": {"master_uri": "http://127.0.0.1:1/"}, "topics": topics, **extra}
    )
    node = _handles[0]
    return node, BridgeNode(node, config=config, adapters={"ros1": fake}), fake


def test_ros2_side_passes_references() -> None:
    topic = unique_topic()
    node, _, fake = make([{"ros2": topic, "type": "std_msgs/msg/String"}])
    msg = String(data="by reference")
    node.inject(topic, msg)
    assert fake.sent[0] is msg


def test_a_both_route_never_loops() -> None:
    topic = unique_topic()
    node, bridge, fake = make([{"ros2": topic, "type": "std_msgs/msg/String", "direction": "both"}])
    assert fake.deliver is not None
    incoming = String(data="from ROS 1")
    fake.deliver(fake.routes[0], incoming, 0, 10)
    node.spin_some()
    assert node.published(topic) == [incoming]  # reached ROS 2 ...
    assert fake.sent == []  # ... and did not go back out
    assert bridge.router.loops_suppressed == 1
    node.inject(topic, String(data="from ROS 2"))
    assert [m.data for m in fake.sent] == ["from ROS 2"]


def test_local_throttle_counts_what_it_holds_back() -> None:
    topic = unique_topic()
    node, bridge, fake = make(
        [{"ros2": topic, "type": "std_msgs/msg/String", "throttle": {"max_rate_hz": 0.5}}]
    )
    for i in range(10):
        node.inject(topic, String(data=str(i)))
    assert [m.data for m in fake.sent] == ["0"]
    snap = next(s for s in bridge.stats() if s.direction == "to_ros1")
    assert snap.drops == {"throttled": 9} and snap.messages == 1


def test_a_bad_topic_entry_is_logged_and_the_rest_bridged(
    capfd: pytest.CaptureFixture[str],
) -> None:
    good = unique_topic()
    _node, bridge, _ = make(
        [
            {"ros2": good, "type": "std_msgs/msg/String"},
            {"ros2": unique_topic(), "type": "nope_msgs/msg/Nothing"},
        ]
    )
    assert [r.spec.ros2_topic for r in bridge.routes] == [good]
    logs = CapturedLogs(capfd)
    assert logs.wait("nope_msgs/msg/Nothing")
    assert next(line for line in logs.text().splitlines() if "nope_msgs" in line).startswith(
        "[ERROR]"
    )
    assert logs.wait("1 topic(s) bridged with ['ros1']; 1 not bridged")


def test_statistics_are_logged_periodically(capfd: pytest.CaptureFixture[str]) -> None:
    topic = unique_topic()
    node, _, _ = make(
        [{"ros2": topic, "type": "std_msgs/msg/String", "throttle": {"max_rate_hz": 0.5}}],
        stats_period_s=5.0,
    )
    logs = CapturedLogs(capfd)
    node.inject(topic, String(data="a"), String(data="b"))
    assert "drops:" not in logs.text()
    node.advance(5.0)
    lines = [line for line in logs.text().splitlines() if "drops:" in line]
    assert len(lines) == 1
    assert lines[0].endswith(f"{topic} to_ros1: 1 msgs, 1 B; drops: throttled 1")


SIGHTING_RULE = {
    "ros1": "lab_msgs/Sighting",
    "ros2": "geometry_msgs/msg/Vector3",
    "fields": {"x": "distance", "y": "bearing"},
    "ros1_definition": "float64 distance\nfloat64 bearing",
}


def real_ros1(topics: list[dict[str, Any]], rules: list[dict[str, Any]]) -> BridgeNode:
    """A bridge with the real ROS 1 adapter (no master needed to start it)."""
    config = parse_config(
        {"ros1": {"master_uri": "http://127.0.0.1:1/"}, "topics": topics, "types": rules}
    )
    return BridgeNode(_handles[0], config=config)


def test_a_type_rule_applies_only_to_the_topics_naming_its_type() -> None:
    named, other = unique_topic("sightings"), unique_topic("vector")
    bridge = real_ros1(
        [
            {"ros2": named, "type": "geometry_msgs/msg/Vector3", "peer_type": "lab_msgs/Sighting"},
            {"ros2": other, "type": "geometry_msgs/msg/Vector3"},
        ],
        [SIGHTING_RULE],
    )
    try:
        pubs: Any = bridge.adapters["ros1"]._pubs  # type: ignore[attr-defined]
        assert pubs[named].ros1_type == "lab_msgs/Sighting"
        assert pubs[other].ros1_type == "geometry_msgs/Vector3"
        assert pubs[other].md5sum == "4a842b65f413084dc2b10fb484ea7f17"  # ROS 1's Vector3
    finally:
        bridge.close()


def test_a_topic_the_ros1_side_refuses_is_not_counted_as_bridged(
    capfd: pytest.CaptureFixture[str],
) -> None:
    good, refused = unique_topic("good"), unique_topic("refused")
    bad_rule = {**SIGHTING_RULE, "ros1": "lab_msgs/Label", "ros1_definition": "string distance"}
    bridge = real_ros1(
        [
            {"ros2": good, "type": "std_msgs/msg/String"},
            {"ros2": refused, "type": "geometry_msgs/msg/Vector3", "peer_type": "lab_msgs/Label"},
        ],
        [bad_rule],
    )
    try:
        logs = CapturedLogs(capfd)
        assert logs.wait(f"topic {refused} not bridged")
        assert logs.wait("1 topic(s) bridged with ['ros1']; 1 not bridged")
        assert [r.spec.ros2_topic for r in bridge.routes] == [good]
        assert [s.topic for s in bridge.stats()] == [good]
        assert _handles[0].rclpy_node is not None
        assert refused not in dict(_handles[0].rclpy_node.get_topic_names_and_types())
    finally:
        bridge.close()


class EagerAdapter(FakeAdapter):
    """A peer that sends at once: a sample arrives while the adapter is still starting
    (the team link's subscribers are live as soon as they are declared)."""

    def start(self, routes: Sequence[Route], deliver: Deliver) -> Sequence[Route]:
        for route in routes:
            deliver(route, String(data="early"), 0, 5)
        return super().start(routes, deliver)


def test_samples_arriving_while_the_adapters_start_are_published() -> None:
    topic = unique_topic()
    config = parse_config(
        {
            "ros1": {"master_uri": "http://127.0.0.1:1/"},
            "topics": [{"ros2": topic, "type": "std_msgs/msg/String", "direction": "from_peer"}],
        }
    )
    node = _handles[0]
    bridge = BridgeNode(node, config=config, adapters={"ros1": EagerAdapter()})
    node.spin_some()
    assert [m.data for m in node.published(topic)] == ["early"]
    assert bridge.stats()[0].messages == 1
