"""In-process delivery follows DDS QoS rules: compatibility, durability, types."""

from __future__ import annotations

import pytest
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import Int32, String

from efficient_comm import NameResolutionError, TopicTypeError, matching_qos
from efficient_comm.testing import TestHandle, test_container

BEST_EFFORT = QoSProfile(depth=10, reliability=ReliabilityPolicy.BEST_EFFORT)
LATCHED = QoSProfile(depth=2, durability=DurabilityPolicy.TRANSIENT_LOCAL)


def test_reliable_subscriber_does_not_hear_best_effort_publisher() -> None:
    node = TestHandle()
    reliable: list[String] = []
    best_effort: list[String] = []
    node.create_subscription(String, "t", reliable.append, qos=10)
    node.create_subscription(String, "t", best_effort.append, qos=BEST_EFFORT)
    node.create_publisher(String, "t", qos=BEST_EFFORT).publish(String())
    assert len(reliable) == 0 and len(best_effort) == 1


def test_transient_local_replays_last_depth_messages_to_late_joiners_only() -> None:
    node = TestHandle()
    pub = node.create_publisher(String, "map", qos=LATCHED)
    for i in range(3):
        pub.publish(String(data=str(i)))
    late: list[str] = []
    volatile_late: list[str] = []
    node.create_subscription(String, "map", lambda m: late.append(m.data), qos=LATCHED)
    node.create_subscription(String, "map", lambda m: volatile_late.append(m.data))
    node.spin_some()
    assert late == ["1", "2"] and volatile_late == []


def test_volatile_publisher_cannot_serve_transient_local_subscriber() -> None:
    node = TestHandle()
    got: list[String] = []
    node.create_subscription(String, "t", got.append, qos=LATCHED)
    node.create_publisher(String, "t").publish(String())
    assert got == []


def test_one_topic_one_type() -> None:
    node = TestHandle()
    node.create_publisher(String, "t")
    with pytest.raises(TopicTypeError, match="std_msgs/msg/String"):
        node.create_subscription(Int32, "t", lambda m: None)


def test_publishing_the_wrong_type_raises() -> None:
    node = TestHandle()
    with pytest.raises(TypeError):
        node.create_publisher(String, "t").publish(Int32())


@pytest.mark.parametrize("bad", ["with space", "1starts_with_digit", "double//slash", ""])
def test_invalid_topic_names_are_rejected(bad: str) -> None:
    with pytest.raises(NameResolutionError):
        TestHandle().create_publisher(String, bad)


def test_private_and_relative_names_resolve_like_rcl() -> None:
    node = TestHandle("cam", namespace="/robot", remappings={"~/raw": "/sensors/raw"})
    assert node.create_publisher(String, "image").topic_name == "/robot/image"
    assert node.create_publisher(String, "~/info").topic_name == "/robot/cam/info"
    assert node.create_publisher(String, "~/raw").topic_name == "/sensors/raw"


def test_unloading_removes_endpoints() -> None:
    node = TestHandle("a")
    other = TestHandle("b", container=node.container)
    got: list[String] = []
    other.create_subscription(String, "t", got.append)
    pub = node.create_publisher(String, "t")
    other.close()
    pub.publish(String())
    assert got == []


def test_remap_rules_follow_rcl() -> None:
    from efficient_comm.testing import test_container

    container = test_container()
    rules = ["out:=/first", "out:=/second", "other:out:=/not_mine", "cam:info:=/mine"]
    from efficient_comm._names import parse_remaps

    node = TestHandle("cam", container=container, remappings=parse_remaps(rules))
    assert node.create_publisher(String, "out").topic_name == "/first"  # first rule wins
    assert node.create_publisher(String, "info").topic_name == "/mine"


def test_node_name_and_namespace_remaps_apply_in_containers() -> None:
    from efficient_comm.testing import test_container

    container = test_container()
    container.add(
        lambda n: None, name="cam", remappings=["__node:=front", "__ns:=/robot"]
    )
    assert [c.full_node_name for c in container.components()] == ["/robot/front"]


def test_published_refuses_topics_it_does_not_record() -> None:
    node = TestHandle()
    with pytest.raises(LookupError):
        node.published("never_published")


def test_publisher_qos_lists_the_offered_profiles_of_a_topic() -> None:
    node = TestHandle()
    bus = node.container.bus
    assert bus.publisher_qos("/q") == []
    node.create_publisher(String, "/q", qos=BEST_EFFORT)
    node.create_publisher(String, "/q", qos=LATCHED)
    node.create_subscription(String, "/q", lambda _: None)  # subscriptions offer nothing
    offered = bus.publisher_qos("/q")
    assert [q.reliability for q in offered] == [ReliabilityPolicy.BEST_EFFORT,
                                                ReliabilityPolicy.RELIABLE]
    assert offered[1].durability == DurabilityPolicy.TRANSIENT_LOCAL


def test_incompatible_qos_in_process_is_warned_once_on_both_sides() -> None:
    """DDS warns of an incompatible endpoint; in-process endpoints must not fail silently."""
    container = test_container()
    camera = TestHandle("camera", container=container)
    viewer = TestHandle("viewer", container=container)
    pub = camera.create_publisher(
        String, "/image", qos=QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT)
    )
    heard: list[String] = []
    viewer.create_subscription(String, "/image", heard.append, qos=10)  # reliable
    for _ in range(3):
        pub.publish(String(data="frame"))
    camera.create_publisher(String, "/other", qos=10)  # rewiring elsewhere warns nothing new
    assert heard == []

    def warnings(node: TestHandle) -> list[str]:
        return [m for level, m in node.records if level == "warning"]

    (heard_of,) = warnings(viewer)
    assert "/camera" in heard_of and "'/image'" in heard_of and "RELIABILITY" in heard_of
    (told,) = warnings(camera)
    assert "/viewer" in told and "RELIABILITY" in told
    viewer.create_subscription(
        String, "/image", heard.append,
        qos=QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL,
                       reliability=ReliabilityPolicy.BEST_EFFORT),
    )
    assert "DURABILITY" in warnings(viewer)[-1] and len(warnings(viewer)) == 2


def test_matching_qos_receives_from_what_publishers_offer() -> None:
    latched = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
    sensor = QoSProfile(depth=5, reliability=ReliabilityPolicy.BEST_EFFORT)
    nobody = matching_qos([])
    assert (nobody.reliability, nobody.durability) == (
        ReliabilityPolicy.RELIABLE, DurabilityPolicy.VOLATILE)
    assert matching_qos([latched, latched]).durability == DurabilityPolicy.TRANSIENT_LOCAL
    mixed = matching_qos([latched, sensor], depth=3)
    assert (mixed.reliability, mixed.durability, mixed.depth) == (
        ReliabilityPolicy.BEST_EFFORT, DurabilityPolicy.VOLATILE, 3)
