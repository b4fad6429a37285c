"""The team link's byte budget and its usage counter, without a Zenoh session: what does
not fit the budget is not sent and is counted, what is sent never exceeds ``burst + rate ·
t``, and the bridge reports the usage on /diagnostics."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import pytest
import rclpy.logging
from diagnostic_msgs.msg import DiagnosticArray
from std_msgs.msg import String

from efficient_comm.testing import TestHandle, unique_topic
from rf_bridge import BridgeNode, ConfigError, LinkUsage, parse_config
from rf_bridge.adapters.team import _ATTACHMENT, TeamAdapter
from rf_bridge.core.adapter import Deliver, Route
from rf_bridge.core.budget import ByteBudget
from rf_bridge.core.stats import TopicStats


class FakeClock:
    def __init__(self) -> None:
        self.ns = 1_000_000_000

    def __call__(self) -> int:
        return self.ns


def test_the_token_bucket_allows_the_burst_then_the_rate() -> None:
    clock = FakeClock()
    budget = ByteBudget(1000.0, 300, now_ns=clock)
    assert budget.take(200) and budget.take(100)
    assert not budget.take(1)  # the burst is spent
    clock.ns += 100_000_000  # 0.1 s: 100 bytes
    assert not budget.take(101)  # nothing spent by a refusal ...
    assert budget.take(100)  # ... so what fits still goes
    clock.ns += 10_000_000_000
    assert budget.take(300) and not budget.take(1)  # refilled up to the burst, no more
    with pytest.raises(ValueError):
        ByteBudget(0.0, 10, now_ns=clock)


@dataclass
class Matching:
    matching: bool = True


@dataclass
class FakePublisher:
    """What the adapter needs of a Zenoh publisher: matching status and put."""

    matching_status: Matching = field(default_factory=Matching)
    puts: list[tuple[bytes, bytes]] = field(default_factory=list)

    def put(self, payload: bytes, *, attachment: bytes) -> None:
        self.puts.append((payload, attachment))


def _adapter(clock: FakeClock, **team: Any) -> tuple[TeamAdapter, Route, FakePublisher]:
    config = parse_config({
        "team": {"robot_id": "blue1", "compression": "none", **team},
        "topics": [{"ros2": "/t", "type": "std_msgs/msg/String", "peer": "team"}],
    })
    assert config.team is not None
    route = Route(config.topics[0], String, TopicStats("/t", "to_team"),
                  TopicStats("/t", "from_team"))
    adapter = TeamAdapter(config.team, rclpy.logging.get_logger("rf_bridge_test"), now_ns=clock)
    pub = FakePublisher()
    adapter._pubs[id(route)] = pub  # as start() would, without a session
    adapter._seq[id(route)] = 0
    return adapter, route, pub


def test_what_does_not_fit_the_budget_is_dropped_and_counted() -> None:
    clock = FakeClock()
    adapter, route, pub = _adapter(clock, budget_bytes_per_s=1000, budget_burst_bytes=500)
    msg = String(data="x" * 100)
    sent_at: list[int] = []
    for _ in range(200):  # 100 Hz for 2 s: about 6 times the budget
        before = len(pub.puts)
        adapter.send(route, msg, 0)
        if len(pub.puts) > before:
            sent_at.append(clock.ns)
        clock.ns += 10_000_000
    usage = adapter.usage()
    wire = [len(p) + len(a) for p, a in pub.puts]
    assert usage.sent_bytes == sum(wire) and usage.sent_messages == len(pub.puts)
    assert usage.sent_bytes <= 500 + 1000 * 2.0  # burst + rate · t
    assert usage.sent_bytes >= 1000 * 2.0 - max(wire)  # and the budget is used
    assert usage.over_budget == 200 - len(pub.puts) > 100
    assert route.stats_out.snapshot().drops == {"over_budget": usage.over_budget}
    assert usage.peak_bytes_per_s <= 500 + 1000
    assert (usage.budget_bytes_per_s, usage.budget_burst_bytes) == (1000.0, 500)
    assert usage.sent_bytes_per_s == pytest.approx(usage.sent_bytes / 2.0)
    # the wire size: CDR payload, the attachment (sequence, flags, boot) and the robot id
    assert wire[0] == len(pub.puts[0][0]) + _ATTACHMENT.size + len("blue1")
    # a drop uses no sequence number: the receiver sees no gap, so counts no loss
    seqs = [_ATTACHMENT.unpack_from(a)[0] for _, a in pub.puts]
    assert seqs == list(range(1, len(pub.puts) + 1))


def test_without_a_budget_everything_goes_and_is_still_measured() -> None:
    clock = FakeClock()
    adapter, route, _ = _adapter(clock)
    for _ in range(50):
        adapter.send(route, String(data="y" * 10), 0)
    clock.ns += 2_000_000_000
    usage = adapter.usage()
    assert usage.sent_messages == 50 and usage.over_budget == 0
    assert usage.budget_bytes_per_s is None
    assert usage.sent_bytes_per_s == pytest.approx(usage.sent_bytes / 2.0)


@pytest.mark.parametrize("key, value", [("budget_bytes_per_s", -1), ("budget_burst_bytes", 1.5),
                                        ("budget_bytes_per_s", "fast")])
def test_a_wrong_budget_names_the_entry(key: str, value: Any) -> None:
    with pytest.raises(ConfigError, match=f"team.{key}"):
        parse_config({"team": {"robot_id": "a", key: value}})


class UsageAdapter:
    """A team adapter stand-in that reports usage."""

    name = "team"

    def start(self, routes: Sequence[Route], deliver: Deliver) -> Sequence[Route]:
        return routes

    def send(self, route: Route, msg: Any, received_ns: int) -> None:
        pass

    def close(self) -> None:
        pass

    def usage(self) -> LinkUsage:
        return LinkUsage(link="team", robot_id="red2", sent_messages=20, sent_bytes=1580,
                         received_messages=40, received_bytes=3160, over_budget=3,
                         elapsed_s=10.0, budget_bytes_per_s=2048.0, budget_burst_bytes=2048,
                         peak_bytes_per_s=237)


def test_the_bridge_reports_the_link_usage_on_diagnostics() -> None:
    node = TestHandle("bridge")
    topic = unique_topic()
    config = parse_config({"team": {"robot_id": "red2"}, "usage_period_s": 1.0,
                           "topics": [{"ros2": topic, "type": "std_msgs/msg/String",
                                       "peer": "team"}]})
    bridge = BridgeNode(node, config=config, adapters={"team": UsageAdapter()})
    assert [u.robot_id for u in bridge.link_usage()] == ["red2"]
    node.advance(2.0)
    arrays: list[DiagnosticArray] = node.published("/diagnostics")
    assert len(arrays) == 2
    (status,) = arrays[-1].status
    values = {kv.key: kv.value for kv in status.values}
    assert (status.name, status.hardware_id) == ("rf_bridge: team link", "red2")
    assert values["sent_bytes_per_s"] == "158.0" and values["over_budget"] == "3"
    assert values["budget_bytes_per_s"] == "2048.0" and values["peak_bytes_per_s"] == "237"
    assert "over budget" in status.message
