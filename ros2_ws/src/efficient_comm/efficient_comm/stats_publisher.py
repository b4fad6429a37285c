"""The callback statistics on a topic, for tools outside the process (the debug GUI).

Every container and every standalone node runs a :class:`StatsPublisher`: every
``period_s`` it publishes an ``efficient_comm_interfaces/ExecutorStats`` on
``<namespace>/efficient_comm/stats`` (:data:`STATS_TOPIC`, relative to the handle's
namespace), but only while someone subscribes, in this process or over DDS. A process
nobody watches pays one subscription-count test per period, nothing else: the snapshot,
its windowed figures (:class:`~efficient_comm.stats.StatsWindow`) and the message are
computed only for a listener. A debugging tool finds robots by this topic: a robot is a
(DDS domain, namespace) pair where it exists.

It is written against the node handle like any component, so it behaves the same on every
backend (composed with or without DDS, standalone, :class:`~efficient_comm.testing.TestHandle`).
"""

from __future__ import annotations

import os
import socket

from efficient_comm_interfaces.msg import CallbackStats as CallbackStatsMsg
from efficient_comm_interfaces.msg import ExecutorStats

from ._clock import to_msg
from .handle import NodeHandle
from .stats import StatsRegistry, StatsWindow

#: The topic, relative to the publishing handle's namespace.
STATS_TOPIC = "efficient_comm/stats"
#: Default publishing period (seconds) of containers and standalone nodes.
DEFAULT_STATS_PERIOD_S = 1.0


def check_stats_period(period_s: float) -> float:
    """``period_s`` as a float if it is >= 0 (0 disables the topic); ValueError otherwise."""
    if isinstance(period_s, bool) or not isinstance(period_s, int | float) or not period_s >= 0:
        raise ValueError(f"stats_period_s must be a number >= 0 (0 disables), got {period_s!r}")
    return float(period_s)


class StatsPublisher:
    """Publishes ``registry``'s callbacks every ``period_s`` while someone subscribes.

    Create it in the thread that runs the callbacks (it reads the live counters there).
    Its own timer is one of the registry's callbacks, so the cost of being watched shows
    in the figures it publishes.
    """

    def __init__(
        self,
        node: NodeHandle,
        *,
        registry: StatsRegistry,
        period_s: float = DEFAULT_STATS_PERIOD_S,
        process_name: str,
    ) -> None:
        period_s = check_stats_period(period_s)
        if period_s == 0:
            raise ValueError("a StatsPublisher needs a period > 0 (0 means: create none)")
        self._node = node
        self._process_name = process_name
        self._hostname = socket.gethostname()
        self._pid = os.getpid()
        self._window = StatsWindow(registry, now_ns=node.clock.now_ns())
        self.publisher = node.create_publisher(ExecutorStats, STATS_TOPIC, qos=1)
        self.topic = node.resolve_topic_name(STATS_TOPIC)
        self.published = 0
        node.create_timer(period_s, self._tick)

    def _tick(self) -> None:
        if self.publisher.get_subscription_count():
            self.publisher.publish(self.snapshot())
            self.published += 1

    def snapshot(self) -> ExecutorStats:
        """The figures since the previous snapshot (and starts the next window)."""
        now = self._node.clock.now_ns()
        window_ns, rows = self._window.take(now)
        return ExecutorStats(
            stamp=to_msg(now),
            process_name=self._process_name,
            hostname=self._hostname,
            pid=self._pid,
            window_ns=window_ns,
            callbacks=[
                CallbackStatsMsg(
                    node=r.node,
                    kind=r.kind,
                    name=r.name,
                    calls=r.calls,
                    exceptions=r.exceptions,
                    drops=r.dropped,
                    rate_hz=r.rate_hz,
                    mean_ns=r.mean_ns,
                    p95_ns=r.p95_ns,
                    max_ns=r.max_ns,
                    period_ns=r.period_ns,
                )
                for r in rows
            ],
        )
