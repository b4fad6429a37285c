"""Throttled publishing on every backend: each subscriber gets exactly what it asked for."""

from __future__ import annotations

import itertools
import time
from collections.abc import Callable, Iterator
from contextlib import ExitStack, contextmanager
from pathlib import Path

import pytest
from std_msgs.msg import String

from efficient_comm import Container, Standalone
from efficient_comm.handle import NodeHandle
from efficient_comm.testing import TestHandle, isolated_domain_id, test_container, unique_topic
from throttle_publisher import (
    InvalidOptionsError,
    ThrottledPublisher,
    ThrottledSubscription,
    ThrottleOptions,
)

from ._ros import short_lease_profile

RATE_HZ = 30.0


class Source:
    """A 30 Hz 'expensive' output: computed only when someone wants the sample."""

    def __init__(self, node: NodeHandle, topic: str) -> None:
        self.out = ThrottledPublisher(node, String, topic, qos=100, count_bytes=True)
        self.index = 0
        self.computed = 0
        self.tick_ns: list[int] = []  # the node clock's time at each index's tick
        self._clock = node.clock
        node.create_timer(1.0 / RATE_HZ, self._tick)

    def _tick(self) -> None:
        self.tick_ns.append(self._clock.now_ns())
        if self.out.wants():
            self.computed += 1
            self.out.publish(String(data=str(self.index)))
        else:
            self.out.skip()
        self.index += 1


class Sinks:
    """A plain subscriber and three throttled ones, each recording sample indices."""

    def __init__(self, node: NodeHandle, topic: str, *, plain: bool = True) -> None:
        self.got: dict[str, list[int]] = {k: [] for k in ("plain", "rate", "nth", "paused")}

        def record(key: str) -> Callable[[String], None]:
            return lambda msg: self.got[key].append(int(msg.data))

        if plain:
            node.create_subscription(String, topic, record("plain"), qos=100)
        self.throttled = {
            key: ThrottledSubscription(node, String, topic, record(key), options=options,
                                       qos=100)
            for key, options in [
                ("rate", ThrottleOptions(max_rate_hz=5.0)),
                ("nth", ThrottleOptions(every_nth=10)),
                ("paused", ThrottleOptions(paused=True)),
            ]
        }

    def reset(self) -> None:
        for samples in self.got.values():
            samples.clear()


class World:
    """A source and the sinks on one backend, with a way to let time pass."""

    source: Source
    sinks: Sinks
    spin: Callable[[float], None]

    def run_until(self, predicate: Callable[[], bool], timeout_s: float = 20.0) -> bool:
        end = time.monotonic() + timeout_s
        while not predicate():
            if time.monotonic() > end:
                return False
            self.spin(0.005)
        return True


@contextmanager
def world(backend: str, *, plain: bool = True) -> Iterator[World]:
    topic = unique_topic("camera")
    w = World()
    with ExitStack() as stack:
        if backend == "test":
            container = stack.enter_context(test_container())
            w.source = Source(TestHandle("source", container=container), topic)
            w.sinks = Sinks(TestHandle("sinks", container=container), topic, plain=plain)
            w.spin = lambda _t: container.advance(1.0 / RATE_HZ)
        elif backend == "composed":
            c = stack.enter_context(Container("throttle", domain_id=isolated_domain_id(),
                                              serve=False))
            w.source = c.add(lambda n: Source(n, topic), name="source")
            w.sinks = c.add(lambda n: Sinks(n, topic, plain=plain), name="sinks")
            w.spin = c.spin_once
        else:  # standalone: two nodes in two DDS participants
            domain = isolated_domain_id()
            a = stack.enter_context(
                Standalone(lambda n: Source(n, topic), name="source", domain_id=domain, args=[])
            )
            b = stack.enter_context(
                Standalone(lambda n: Sinks(n, topic, plain=plain), name="sinks",
                           domain_id=domain, args=[])
            )
            w.source, w.sinks = a.component, b.component

            def spin(timeout_s: float) -> None:
                a.spin_once(timeout_s)
                b.spin_once(0)

            w.spin = spin
        yield w


def _wired(w: World, *, plain: bool = True) -> bool:
    out = w.source.out
    requests = out.requests()
    return (
        len(requests) == 3
        and out._pub.get_subscription_count() == int(plain)
        and all(r.publisher.get_subscription_count() == 1 for r in out._replies.values())
    )


