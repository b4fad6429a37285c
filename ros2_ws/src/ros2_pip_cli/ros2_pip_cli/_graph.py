"""A daemon-free node for one command: joins the domain, waits for discovery, goes.

ros2cli asks its daemon, which has been listening all along; without one, a command must
join the domain and listen itself. Rather than sleeping a fixed time, :meth:`CliNode.settle`
answers as soon as the graph stops changing, and :meth:`CliNode.wait_for` as soon as what a
command needs (a topic, a node, a service) has appeared.
"""

from __future__ import annotations

import os
import signal
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from types import FrameType
from typing import Any

import rclpy
from rclpy.context import Context
from rclpy.exceptions import NameValidationException
from rclpy.executors import SingleThreadedExecutor
from rclpy.expand_topic_name import expand_topic_name
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions
from rclpy.validate_full_topic_name import validate_full_topic_name

from ._timing import ANNOUNCE_S as ANNOUNCE_S
from ._timing import QUIET_S as QUIET_S
from ._timing import SETTLE_MAX_S as SETTLE_MAX_S
from ._timing import WAIT_S as WAIT_S
from .errors import CliError

_POLL_S = 0.02


class CliNode:
    """One hidden rclpy node (``_ros2cli_<pid>``, as ros2cli names its own) in its own context."""

    def __init__(self, *, name: str | None = None, parameter_services: bool = False) -> None:
        self.context = Context()
        # No rclpy signal handlers: Ctrl-C is Python's KeyboardInterrupt and SIGTERM ends the
        # process, as for any command line tool (rclpy's own handlers trap SIGTERM).
        rclpy.init(context=self.context, args=[],
                   signal_handler_options=SignalHandlerOptions.NO)
        try:
            self.node = Node(name or f"_ros2cli_{os.getpid()}", context=self.context,
                             start_parameter_services=parameter_services,
                             enable_rosout=False)
        except BaseException:
            self.context.try_shutdown()
            raise
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self._started = time.monotonic()

    def close(self) -> None:
        self.executor.shutdown()
        self.node.destroy_node()
        self.context.try_shutdown()

    def spin_once(self, timeout_s: float = _POLL_S) -> None:
        self.executor.spin_once(timeout_sec=timeout_s)

    def _signature(self) -> tuple[Any, ...]:
        node = self.node
        return (
            sorted(node.get_node_names_and_namespaces()),
            sorted((n, tuple(t)) for n, t in node.get_topic_names_and_types()),
            sorted((n, tuple(t)) for n, t in node.get_service_names_and_types()),
        )

    def _named(self) -> bool:
        """True when every endpoint in the graph belongs to a node whose name is known."""
        node = self.node
        for topic, _ in node.get_topic_names_and_types():
            infos = [*node.get_publishers_info_by_topic(topic),
                     *node.get_subscriptions_info_by_topic(topic)]
            if any(i.node_name == "_NODE_NAME_UNKNOWN_" for i in infos):
                return False
        return True

    def settle(self, *, min_s: float = ANNOUNCE_S, quiet_s: float = QUIET_S,
               max_s: float = SETTLE_MAX_S) -> None:
        """Listen at least ``min_s`` from start, then until the graph has been stable for
        ``quiet_s`` with every endpoint named; at most ``max(max_s, min_s)``."""
        deadline = self._started + max(max_s, min_s)
        earliest = self._started + min_s
        last = self._signature()
        changed = time.monotonic()
        while True:
            now = time.monotonic()
            if now >= deadline:
                return
            if now - changed >= quiet_s and now >= earliest and self._named():
                return
            self.spin_once()
            current = self._signature()
            if current != last:
                last, changed = current, time.monotonic()

    def wait_for(self, predicate: Callable[[], bool], *, timeout_s: float = WAIT_S) -> bool:
        """Spin until ``predicate()`` holds; False after ``timeout_s``."""
        deadline = time.monotonic() + timeout_s
        while not predicate():
            if time.monotonic() >= deadline:
                return False
            self.spin_once()
        return True

    def call(self, srv_type: type, service: str, request: Any, *,
             timeout_s: float = WAIT_S) -> Any:
        """Call ``service`` once and return the response; CliError if it is not there."""
        client = self.node.create_client(srv_type, service)
        try:
            if not self.wait_for(client.service_is_ready, timeout_s=timeout_s):
                raise CliError(f"service {service} is not available (waited {timeout_s:g} s)")
            future = client.call_async(request)
            if not self.wait_for(future.done, timeout_s=timeout_s):
                raise CliError(f"service {service} did not answer within {timeout_s:g} s")
            return future.result()
        finally:
            self.node.destroy_client(client)

    def resolve(self, name: str, *, kind: str = "topic") -> str:
        """A topic or service name as the graph spells it (see :func:`resolve_name`)."""
        return resolve_name(name, kind=kind, node_name=self.node.get_name())

    # -- graph queries shared by several commands ------------------------------------------

    def node_names(self, *, include_hidden: bool = False) -> list[str]:
        """Full names of the nodes in the graph (without this command's own)."""
        names = []
        for name, namespace in self.node.get_node_names_and_namespaces():
            if not include_hidden and name.startswith("_"):
                continue
            names.append(full_name(name, namespace))
        return sorted(names)

    def has_node(self, name: str) -> bool:
        return name in self.node_names(include_hidden=True)

    def require_node(self, name: str) -> tuple[str, str]:
        """Wait for ``name`` to appear; returns (name, namespace) or raises CliError."""
        fqn = absolute(name)
        if not self.wait_for(lambda: self.has_node(fqn)):
            raise CliError(f"Node not found: {fqn}")
        namespace, _, base = fqn.rpartition("/")
        return base, namespace or "/"


