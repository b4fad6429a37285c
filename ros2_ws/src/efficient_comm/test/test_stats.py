"""Callback statistics as users read them."""

from __future__ import annotations

from std_msgs.msg import String

from efficient_comm import format_stats
from efficient_comm.testing import TestHandle

LONG = "/robot/head/camera/image_raw/compressed_for_the_operator"


def test_the_stats_table_shows_whole_node_and_topic_names() -> None:
    node = TestHandle("a_detector_with_a_long_name", namespace="/robot/head")
    node.create_subscription(String, LONG, lambda _msg: None)
    node.inject(LONG, String(), String())
    table = format_stats(node.container.stats())
    header, row = table.splitlines()[0], table.splitlines()[-1]
    assert header.split()[:3] == ["node", "kind", "name"]
    assert row.split()[:4] == ["/robot/head/a_detector_with_a_long_name", "subscription", LONG, "2"]
