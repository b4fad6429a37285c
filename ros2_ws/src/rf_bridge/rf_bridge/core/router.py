"""The router: moves messages between the ROS 2 side and the channel adapters.

Loop prevention works by origin: adapters never hand back what the bridge itself sent
(ROS 1: our own publisher is skipped; team: samples carry their robot's id), and on the ROS 2
side a message the bridge published is remembered until it comes back through the bridge's
own subscription of a ``both`` route, where it is recognised (same object when composed,
equal value over DDS) and not sent out again.
"""

from __future__ import annotations

import collections
import threading
import time
from collections.abc import Callable, Mapping
from typing import Any

from throttle_publisher import Gate

from .adapter import ChannelAdapter, Route

_ECHO_WINDOW = 32


class Router:
    def __init__(
        self,
        adapters: Mapping[str, ChannelAdapter],
        *,
        publish: Callable[[Route, Any], None],
        now_ns: Callable[[], int],
    ) -> None:
        self._adapters = adapters
        self._publish = publish
        self._now_ns = now_ns
        self._gates: dict[int, Gate] = {}
        self._echo: dict[int, collections.deque[Any]] = {}
        self._lock = threading.Lock()
        self.loops_suppressed = 0

    def add(self, route: Route) -> None:
        if route.spec.throttle is not None and route.spec.throttle_mode == "local":
            self._gates[id(route)] = Gate(route.spec.throttle)
        if route.spec.direction == "both":
            self._echo[id(route)] = collections.deque(maxlen=_ECHO_WINDOW)

    def from_ros2(self, route: Route, msg: Any) -> None:
        """A ROS 2 message on an outbound route (executor thread)."""
        received = time.perf_counter_ns()
        echo = self._echo.get(id(route))
        if echo is not None and self._is_echo(echo, msg):
            self.loops_suppressed += 1
            return
        gate = self._gates.get(id(route))
        if gate is not None and not gate.offer(self._now_ns()):
            route.stats_out.dropped("throttled")
            return
        self._adapters[route.spec.peer].send(route, msg, received)

    def from_peer(self, route: Route, msg: Any, received_ns: int, nbytes: int) -> None:
        """A translated message from an adapter (any thread): publish it on ROS 2."""
        echo = self._echo.get(id(route))
        if echo is not None:
            with self._lock:
                echo.append(msg)
        try:
            self._publish(route, msg)
        except Exception:
            route.stats_in.dropped("publish_failed")
            raise
        route.stats_in.delivered(nbytes, time.perf_counter_ns() - received_ns)

    def _is_echo(self, echo: collections.deque[Any], msg: Any) -> bool:
        with self._lock:
            for i, seen in enumerate(echo):
                if seen is msg or seen == msg:
                    del echo[i]
                    return True
        return False
