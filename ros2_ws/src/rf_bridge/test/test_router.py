"""The core on a TestHandle with a fake adapter: references, loops, throttling, stats."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from std_msgs.msg import String

from efficient_comm.testing import TestHandle, unique_topic
from rf_bridge import BridgeNode, parse_config
from rf_bridge.core.adapter import Deliver, Route


class FakeAdapter:
    name = "ros1"

    def __init__(self) -> None:
        self.sent: list[Any] = []
        self.deliver: Deliver | None = None
        self.routes: list[Route] = []

    def start(self, routes: Sequence[Route], deliver: Deliver) -> None:
        self.routes = list(routes)
        self.deliver = deliver

    def send(self, route: Route, msg: Any, received_ns: int) -> None:
        self.sent.append(msg)
        route.stats_out.delivered(1)

    def close(self) -> None:
        pass


def make(topics: list[dict[str, Any]], **extra: Any) -> tuple[TestHandle, BridgeNode, FakeAdapter]:
    fake = FakeAdapter()
    config = parse_config(
        {"ros1": {"master_uri": "http://127.0.0.1:1/"}, "topics": topics, **extra}
    )
    node = TestHandle("rf_bridge")
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


def test_a_bad_topic_entry_is_logged_and_the_rest_bridged() -> None:
    good = unique_topic()
    node, bridge, _ = make(
        [
            {"ros2": good, "type": "std_msgs/msg/String"},
            {"ros2": unique_topic(), "type": "nope_msgs/msg/Nothing"},
        ]
    )
    assert [r.spec.ros2_topic for r in bridge.routes] == [good]
    assert any("nope_msgs/msg/Nothing" in text for level, text in node.records if level == "error")


def test_statistics_are_logged_periodically() -> None:
    topic = unique_topic()
    node, _, _ = make(
        [{"ros2": topic, "type": "std_msgs/msg/String", "throttle": {"max_rate_hz": 0.5}}],
        stats_period_s=5.0,
    )
    node.inject(topic, String(data="a"), String(data="b"))
    assert not any("drops:" in text for _, text in node.records)
    node.advance(5.0)
    lines = [text for _, text in node.records if "drops:" in text]
    assert lines == [f"{topic} to_ros1: 1 msgs, 1 B; drops: throttled 1"]
