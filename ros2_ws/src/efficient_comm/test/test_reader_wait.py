"""The waits of efficient_comm._reader_wait: the lockstep barrier's (one wait set for its
life, every sample of each ready subscription taken, woken by its guard from another
thread), the executor's (NodesWait) and its poll for the rest (PolledWait)."""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import pytest
import rclpy
from rclpy.context import Context
from rclpy.executors import ExternalShutdownException
from rclpy.qos import QoSProfile, ReliabilityPolicy
from std_msgs.msg import String

from efficient_comm._qos import latched_qos
from efficient_comm._reader_wait import NodesWait, PolledWait, ReaderWait
from efficient_comm.executor import take_samples
from efficient_comm.testing import isolated_domain_id, unique_topic


def _node(name: str, domain: int) -> Any:
    context = Context()
    rclpy.init(context=context, domain_id=domain)
    return rclpy.create_node(name, context=context, enable_rosout=False,
                             start_parameter_services=False)


def _close(node: Any) -> None:
    context = node.context
    node.destroy_node()
    context.try_shutdown()


@pytest.fixture
def nodes() -> Iterator[tuple[Any, Any]]:
    """A node that waits and a peer in a participant of its own (the process may already
    ignore its own endpoints: efficient_comm.dds)."""
    domain = isolated_domain_id()
    node, peer = _node("reader_wait", domain), _node("peer", domain)
    try:
        yield node, peer
    finally:
        _close(peer)
        _close(node)


def _qos() -> QoSProfile:
    return QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)


def _matched(waiter: ReaderWait, pub: Any) -> None:
    _wait_until(waiter, lambda: pub.get_subscription_count() > 0)


def _wait_until(waiter: ReaderWait, done: Any, timeout_s: float = 10.0) -> None:
    end = time.monotonic() + timeout_s
    while not done():
        assert time.monotonic() < end, "nothing came"
        waiter.wait(0.5)


def test_every_sample_of_a_ready_subscription_is_taken_and_others_added_later(
        nodes: tuple[Any, Any]) -> None:
    node, peer = nodes
    first, second = unique_topic("first"), unique_topic("second")
    got: list[tuple[str, str]] = []
    subs = (node.create_subscription(String, first, lambda m: got.append(("a", m.data)),
                                     _qos()),)
    waiter = ReaderWait(node.context, subs)
    try:
        pub = peer.create_publisher(String, first, _qos())
        later = peer.create_publisher(String, second, _qos())
        _matched(waiter, pub)
        assert waiter.wait(0.0) == 0
        for i in range(3):
            pub.publish(String(data=str(i)))
        assert pub.wait_for_all_acked()  # all three are in the reader's cache now
        assert waiter.wait(10.0) == 3  # one wait takes every sample the reader holds
        assert got == [("a", "0"), ("a", "1"), ("a", "2")]  # in order, none twice

        # A subscription added after the first wait is waited on too.
        waiter.add(node.create_subscription(String, second,
                                            lambda m: got.append(("b", m.data)),
                                            _qos()))
        _matched(waiter, later)
        later.publish(String(data="x"))
        _wait_until(waiter, lambda: ("b", "x") in got)
        assert got.count(("b", "x")) == 1
    finally:
        waiter.close()


def test_the_guard_ends_a_wait_at_once_and_a_destroyed_subscription_is_dropped(
        nodes: tuple[Any, Any]) -> None:
    node, _ = nodes
    sub = node.create_subscription(String, unique_topic("quiet"), lambda _m: None,
                                   latched_qos())
    guard = node.create_guard_condition(lambda: None)
    waiter = ReaderWait(node.context, (sub,), guard=guard)
    try:
        timer = threading.Timer(0.2, guard.trigger)
        timer.start()
        start = time.monotonic()
        assert waiter.wait(30.0) == 0
        assert time.monotonic() - start < 10.0  # woken, not timed out
        timer.join()

        node.destroy_subscription(sub)
        assert waiter.wait(0.0) == 0  # dropped, not an error
        assert waiter.wait(0.0) == 0
    finally:
        waiter.close()


def test_a_wait_after_shutdown_raises_as_rclpy_executors_do(nodes: tuple[Any, Any]) -> None:
    node, _ = nodes
    waiter = ReaderWait(node.context, ())
    node.context.try_shutdown()
    with pytest.raises(ExternalShutdownException):
        waiter.wait(0.0)
    waiter.close()