@pytest.mark.parametrize("backend", ["test", "composed", "standalone"])
def test_each_subscriber_gets_what_it_asked_for(backend: str) -> None:
    with world(backend) as w:
        assert w.run_until(lambda: _wired(w)), w.source.out.requests()
        w.sinks.reset()
        assert w.run_until(lambda: len(w.sinks.got["plain"]) >= 90)
        got = w.sinks.got
        plain, rate, nth = got["plain"], got["rate"], got["nth"]
        # Plain subscribers keep receiving every sample.
        assert plain == list(range(plain[0], plain[0] + len(plain)))
        # every_nth: exactly every 10th sample the source produced.
        assert nth and all(b - a == 10 for a, b in itertools.pairwise(nth))
        assert abs(len(nth) - len(plain) / 10) <= 1
        # max_rate_hz=5 of a 30 Hz source: 5 Hz on average on the publisher's clock, and no
        # gap much shorter than 0.2 s (the gate takes a sample that comes up to 0.6 of the
        # source's measured interval early, so a late tick does not cost a whole period).
        # Counted in time, not in samples: on a loaded machine ticks come late and then
        # bunched, so a 0.2 s gap may hold 4 samples, or 8.
        stamps = w.source.tick_ns
        gaps = [(stamps[b] - stamps[a]) * 1e-9 for a, b in itertools.pairwise(rate)]
        assert gaps and min(gaps) >= 0.15, gaps
        assert 0.19 <= sum(gaps) / len(gaps) <= 0.25, gaps
        assert got["paused"] == []
        # The publisher's own counters agree with what each subscriber received.
        sent = {s.options: s for s in w.source.out.stats().values()}
        assert sent[ThrottleOptions(paused=True)].sent == 0
        nth_stats = sent[ThrottleOptions(every_nth=10)]
        assert nth_stats.sent >= len(nth) and nth_stats.sent_bytes > 0


@pytest.mark.parametrize("backend", ["test", "composed"])
def test_what_nobody_wants_is_not_computed(backend: str) -> None:
    with world(backend, plain=False) as w:
        assert w.run_until(lambda: _wired(w, plain=False))
        for sub in w.sinks.throttled.values():
            sub.update(ThrottleOptions(paused=True))
        computed, index = w.source.computed, w.source.index
        assert w.run_until(lambda: w.source.index >= index + 30)
        assert w.source.computed == computed  # 30 ticks, nobody listening: nothing computed
        assert w.source.out.next_due_ns() is None
        w.sinks.throttled["rate"].update(ThrottleOptions(max_rate_hz=1.0))
        computed, index = w.source.computed, w.source.index
        assert w.run_until(lambda: w.source.index >= index + 90)
        # One 1 Hz subscriber: about one sample computed in every 30 (3 s of ticks).
        assert 2 <= w.source.computed - computed <= 4


def test_run_time_changes_apply_without_restart() -> None:
    with world("test") as w:
        assert w.run_until(lambda: _wired(w))
        paused = w.sinks.throttled["paused"]
        paused.update(ThrottleOptions(every_nth=3))
        w.sinks.reset()
        assert w.run_until(lambda: len(w.sinks.got["paused"]) >= 5)
        got = w.sinks.got["paused"]
        assert all(b - a == 3 for a, b in itertools.pairwise(got))


def test_invalid_options_fail_at_creation_and_wire_errors_are_logged() -> None:
    container = test_container()
    node = TestHandle("sinks", container=container)
    with pytest.raises(InvalidOptionsError):
        ThrottledSubscription(node, String, "t", lambda m: None, options="fast")  # type: ignore[arg-type]
    source_node = TestHandle("source", container=container)
    ThrottledPublisher(source_node, String, "t")
    from efficient_comm_interfaces.msg import ThrottleOption, ThrottleRequest

    bad = ThrottleRequest(subscriber_id="s1", topic="/t",
                          options=[ThrottleOption(name="every_nth", value=0.0)])
    node.inject("/t/_throttle", bad)
    assert any("ignored" in text for level, text in source_node.records if level == "warning")




def test_a_departed_subscriber_stops_costing_at_once_and_is_forgotten() -> None:
    from throttle_publisher.protocol import FORGET_AFTER_S

    with world("test") as w:
        assert w.run_until(lambda: _wired(w))
        gone = w.sinks.throttled["rate"]
        gone.close()
        reply = w.source.out._replies[gone.subscriber_id]
        assert reply.publisher.get_subscription_count() == 0  # nothing is sent for it
        index = w.source.index
        assert w.run_until(lambda: w.source.index >= index + RATE_HZ * (FORGET_AFTER_S + 1),
                           timeout_s=60)
        assert gone.subscriber_id not in w.source.out.requests()
        assert len(w.source.out.requests()) == 2


