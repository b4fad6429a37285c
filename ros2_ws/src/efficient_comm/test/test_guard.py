"""The mutation guard names the callback that changed a shared message."""

from __future__ import annotations

import pytest
from std_msgs.msg import String

from efficient_comm import MessageMutatedError
from efficient_comm.testing import TestHandle, test_container


def _vandal(msg: String) -> None:
    msg.data = "changed"


def test_guard_names_the_mutating_subscriber() -> None:
    container = test_container(guard_mutation=True)
    node = TestHandle("vandal", container=container)
    node.create_subscription(String, "t", _vandal)
    node.create_publisher(String, "t").publish(String(data="orig"))
    (report,) = container.executor.mutations
    assert report.topic == "/t" and "/vandal" in report.culprit


def test_guard_in_raise_mode_fails_the_test() -> None:
    node = TestHandle("vandal")  # test handles raise by default
    node.create_subscription(String, "t", _vandal)
    with pytest.raises(MessageMutatedError, match="/vandal"):
        node.create_publisher(String, "t").publish(String(data="orig"))


def test_guard_catches_a_publisher_that_modifies_after_publishing() -> None:
    container = test_container(strategy="breadth_first", guard_mutation=True)
    node = TestHandle("sloppy", container=container)
    node.create_subscription(String, "t", lambda m: None)
    msg = String(data="v1")
    node.create_publisher(String, "t").publish(msg)
    msg.data = "v2"  # while still queued for the subscriber
    node.spin_some()
    (report,) = container.executor.mutations
    assert "publisher /sloppy" in report.culprit


def test_readers_that_do_not_mutate_pass() -> None:
    node = TestHandle()
    node.create_subscription(String, "t", lambda m: m.data.upper())
    node.create_publisher(String, "t").publish(String(data="fine"))
    assert node.container.executor.mutations == []


def test_raise_mode_blames_the_mutator_not_its_upstream_and_delivers_to_the_rest() -> None:
    container = test_container()  # raise mode
    relay = TestHandle("relay", container=container)
    out = relay.create_publisher(String, "mid")
    relay.create_subscription(String, "in", lambda m: out.publish(String(data=m.data)))
    vandal = TestHandle("vandal", container=container)
    vandal.create_subscription(String, "mid", _vandal)
    bystander: list[str] = []
    TestHandle("bystander", container=container).create_subscription(
        String, "mid", lambda m: bystander.append(m.data)
    )
    with pytest.raises(MessageMutatedError, match="/vandal"):
        relay.inject("in", String(data="x"))
    assert len(bystander) == 1  # the others still got the message
    assert all(s.exceptions == 0 for s in container.stats())  # nobody else was charged


def test_breadth_first_reports_only_the_subscriber_that_changed_it() -> None:
    container = test_container(strategy="breadth_first", guard_mutation=True)
    node = TestHandle("vandal", container=container)
    node.create_subscription(String, "t", _vandal)
    node.create_subscription(String, "t", lambda m: None)
    node.create_publisher(String, "t").publish(String(data="orig"))
    node.spin_some()
    assert [r.culprit.split()[0:2] for r in container.executor.mutations] == [
        ["subscriber", "/vandal"]
    ]


def test_fingerprints_are_stable_for_unchanged_messages_and_see_deep_changes() -> None:
    from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
    from sensor_msgs.msg import Image

    from efficient_comm.guard import fingerprint

    array_msg = DiagnosticArray(status=[
        DiagnosticStatus(name=f"servo {i}", level=DiagnosticStatus.OK,
                         values=[KeyValue(key="k", value=str(i))]) for i in range(20)
    ])
    before = fingerprint(array_msg)
    assert all(fingerprint(array_msg) == before for _ in range(100))
    array_msg.status[7].values[0].value = "changed"
    assert fingerprint(array_msg) != before
    image = Image(data=bytes(1000))
    before = fingerprint(image)
    image.data[500] = 1
    assert fingerprint(image) != before