def test_a_nodes_wait_says_what_is_ready_and_takes_matched_events_for_the_caller(
        nodes: tuple[Any, Any]) -> None:
    """NodesWait (a real-time container's DDS wait): samples of ready subscriptions are left
    to the caller, a service request is reported for rclpy's executor, and a publisher's
    "matched" event is taken for the caller to run at once (a composed publisher writes DDS
    only while a reader is matched); nothing runs in the wait itself (the executor runs
    what it found, in its order)."""
    from rclpy.event_handler import PublisherEventCallbacks
    from rclpy.executors import SingleThreadedExecutor

    from efficient_comm_interfaces.srv import ListComponents

    node, peer = nodes
    topic, service = unique_topic("nodes"), unique_topic("trigger")
    got: list[str] = []
    matched: list[int] = []
    node.create_subscription(String, topic, lambda m: got.append(m.data), _qos())
    node.create_service(ListComponents, service, lambda _req, resp: resp)
    def on_matched(status: Any) -> None:
        matched.append(status.current_count)

    out = node.create_publisher(String, unique_topic("out"), _qos(),
                                event_callbacks=PublisherEventCallbacks(matched=on_matched))
    executor = SingleThreadedExecutor(context=node.context)
    executor.add_node(node)
    waiter = NodesWait(executor)
    try:
        pub = peer.create_publisher(String, topic, _qos())
        end = time.monotonic() + 10.0
        while pub.get_subscription_count() == 0:
            assert time.monotonic() < end, "never matched"
            waiter.wait(0.1)
        pub.publish(String(data="hi"))
        assert pub.wait_for_all_acked()
        ready = waiter.wait(10.0)
        assert [s.topic_name for s in ready.subs] == [topic] and not ready.other
        assert got == [] and take_samples(ready.subs[0]) == 1 and got == ["hi"]

        client = peer.create_client(ListComponents, service)
        assert client.wait_for_service(timeout_sec=10.0)
        client.call_async(ListComponents.Request())
        end = time.monotonic() + 10.0
        while not waiter.wait(0.5).other:  # the request: for rclpy's executor to serve
            assert time.monotonic() < end, "the request never showed"

        peer.create_subscription(String, out.topic_name, lambda _m: None, _qos())
        end = time.monotonic() + 10.0
        while not (events := waiter.wait(0.5).events):
            assert time.monotonic() < end, "the matched event never came"
        assert matched == []  # taken, not run
        [(handler, data)] = events
        handler.callback(data)
        assert matched == [1]
    finally:
        waiter.close()
        executor.shutdown()


@contextmanager
def _parameter_request(prefix: str) -> Iterator[tuple[Any, Any, Any, Any]]:
    """A node with its parameter services on an rclpy executor, and a peer in a participant
    of its own that has asked it for ``use_sim_time``: ``(node, executor, peer's executor,
    the request's future)``, all closed afterwards."""
    from rcl_interfaces.srv import GetParameters
    from rclpy.executors import SingleThreadedExecutor

    domain = isolated_domain_id()
    context = Context()
    rclpy.init(context=context, domain_id=domain)
    name = f"{prefix}_{unique_topic('n').strip('/')}"
    node = rclpy.create_node(name, context=context, enable_rosout=False)  # services on
    peer = _node("peer", domain)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    peer_executor = SingleThreadedExecutor(context=peer.context)
    peer_executor.add_node(peer)
    try:
        client = peer.create_client(GetParameters, f"/{name}/get_parameters")
        assert client.wait_for_service(timeout_sec=10.0)
        yield node, executor, peer_executor, client.call_async(
            GetParameters.Request(names=["use_sim_time"]))
    finally:
        executor.shutdown()
        peer_executor.shutdown()
        _close(peer)
        _close(node)


def test_a_nodes_wait_leaves_parameter_services_to_the_callers_poll() -> None:
    """A node's parameter services (seven a node, most of a container's entities) are not in
    the wait set: a request to one is not reported, rclpy's wait (the caller's poll every
    ``DDS_EVENTS_POLL_NS``) answers it."""
    with _parameter_request("params") as (_, executor, peer_executor, future):
        waiter = NodesWait(executor)
        try:
            end = time.monotonic() + 1.0
            while time.monotonic() < end:
                assert not waiter.wait(0.1).other, "a parameter request woke the wait"
            end = time.monotonic() + 10.0
            while not future.done():
                assert time.monotonic() < end, "rclpy's wait did not answer the request"
                executor.spin_once(timeout_sec=0.1)
                peer_executor.spin_once(timeout_sec=0.1)
            assert future.result() is not None and len(future.result().values) == 1
        finally:
            waiter.close()


def test_the_poll_answers_parameter_requests_without_rclpys_wait() -> None:
    """What NodesWait leaves out is polled on a wait set of its own (PolledWait): a peer's
    parameter request is answered with rclpy's executor never asked to wait (its wait over
    every entity cost 5.9 ms a poll in a robot's container). Its QoS events ("message
    lost") are polled the same way: tests/test_ros2_bag_compat.py counts a recorder's."""
    with _parameter_request("polled") as (node, executor, peer_executor, future):
        node.create_subscription(String, unique_topic("events"), lambda m: None, _qos())

        def never(*args: Any, **kwargs: Any) -> Any:
            raise AssertionError("rclpy's executor was asked to wait")

        executor._wait_for_ready_callbacks = never
        polled = PolledWait(executor)
        end = time.monotonic() + 10.0
        while not future.done():
            assert time.monotonic() < end, "the poll did not answer the request"
            polled.poll()
            peer_executor.spin_once(timeout_sec=0.05)
        assert future.result() is not None and len(future.result().values) == 1