@pytest.mark.parametrize("backend", ["test", "standalone"])
def test_a_publisher_that_starts_later_learns_every_request(backend: str) -> None:
    topic = unique_topic("camera")
    with ExitStack() as stack:
        if backend == "test":
            container = stack.enter_context(test_container())
            Sinks(TestHandle("sinks", container=container), topic)
            source = Source(TestHandle("source", container=container), topic)

            def spin(timeout_s: float) -> None:
                del timeout_s  # manual time: one source period per step
                container.advance(1.0 / RATE_HZ)

        else:
            domain = isolated_domain_id()
            b = stack.enter_context(Standalone(lambda n: Sinks(n, topic), name="sinks",
                                               domain_id=domain, args=[]))
            b.spin_once(0.1)  # the requests are out before the publisher exists
            a = stack.enter_context(Standalone(lambda n: Source(n, topic), name="source",
                                               domain_id=domain, args=[]))
            source = a.component

            def spin(timeout_s: float) -> None:
                a.spin_once(timeout_s)
                b.spin_once(0)

        w = World()
        w.source, w.spin = source, spin
        assert w.run_until(lambda: len(source.out.requests()) == 3), source.out.requests()
        assert sorted(str(o) for o in source.out.requests().values()) == sorted(
            str(o) for o in (ThrottleOptions(max_rate_hz=5.0), ThrottleOptions(every_nth=10),
                             ThrottleOptions(paused=True))
        )


KILLED_SUBSCRIBER = """
import sys
from std_msgs.msg import String
from efficient_comm import Standalone
from throttle_publisher import ThrottledSubscription, ThrottleOptions
got = []
def viewer(node):
    return ThrottledSubscription(node, String, sys.argv[1], got.append,
                                 options=ThrottleOptions(max_rate_hz=5.0), qos=100)
with Standalone(viewer, name="viewer", args=[]) as v:
    while not got:
        v.spin_once(0.05)
    print("RECEIVING", flush=True)
    while True:
        v.spin_once(0.1)
"""


@pytest.mark.timeout(90)
def test_a_killed_subscriber_stops_costing_within_the_lease(tmp_path: Path) -> None:
    import select
    import signal
    import subprocess
    import sys

    from efficient_comm.testing import ros_env
    from throttle_publisher.protocol import FORGET_AFTER_S

    topic = unique_topic("camera")
    domain = isolated_domain_id()
    with Standalone(lambda n: Source(n, topic), name="source", domain_id=domain,
                    args=[]) as a:
        # The subscriber announces a 2 s lease instead of Fast DDS's 20 s: what is tested
        # is that the source stops writing once DDS drops the peer, not how long it waits.
        profile = short_lease_profile(tmp_path)
        proc = subprocess.Popen([sys.executable, "-c", KILLED_SUBSCRIBER, topic],
                                env={**ros_env(domain),
                                     "FASTRTPS_DEFAULT_PROFILES_FILE": str(profile)},
                                stdout=subprocess.PIPE, text=True, start_new_session=True)
        try:
            assert proc.stdout is not None
            w = World()
            w.source, w.spin = a.component, lambda t: a.spin_once(t)
            replies = a.component.out._replies
            assert w.run_until(
                lambda: any(r.publisher.get_subscription_count() for r in replies.values()),
                timeout_s=30,
            )
            lines: list[str] = []
            stdout = proc.stdout

            def said_receiving() -> bool:
                ready, _, _ = select.select([stdout], [], [], 0)
                if ready:
                    lines.append(stdout.readline().strip())
                return "RECEIVING" in lines

            assert w.run_until(said_receiving, timeout_s=30), lines
            proc.send_signal(signal.SIGKILL)
            proc.wait()
            # Fast DDS drops a killed participant after its lease (2 s here, 20 s by
            # default); from then on nothing is written for it.
            assert w.run_until(
                lambda: not any(r.publisher.get_subscription_count() for r in replies.values()),
                timeout_s=FORGET_AFTER_S,
            )
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
            if proc.stdout is not None:
                proc.stdout.close()
