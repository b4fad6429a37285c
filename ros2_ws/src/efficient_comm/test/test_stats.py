"""Callback statistics as users read them."""

from __future__ import annotations

import math

import pytest
from std_msgs.msg import String

from efficient_comm import ConfigError, format_stats
from efficient_comm.stats import RECENT, StatsRegistry, StatsWindow
from efficient_comm.testing import TestHandle, test_container
from efficient_comm_interfaces.msg import ExecutorStats

LONG = "/robot/head/camera/image_raw/compressed_for_the_operator"


def test_the_stats_table_shows_whole_node_and_topic_names() -> None:
    node = TestHandle("a_detector_with_a_long_name", namespace="/robot/head")
    node.create_subscription(String, LONG, lambda _msg: None)
    node.inject(LONG, String(), String())
    table = format_stats(node.container.stats())
    header, row = table.splitlines()[0], table.splitlines()[-1]
    assert header.split()[:3] == ["node", "kind", "name"]
    assert row.split()[:4] == ["/robot/head/a_detector_with_a_long_name", "subscription", LONG, "2"]


def test_windowed_figures_rate_mean_p95_and_max_cover_only_the_last_window() -> None:
    registry = StatsRegistry()
    entry = registry.add("/n", "timer", "tick", period_ns=10_000_000)
    window = StatsWindow(registry, now_ns=0)
    for i in range(1, 101):  # 1 .. 100 µs: nearest-rank p95 is 95 µs
        entry.record(i * 10_000_000, i * 1_000)
    window_ns, (row,) = window.take(1_000_000_000)
    assert window_ns == 1_000_000_000
    assert (row.calls, row.rate_hz, row.period_ns) == (100, 100.0, 10_000_000)
    assert (row.mean_ns, row.p95_ns, row.max_ns) == (50_500, 95_000, 100_000)
    # The next window holds two short calls only: the long ones of before do not count.
    entry.record(1_100_000_000, 7_000)
    entry.record(1_200_000_000, 3_000)
    window_ns, (row,) = window.take(1_500_000_000)
    assert window_ns == 500_000_000
    assert (row.calls, row.rate_hz) == (102, 4.0)
    assert (row.mean_ns, row.p95_ns, row.max_ns) == (5_000, 7_000, 7_000)
    assert entry.max_ns == 100_000  # the all-time max stays
    _, (row,) = window.take(2_000_000_000)  # a window without calls
    assert (row.rate_hz, row.mean_ns, row.p95_ns, row.max_ns) == (0.0, 0, 0, 0)


def test_p95_of_a_window_longer_than_the_ring_uses_the_most_recent_calls() -> None:
    registry = StatsRegistry()
    entry = registry.add("/n", "subscription", "/t")
    window = StatsWindow(registry, now_ns=0)
    for i in range(RECENT * 3):  # old calls slow, the last RECENT ones 1 µs .. RECENT µs
        entry.record(i, 1_000_000 if i < RECENT * 2 else (i - RECENT * 2 + 1) * 1_000)
    _, (row,) = window.take(1_000_000_000)
    assert row.p95_ns == math.ceil(0.95 * RECENT) * 1_000
    assert row.max_ns == 1_000_000  # max is exact over the whole window


def test_a_container_without_stats_has_no_stats_topic_and_a_bad_period_is_refused() -> None:
    container = test_container(stats_period_s=0)
    assert container.stats_publisher is None
    assert container.executor.next_timer_due_ns() is None
    container.close()
    with pytest.raises(ConfigError, match="stats_period_s"):
        test_container(stats_period_s=-1.0)
    with pytest.raises(ConfigError, match="namespace"):
        test_container(stats_namespace="not a namespace")


def test_in_process_listeners_get_snapshots_from_the_container_they_live_in() -> None:
    container = test_container(stats_period_s=0.5, stats_namespace="/robot2")
    node = TestHandle("watcher", container=container)
    node.advance(2.0)
    assert container.stats_publisher is not None
    assert container.stats_publisher.published == 0
    got: list[ExecutorStats] = []
    node.create_subscription(ExecutorStats, "/robot2/efficient_comm/stats", got.append)
    node.advance(1.0)
    assert len(got) == 2 and got[0].window_ns == 2_500_000_000  # the first covers the pause
    assert got[1].window_ns == 500_000_000 and got[1].stamp.sec == 3
    assert {c.node for c in got[1].callbacks} == {"/watcher", f"/robot2/{container.name}_stats"}
