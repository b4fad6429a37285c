"""Composed topics and DDS: every peer gets every message exactly once, locals by reference.

Peers here are rclpy nodes in other contexts, i.e. other DDS participants, which is what
another process is to DDS. ``test_processes.py`` repeats the key cases across processes.
"""

from __future__ import annotations

import sys
import threading
import time
from collections import Counter
from typing import Any

import pytest
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import String

from efficient_comm import Container
from efficient_comm.handle import NodeHandle
from efficient_comm.testing import isolated_domain_id, unique_topic

from ._ros import peer

RELIABLE = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)


class Talker:
    def __init__(self, node: NodeHandle, topic: str) -> None:
        self.pub = node.create_publisher(String, topic, qos=RELIABLE)
        self.sent: list[String] = []

    def say(self, text: str) -> None:
        msg = String(data=text)
        self.sent.append(msg)
        self.pub.publish(msg)


class Listener:
    def __init__(self, node: NodeHandle, topic: str) -> None:
        self.heard: list[Any] = []
        node.create_subscription(String, topic, self.heard.append, qos=RELIABLE)


def test_no_duplicate_and_no_loss_with_local_and_remote_publishers_and_subscribers() -> None:
    topic = unique_topic()
    domain = isolated_domain_id()
    with (
        Container("gw", domain_id=domain, serve=False) as container,
        peer(domain, "remote_listener") as rx,
        peer(domain, "remote_talker") as tx,
    ):
        talker = container.add(lambda n: Talker(n, topic), name="talker")
        listener = container.add(lambda n: Listener(n, topic), name="listener")
        remote_heard: list[String] = []
        rx.node.create_subscription(String, topic, remote_heard.append, RELIABLE)
        remote_pub = tx.node.create_publisher(String, topic, RELIABLE)

        def spin(timeout_s: float) -> None:
            container.spin_once(timeout_s)
            tx.executor.spin_once(timeout_sec=0)

        # Discovery: the remote reader matched our writer, our reader and the remote one
        # matched the remote writer.
        assert rx.wait_for(
            lambda: talker.pub.dds_matched == 1 and remote_pub.get_subscription_count() == 2,
            also=spin,
        )
        for i in range(20):
            talker.say(f"local {i}")
            remote_pub.publish(String(data=f"remote {i}"))
        assert rx.wait_for(
            lambda: len(listener.heard) >= 40 and len(remote_heard) >= 40, also=spin
        )
        rx.wait_for(lambda: False, timeout_s=0.3, also=spin)  # let duplicates show, if any
        expected = {f"{who} {i}" for who in ("local", "remote") for i in range(20)}
        for heard in (listener.heard, remote_heard):
            counts = Counter(m.data for m in heard)
            assert set(counts) == expected and set(counts.values()) == {1}
        # In-process delivery was by reference: the very objects the talker published.
        local_objects = [m for m in listener.heard if m.data.startswith("local")]
        assert all(a is b for a, b in zip(local_objects, talker.sent, strict=True))


def test_no_dds_write_without_remote_subscribers() -> None:
    topic = unique_topic()
    domain = isolated_domain_id()
    with Container("quiet", domain_id=domain, serve=False) as container:
        talker = container.add(lambda n: Talker(n, topic), name="talker")
        container.add(lambda n: Listener(n, topic), name="listener")
        writes: list[Any] = []
        real = talker.pub.dds
        talker.pub.dds = type("Spy", (), {"publish": lambda _self, m: writes.append(m)})()
        talker.say("only local")
        assert talker.pub.dds_matched == 0 and writes == []
        talker.pub.dds = real


def test_remote_late_joiner_gets_transient_local_history() -> None:
    topic = unique_topic()
    domain = isolated_domain_id()
    latched = QoSProfile(
        depth=1,
        reliability=ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.TRANSIENT_LOCAL,
    )

    class Map:
        def __init__(self, node: NodeHandle) -> None:
            node.create_publisher(String, topic, qos=latched).publish(String(data="the map"))

    with Container("latch", domain_id=domain, serve=False) as container, peer(domain) as remote:
        container.add(Map, name="map_server")
        got: list[String] = []
        remote.node.create_subscription(String, topic, got.append, latched)
        assert remote.wait_for(lambda: len(got) == 1, also=container.spin_once)
        assert got[0].data == "the map"


def test_publish_from_another_thread_reaches_callbacks_in_the_executor_thread() -> None:
    import threading

    topic = unique_topic()
    with Container("threads", domain_id=isolated_domain_id(), serve=False) as container:
        talker = container.add(lambda n: Talker(n, topic), name="talker")
        threads: list[int] = []
        container.add(lambda n: n.create_subscription(
            String, topic, lambda _m: threads.append(threading.get_ident()), qos=RELIABLE
        ), name="listener")
        worker = threading.Thread(target=lambda: container.spin_until(
            lambda: len(threads) == 3, timeout_s=15
        ))
        spinning = threading.Event()
        container.executor.post(spinning.set)  # runs once the worker owns the executor
        worker.start()
        assert spinning.wait(15)
        for i in range(3):
            talker.say(str(i))
        worker.join()
        assert threads == [worker.ident] * 3


#: Where an executor's thread waits for DDS work: its wait set (efficient_comm._reader_wait),
#: or rclpy's executor's.
_DDS_WAITS = {"NodesWait.wait", "Executor._wait_for_ready_callbacks"}


