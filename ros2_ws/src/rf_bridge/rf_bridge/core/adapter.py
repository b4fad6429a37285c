"""The channel-adapter interface and the resolved route every adapter works with.

One adapter per external system (ROS 1, the team link). The core hands an adapter ROS 2
message objects to send and receives ROS 2 message objects back: translation into the
external system's types is the adapter's business, through the translators it is given.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol

from ..config import TopicSpec
from .stats import TopicStats


@dataclass(frozen=True, eq=False)
class Route:
    """A configured topic with its ROS 2 class resolved and its statistics."""

    spec: TopicSpec
    ros2_cls: type
    stats_out: TopicStats = field(repr=False)  # ROS 2 -> peer
    stats_in: TopicStats = field(repr=False)  # peer -> ROS 2

    @property
    def peer_topic(self) -> str:
        return self.spec.peer_topic


#: ``deliver(route, ros2_message, received_ns, wire_bytes)``, callable from any thread;
#: ``received_ns`` is ``time.perf_counter_ns()`` when the bytes arrived.
Deliver = Callable[[Route, Any, int, int], None]


class ChannelAdapter(Protocol):
    name: str

    def start(self, routes: Sequence[Route], deliver: Deliver) -> Sequence[Route]:
        """Connect and begin serving ``routes``; returns without waiting for peers.

        Returns the routes it serves: one it refuses (a type it cannot carry, say) is
        logged with the reason and left out, and the bridge does not count it as bridged.
        ``deliver`` may be called before this returns.
        """
        ...

    def send(self, route: Route, msg: Any, received_ns: int) -> None:
        """Send a ROS 2 message to the peer; never blocks, counts what it cannot deliver."""
        ...

    def close(self) -> None: ...
