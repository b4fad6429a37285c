"""Foxglove channels follow the robots' topics without churn: a topic missing from one
graph scan keeps its channel (and id); a topic gone for longer, or a robot gone, loses it."""

from __future__ import annotations

from typing import Any

import foxglove
import pytest

from debug_gui import RobotId
from debug_gui import foxglove as fox


class FlickeringHub:
    """The two methods of the Hub that the bridge's sync reads; the test sets the graph."""

    def __init__(self, robot: RobotId) -> None:
        self.robot = robot
        self.present = True
        self.topics_now = {"/alpha/chatter": ["std_msgs/msg/String"]}

    def robots(self) -> list[RobotId]:
        return [self.robot] if self.present else []

    def topics(self, robot: RobotId) -> dict[str, list[str]]:
        return dict(self.topics_now)

    def services(self, robot: RobotId) -> dict[str, list[str]]:
        return {}


def _channel_ids(bridge: Any) -> list[int]:
    return sorted(entry.channel.id() for entry in bridge._by_topic.values())


def test_a_topic_missing_for_one_scan_keeps_its_channel(
        monkeypatch: pytest.MonkeyPatch) -> None:
    clock = [100.0]
    monkeypatch.setattr("debug_gui.foxglove.time.monotonic", lambda: clock[0])
    hub = FlickeringHub(RobotId(7, "/alpha"))
    bridge = fox._Bridge(hub, foxglove.Context(), fox._Naming([7]))  # type: ignore[arg-type]
    bridge.sync()
    (first,) = _channel_ids(bridge)
    hub.topics_now = {}  # one scan without the topic
    clock[0] += 0.2
    bridge.sync()
    assert _channel_ids(bridge) == [first]
    hub.topics_now = {"/alpha/chatter": ["std_msgs/msg/String"]}  # back: same channel
    clock[0] += 0.2
    bridge.sync()
    assert _channel_ids(bridge) == [first]
    hub.topics_now = {}  # gone for good: withdrawn once the grace period passed
    clock[0] += 0.2
    bridge.sync()
    assert _channel_ids(bridge) == [first]
    clock[0] += fox.WITHDRAW_AFTER_S
    bridge.sync()
    assert _channel_ids(bridge) == []


def test_a_robot_gone_loses_its_channels_at_once(monkeypatch: pytest.MonkeyPatch) -> None:
    clock = [100.0]
    monkeypatch.setattr("debug_gui.foxglove.time.monotonic", lambda: clock[0])
    hub = FlickeringHub(RobotId(7, "/alpha"))
    bridge = fox._Bridge(hub, foxglove.Context(), fox._Naming([7]))  # type: ignore[arg-type]
    bridge.sync()
    assert len(_channel_ids(bridge)) == 1
    hub.present = False
    clock[0] += 0.2
    bridge.sync()
    assert _channel_ids(bridge) == []
