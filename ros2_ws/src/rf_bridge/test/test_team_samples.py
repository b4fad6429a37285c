"""What the team adapter does with a received sample, without a Zenoh session: a sample is
counted (delivered, lost, malformed, oversize) and a compressed one cannot expand past the
configured limit."""

from __future__ import annotations

import zlib
from dataclasses import dataclass
from typing import Any

import pytest
import rclpy.logging
from rclpy.serialization import serialize_message
from std_msgs.msg import String

from rf_bridge import parse_config
from rf_bridge.adapters.team import _ATTACHMENT, _ZLIB, TeamAdapter
from rf_bridge.core.adapter import Route
from rf_bridge.core.stats import TopicStats
from rf_bridge.testing import CapturedLogs


@dataclass
class Bytes:
    data: bytes

    def to_bytes(self) -> bytes:
        return self.data


@dataclass
class Sample:
    payload: Bytes
    attachment: Bytes | None


def setup(limit: int) -> tuple[TeamAdapter, Route]:
    config = parse_config(
        {
            "team": {"robot_id": "b", "max_message_bytes": limit},
            "topics": [{"ros2": "/t", "type": "std_msgs/msg/String", "peer": "team"}],
        }
    )
    assert config.team is not None
    spec = config.topics[0]
    route = Route(spec, String, TopicStats("/t", "to_team"), TopicStats("/t", "from_team"))
    return TeamAdapter(config.team, rclpy.logging.get_logger("rf_bridge_test")), route


def sample(seq: int, payload: bytes, *, flags: int = 0) -> Sample:
    return Sample(Bytes(payload), Bytes(_ATTACHMENT.pack(seq, flags, 1) + b"a"))


def test_samples_counted_and_a_decompression_bomb_stopped_at_the_limit(
    capfd: pytest.CaptureFixture[str],
) -> None:
    records = CapturedLogs(capfd)
    adapter, route = setup(limit=4096)
    delivered: list[Any] = []

    def deliver(route: Route, msg: Any, received_ns: int, nbytes: int) -> None:
        delivered.append(msg)

    small = serialize_message(String(data="hello"))
    bomb = zlib.compress(bytes(64 << 20), 9)  # 64 MiB of zeros in about 64 KiB
    adapter._on_sample(route, sample(1, small), deliver)
    adapter._on_sample(route, sample(2, bomb, flags=_ZLIB), deliver)
    adapter._on_sample(route, sample(3, b"not zlib", flags=_ZLIB), deliver)
    adapter._on_sample(route, Sample(Bytes(small), None), deliver)
    adapter._on_sample(route, sample(6, small), deliver)
    assert [m.data for m in delivered] == ["hello", "hello"]
    assert route.stats_in.snapshot().drops == {"oversize": 1, "malformed": 2, "lost": 2}
    assert records.wait("over max_message_bytes (4096)")


def test_sender_table_is_bounded() -> None:
    from rf_bridge.adapters import team

    adapter, route = setup(limit=4096)
    small = serialize_message(String(data="x"))
    for robot in range(team._MAX_SENDERS + 10):
        attachment = _ATTACHMENT.pack(1, 0, 1) + f"robot{robot}".encode()
        adapter._on_sample(route, Sample(Bytes(small), Bytes(attachment)), lambda *a: None)
    assert len(adapter._last_seen) == team._MAX_SENDERS
