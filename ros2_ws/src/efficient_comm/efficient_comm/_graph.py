"""The node handle's graph capability: the process's own topics, then what DDS discovered."""

from __future__ import annotations

from typing import TYPE_CHECKING

from ._names import fully_qualified
from .typenames import type_name

if TYPE_CHECKING:
    from rclpy.node import Node
    from rclpy.qos import QoSProfile

    from .bus import Bus


class NodeGraph:
    """One :class:`~efficient_comm.handle.Graph` for every backend.

    ``bus`` is the container's (None standalone), ``node`` the rclpy node DDS is asked
    through (None without DDS). A composed publisher is on both; it is counted once.
    """

    __slots__ = ("_bus", "_node")

    def __init__(self, *, bus: Bus | None, node: Node | None) -> None:
        self._bus = bus
        self._node = node

    def topic_names_and_types(self) -> dict[str, list[str]]:
        found: dict[str, list[str]] = {}
        if self._bus is not None:
            for name, msg_type in self._bus.topics().items():
                found[name] = [type_name(msg_type)]
        if self._node is not None:
            for name, types in self._node.get_topic_names_and_types():
                known = found.setdefault(name, [])
                known += [t for t in types if t not in known]
        return found

    def publishers_qos(self, topic: str) -> list[QoSProfile]:
        offered: list[QoSProfile] = []
        local: set[str] = set()
        if self._bus is not None:
            for pub in self._bus.publishers(topic):
                offered.append(pub.qos)
                local.add(pub.name)
        if self._node is not None:
            offered += [
                info.qos_profile
                for info in self._node.get_publishers_info_by_topic(topic)
                if fully_qualified(info.node_name, info.node_namespace) not in local
            ]
        return offered
