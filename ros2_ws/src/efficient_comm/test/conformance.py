"""Harnesses that run one component on each backend behind the same small interface.

The conformance suite (``test_conformance.py``) talks only to a :class:`Harness`, so each
assertion holds for the standalone, composed and test backends alike. Peers are what a
user would have: another process's node for the DDS backends (here: another rclpy context,
i.e. another DDS participant), another component for the test backend.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from typing import Any, Protocol

import rclpy
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import QoSProfile

from efficient_comm import Container, Standalone
from efficient_comm.handle import NodeHandle
from efficient_comm.testing import TestHandle, isolated_domain_id, test_container

BACKENDS = ["standalone", "composed", "test"]


class Harness(Protocol):
    handle: Any  # the backend's NodeHandle
    component: Any
    stats_publisher: Any  # the container's or standalone node's StatsPublisher (or None)

    def send(self, topic: str, msg: Any) -> None: ...

    def collect(self, topic: str, msg_type: type, qos: QoSProfile | int = 10) -> list[Any]: ...

    def wait_for(self, predicate: Callable[[], bool], timeout_s: float = 10.0) -> bool: ...

    def run_for(self, seconds: float) -> None: ...

    def client(self, srv_type: type, name: str) -> Any: ...

    def serve(self, factory: Callable[[NodeHandle], Any]) -> Any:
        """Run ``factory`` as another component that the one under test can reach."""
        ...


class _DdsPeer:
    """A plain rclpy node in its own context: to the component, another process."""

    def __init__(self, domain_id: int) -> None:
        self.domain_id = domain_id
        self.others: list[Standalone] = []
        self.context = Context()
        rclpy.init(context=self.context, domain_id=domain_id)
        self.node = Node("peer", context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self._pubs: dict[str, Any] = {}
        self._subs: list[Any] = []

    def close(self) -> None:
        for other in self.others:
            other.close()
        self.executor.shutdown()
        self.node.destroy_node()
        self.context.try_shutdown()


class _DdsHarness:
    """Shared by standalone and composed: the peer is reached over DDS only."""

    def __init__(self, spin_component: Callable[[float], None], peer: _DdsPeer) -> None:
        self._spin_component = spin_component
        self._peer = peer

    def _spin(self, timeout_s: float) -> None:
        self._spin_component(timeout_s)
        self._peer.executor.spin_once(timeout_sec=timeout_s)
        for other in self._peer.others:
            other.spin_once(0)

    def serve(self, factory: Callable[[NodeHandle], Any]) -> Any:
        # Another process's component, as far as DDS can tell.
        other = Standalone(factory, name="other", domain_id=self._peer.domain_id)
        self._peer.others.append(other)
        return other.component

    def wait_for(self, predicate: Callable[[], bool], timeout_s: float = 10.0) -> bool:
        end = time.monotonic() + timeout_s
        while not predicate():
            if time.monotonic() > end:
                return False
            self._spin(0.005)
        return True

    def run_for(self, seconds: float) -> None:
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self._spin(0.005)

    def send(self, topic: str, msg: Any) -> None:
        pub = self._peer._pubs.get(topic)
        if pub is None:
            pub = self._peer._pubs[topic] = self._peer.node.create_publisher(type(msg), topic, 10)
            # Discovery is asynchronous: publish only once the component's reader matched.
            assert self.wait_for(lambda: pub.get_subscription_count() > 0), f"nobody on {topic}"
        pub.publish(msg)

    def client(self, srv_type: type, name: str) -> Any:
        return self._peer.node.create_client(srv_type, name)

    def collect(self, topic: str, msg_type: type, qos: QoSProfile | int = 10) -> list[Any]:
        store: list[Any] = []
        sub = self._peer.node.create_subscription(msg_type, topic, store.append, qos)
        self._peer._subs.append(sub)
        assert self.wait_for(lambda: sub.get_publisher_count() > 0), f"nobody publishes {topic}"
        return store


class _TestHarness:
    def __init__(self, handle: TestHandle, component: Any) -> None:
        self.handle = handle
        self.component = component
        self.stats_publisher: Any = handle.container.stats_publisher
        self._injector = TestHandle("peer", container=handle.container)

    def send(self, topic: str, msg: Any) -> None:
        self._injector.inject(topic, msg)

    def client(self, srv_type: type, name: str) -> Any:
        return self._injector.create_client(srv_type, name)

    def serve(self, factory: Callable[[NodeHandle], Any]) -> Any:
        return factory(TestHandle("other", container=self.handle.container))

    def collect(self, topic: str, msg_type: type, qos: QoSProfile | int = 10) -> list[Any]:
        store: list[Any] = []
        self._injector.create_subscription(msg_type, topic, store.append, qos=qos)
        self.handle.spin_some()
        return store

    def wait_for(self, predicate: Callable[[], bool], timeout_s: float = 10.0) -> bool:
        # Manual time: whatever can happen has happened once the ready queue is empty;
        # advance in small steps so timer-driven components progress too.
        for _ in range(round(timeout_s * 100)):
            if predicate():
                return True
            self.handle.advance(0.01)
        return predicate()

    def run_for(self, seconds: float) -> None:
        self.handle.advance(seconds)


@contextmanager
def harness(
    backend: str,
    factory: Callable[[NodeHandle], Any],
    *,
    name: str = "dut",
    namespace: str = "/",
    parameters: Mapping[str, Any] | None = None,
    remappings: Mapping[str, str] | None = None,
    stats_period_s: float = 1.0,
) -> Iterator[Harness]:
    """Run ``factory`` as node ``namespace/name`` on ``backend``; yields its harness.

    ``stats_period_s`` goes to the container or standalone node (0: no stats topic).
    """
    parameters = dict(parameters or {})
    remappings = dict(remappings or {})
    if backend == "test":
        container = test_container(stats_period_s=stats_period_s, stats_namespace=namespace)
        handle = TestHandle(
            name, namespace=namespace, parameters=parameters, remappings=remappings,
            container=container,
        )
        try:
            yield _TestHarness(handle, factory(handle))
        finally:
            container.close()
        return
    domain_id = isolated_domain_id()
    peer = _DdsPeer(domain_id)
    try:
        if backend == "standalone":
            args = ["dut", "--ros-args"]
            for key, value in parameters.items():
                args += ["-p", f"{key}:={_param_literal(value)}"]
            for src, dst in remappings.items():
                args += ["-r", f"{src}:={dst}"]
            with Standalone(
                factory, name=name, namespace=namespace, args=args, domain_id=domain_id,
                stats_period_s=stats_period_s,
            ) as node:
                h: Any = _DdsHarness(lambda t: node.spin_once(t), peer)
                h.handle, h.component = node.handle, node.component
                h.stats_publisher = node.stats_publisher
                yield h
        elif backend == "composed":
            with Container(
                "conformance", domain_id=domain_id, serve=False, stats_period_s=stats_period_s,
                stats_namespace=namespace,
            ) as container:
                instance = container.add(
                    factory, name=name, namespace=namespace, parameters=parameters,
                    remappings=remappings,
                )
                h = _DdsHarness(container.spin_once, peer)
                h.handle, h.component = container.components()[0].handle, instance
                h.stats_publisher = container.stats_publisher
                yield h
        else:
            raise ValueError(backend)
    finally:
        peer.close()


def _param_literal(value: Any) -> str:
    if value is None:
        return "#"  # what a user types unquoted: YAML reads a comment, i.e. null
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return f"'{value}'"
    return repr(value)