def _waiting_in_rclpy(thread_id: int) -> bool:
    """Whether the thread sits in a wait for DDS work (a wait set's)."""
    frame = sys._current_frames().get(thread_id)
    while frame is not None:
        if frame.f_code.co_qualname in _DDS_WAITS:
            return True
        frame = frame.f_back
    return False


@pytest.mark.timeout(60)
@pytest.mark.parametrize("every_round_polls_events", [False, True])
def test_a_publish_from_another_thread_ends_the_executors_wait_for_dds(
        every_round_polls_events: bool, monkeypatch: pytest.MonkeyPatch) -> None:
    """A DDS container's executor waits in rclpy's wait set; another thread's publish must
    end that wait. Before, it only made rclpy rebuild its wait set and wait again until the
    poll timeout (median 48 ms; here, with no timeout, for good), so at 1 kHz and depth 10
    most messages were dropped (bench/comm_bench.py --only foreign measures both).
    No statistics timer: its deadline would end the wait on its own.

    The wait's round for the QoS events (every ``DDS_EVENTS_POLL_NS``) takes the wake-up's
    guard condition too, and the executor went on waiting after it when no callback had
    run: a publish that came during that round was heard only with the watchdog's message
    (once in a full run; with every round an events round, every time)."""
    from efficient_comm import executor

    if every_round_polls_events:
        monkeypatch.setattr(executor, "DDS_EVENTS_POLL_NS", 0)
    topic = unique_topic("foreign")
    domain = isolated_domain_id()
    with peer(domain) as p, Container("foreign", domain_id=domain, serve=False,
                                      stats_period_s=0) as container:
        talker = container.add(lambda n: Talker(n, topic), name="talker")
        heard: list[String] = []
        container.add(
            lambda n: n.create_subscription(String, topic, heard.append, qos=10), name="ear"
        )
        executor_thread = threading.get_ident()

        def publish_while_the_executor_waits() -> None:
            deadline = time.monotonic() + 30
            while not _waiting_in_rclpy(executor_thread) and time.monotonic() < deadline:
                time.sleep(0.001)
            talker.pub.publish(String(data="wake up"))

        # If the publish does not end the wait, a message from another participant will,
        # so that the test fails instead of hanging (a signal cannot end rclpy's wait).
        rescue = p.node.create_publisher(String, topic, 10)
        watchdog = threading.Timer(20.0, lambda: rescue.publish(String(data="watchdog")))
        thread = threading.Thread(target=publish_while_the_executor_waits)
        watchdog.start()
        thread.start()
        try:
            container.spin_once()  # no timeout: only the publish should end this wait
        finally:
            watchdog.cancel()
            thread.join()
        assert [m.data for m in heard] == ["wake up"]


def test_a_container_on_a_manual_clock_hears_remote_peers_while_it_advances() -> None:
    """Lockstep with DDS (``demo --lockstep`` watched by the GUI): ``advance()`` never waits,
    yet what remote peers send (messages, throttle requests, service calls) gets in."""
    from efficient_comm.testing import ManualClock

    topic = unique_topic()
    domain = isolated_domain_id()
    with (
        Container("lockstep", domain_id=domain, clock=ManualClock(), serve=False,
                  stats_period_s=0) as container,
        peer(domain, "remote_talker") as tx,
    ):
        listener = container.add(lambda n: Listener(n, topic), name="listener")
        ticks: list[int] = []
        container.add(lambda n: n.create_timer(0.01, lambda: ticks.append(1)), name="ticker")
        remote_pub = tx.node.create_publisher(String, topic, RELIABLE)
        end = time.monotonic() + 20.0
        sent = 0
        while not listener.heard:
            assert time.monotonic() < end, "a remote message never reached the container"
            if remote_pub.get_subscription_count() and sent < 50:
                remote_pub.publish(String(data=f"m{sent}"))
                sent += 1
            container.advance(0.01)  # as fast as the machine allows: no wait inside
        assert listener.heard[0].data.startswith("m")
        assert ticks  # simulated time went on meanwhile


def test_a_busy_container_answers_service_calls_when_every_poll_is_an_event_poll(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """A busy executor's DDS polls come at its poll interval, which grows with the poll's
    cost (a robot's container: 330 ms). Once that exceeds ``DDS_EVENTS_POLL_NS`` every
    poll is also the QoS events' poll; the services its DDS wait looks after must be
    answered in those rounds too (a lockstep robot's recorder never answered ``stop``).
    The events' period is set to 0 here: every round is such a round."""
    from efficient_comm import executor
    from efficient_comm.testing import ManualClock
    from robot_recorder_interfaces.srv import Stop

    monkeypatch.setattr(executor, "DDS_EVENTS_POLL_NS", 0)
    domain = isolated_domain_id()
    service = unique_topic("stop")
    calls: list[int] = []

    def answer(request: Any, response: Any) -> Any:
        calls.append(1)
        response.success = True
        return response

    with (
        Container("busy", domain_id=domain, clock=ManualClock(), serve=False,
                  stats_period_s=0) as container,
        peer(domain, "caller") as caller,
    ):
        container.add(lambda n: n.create_service(Stop, service, answer), name="server")
        container.add(lambda n: n.create_timer(0.01, lambda: None), name="ticker")
        client = caller.node.create_client(Stop, service)
        assert caller.wait_for(client.service_is_ready, 20.0,
                               also=lambda _: container.advance(0.01))
        future = client.call_async(Stop.Request())
        assert caller.wait_for(future.done, 20.0, also=lambda _: container.advance(0.01)), \
            "the container never answered the call"
        assert future.result().success and calls == [1]