def absolute(name: str) -> str:
    """``talker`` -> ``/talker``, as ros2cli reads node names."""
    return name if name.startswith("/") else "/" + name


def full_name(name: str, namespace: str) -> str:
    return (namespace.rstrip("/") + "/" + name) if namespace != "/" else "/" + name


def resolve_name(name: str, *, kind: str = "topic", node_name: str | None = None) -> str:
    """A topic or service name as the graph spells it: ``chatter`` -> ``/chatter``.

    ros2cli resolves the names it is given as rclpy does for its own node (relative to
    the root namespace, ``~`` to the command's node); an invalid name is one line. No node
    is needed, so a verb answered by the daemon resolves the same way."""
    try:
        expanded = expand_topic_name(name, node_name or f"_ros2cli_{os.getpid()}", "/")
        validate_full_topic_name(expanded, is_service=kind == "service")
    except (ValueError, NameValidationException) as exc:
        raise CliError(f"Invalid {kind} name {name!r}: "
                       f"{str(exc).splitlines()[0].split(', at /')[0]}") from exc
    return expanded


@contextmanager
def cli_node(*, name: str | None = None, parameter_services: bool = False) -> Iterator[CliNode]:
    node = CliNode(name=name, parameter_services=parameter_services)
    try:
        yield node
    finally:
        node.close()


class StopSignal:
    """Ctrl-C and SIGTERM set :attr:`requested` instead of raising (a context manager).

    A KeyboardInterrupt raised inside an executor's ``spin_once`` leaves a callback half
    dispatched; with the flag, commands that run until stopped (echo, hz, bag record) end
    between callbacks and close their bag, node and context in order.
    """

    def __init__(self) -> None:
        self.requested = False
        self._previous: dict[int, Any] = {}

    def __enter__(self) -> StopSignal:
        for sig in (signal.SIGINT, signal.SIGTERM):
            self._previous[sig] = signal.signal(sig, self._request)
        return self

    def __exit__(self, *_exc: object) -> None:
        for sig, handler in self._previous.items():
            signal.signal(sig, handler)

    def _request(self, _signum: int, _frame: FrameType | None) -> None:
        self.requested = True
