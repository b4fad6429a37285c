"""What the read-only graph verbs print, answered by the daemon or by the command's own node.

A :class:`Query` says what a verb needs (what to wait for, one topic's or one node's
endpoints); :func:`build_view` answers it from an rclpy node as a :class:`View` of plain
lists and strings. The daemon runs the same function on its node, so an answer from the
daemon is, by construction, the answer the command would have computed by itself
(``--no-daemon``); only how long discovery took differs.
"""

from __future__ import annotations

import argparse
from dataclasses import asdict, dataclass, field
from typing import TYPE_CHECKING, Any

from ._timing import ANNOUNCE_S

if TYPE_CHECKING:  # rclpy only where a graph is read: ``ros2 run`` imports this module
    from rclpy.node import Node

#: Nodes of this tool that are not part of the user's graph: graph daemons (any command's)
#: are left out of every answer, as is the asking command's own node.
DAEMON_NODE_PREFIX = "_ros2cli_daemon_"

NamesAndTypes = list[tuple[str, list[str]]]


@dataclass(frozen=True)
class Query:
    """``wait_kind``/``wait_name``: a ``topic``, ``node`` or ``service`` to wait for (an
    absent one is answered once discovery has settled); ``settle_after_wait``: then also
    wait until the graph is quiet (for counts); ``topic``, ``node``: whose endpoints."""

    wait_kind: str = ""
    wait_name: str = ""
    settle_after_wait: bool = False
    topic: str = ""
    node: str = ""

    def to_json(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> Query:
        return cls(**{k: data[k] for k in cls.__dataclass_fields__ if k in data})


@dataclass
class View:
    """The graph as the verbs print it. Endpoint infos are kept as ros2cli prints them."""

    nodes: list[str] = field(default_factory=list)  # full names, sorted
    topics: NamesAndTypes = field(default_factory=list)
    services: NamesAndTypes = field(default_factory=list)
    publishers: list[str] = field(default_factory=list)  # of Query.topic, str(info) each
    subscriptions: list[str] = field(default_factory=list)
    publisher_count: int = 0
    subscription_count: int = 0
    #: Query.node's sections (Subscribers, Publishers, Service Servers, Service Clients).
    node_sections: list[tuple[str, NamesAndTypes]] = field(default_factory=list)
    node_error: str = ""

    def to_json(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> View:
        def pairs(items: Any) -> NamesAndTypes:
            return [(str(n), [str(t) for t in types]) for n, types in items]

        return cls(
            nodes=[str(n) for n in data["nodes"]],
            topics=pairs(data["topics"]), services=pairs(data["services"]),
            publishers=list(data["publishers"]), subscriptions=list(data["subscriptions"]),
            publisher_count=int(data["publisher_count"]),
            subscription_count=int(data["subscription_count"]),
            node_sections=[(str(t), pairs(e)) for t, e in data["node_sections"]],
            node_error=str(data["node_error"]))

    def topic_types(self, name: str) -> list[str]:
        return dict(self.topics).get(name, [])

    def service_types(self, name: str) -> list[str]:
        return dict(self.services).get(name, [])


def _tool_node(fqn: str, own: str) -> bool:
    return fqn == own or fqn.rpartition("/")[2].startswith(DAEMON_NODE_PREFIX)


def _tool_service(name: str, own: str) -> bool:
    """A service of the asking command's node or of a daemon's (``/<node>/<service>``)."""
    owner = name.rpartition("/")[0]
    return owner == own or owner.rpartition("/")[2].startswith(DAEMON_NODE_PREFIX)


def present(node: Node, query: Query) -> bool:
    """Whether what ``query`` waits for is in ``node``'s graph (True if it waits for none)."""
    from ._graph import full_name

    if query.wait_kind == "topic":
        return any(n == query.wait_name for n, _ in node.get_topic_names_and_types())
    if query.wait_kind == "service":
        return any(n == query.wait_name for n, _ in node.get_service_names_and_types())
    if query.wait_kind == "node":
        return any(full_name(n, ns) == query.wait_name
                   for n, ns in node.get_node_names_and_namespaces())
    return True


def build_view(node: Node, query: Query) -> View:
    """The answer to ``query`` from what ``node`` has discovered (no waiting here)."""
    from ._graph import full_name

    own = node.get_fully_qualified_name()
    view = View(
        nodes=sorted(f for f in (full_name(n, ns) for n, ns in
                                 node.get_node_names_and_namespaces())
                     if not _tool_node(f, own)),
        topics=sorted((n, list(t)) for n, t in node.get_topic_names_and_types()),
        services=sorted((n, list(t)) for n, t in node.get_service_names_and_types()
                        if not _tool_service(n, own)),
    )
    if query.topic:
        view.publishers = [str(i) for i in node.get_publishers_info_by_topic(query.topic)]
        view.subscriptions = [str(i) for i in node.get_subscriptions_info_by_topic(query.topic)]
        view.publisher_count = node.count_publishers(query.topic)
        view.subscription_count = node.count_subscribers(query.topic)
    if query.node:
        namespace, _, name = query.node.rpartition("/")
        namespace = namespace or "/"
        try:
            view.node_sections = [
                ("Subscribers", node.get_subscriber_names_and_types_by_node(name, namespace)),
                ("Publishers", node.get_publisher_names_and_types_by_node(name, namespace)),
                ("Service Servers", node.get_service_names_and_types_by_node(name, namespace)),
                ("Service Clients", node.get_client_names_and_types_by_node(name, namespace)),
            ]
            view.node_sections = [(t, sorted((n, list(ts)) for n, ts in e))
                                  for t, e in view.node_sections]
        except Exception as exc:  # the node left between the two queries
            view.node_error = str(exc)
    return view


def graph_view(args: argparse.Namespace, query: Query) -> View:
    """Ask the daemon (started if need be) unless ``--no-daemon``; without an answer from
    it, listen for oneself: ``--spin-time`` first for whole-graph answers, else until
    what the query waits for has appeared (then ``--spin-time`` and until the graph is
    quiet, if asked: one endpoint seen says nothing of the other processes' endpoints)."""
    if not getattr(args, "no_daemon", False):
        from ._daemon import ask_view

        answer = ask_view(query)
        if answer is not None:
            return answer
    from ._graph import cli_node

    with cli_node() as cli:
        # Whole-graph answers listen --spin-time first; answers about one thing wait for it
        # (and, for counts, listen as long too once it has appeared).
        waited = not query.wait_kind or (cli.wait_for(lambda: present(cli.node, query))
                                         and query.settle_after_wait)
        if waited:
            cli.settle(min_s=getattr(args, "spin_time", ANNOUNCE_S))
        return build_view(cli.node, query)
