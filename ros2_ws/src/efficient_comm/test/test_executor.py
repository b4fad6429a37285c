"""The consecutive executor: order, queues, timers, failures and statistics."""

from __future__ import annotations

import threading

import pytest
from rclpy.qos import QoSProfile
from std_msgs.msg import String

from efficient_comm import ExecutorError, ManualClock
from efficient_comm.executor import MAX_NESTING, ConsecutiveExecutor
from efficient_comm.handle import NodeHandle
from efficient_comm.testing import TestHandle, test_container


class Relay:
    """Logs what it hears into a shared journal and forwards it, tagged."""

    def __init__(self, node: NodeHandle, *, src: str, dst: str | None, journal: list[str]) -> None:
        self.name = node.name
        self.journal = journal
        self.pub = node.create_publisher(String, dst) if dst else None
        node.create_subscription(String, src, self.on_msg)

    def on_msg(self, msg: String) -> None:
        self.journal.append(f"{self.name}:{msg.data}")
        if self.pub is not None:
            self.pub.publish(String(data=msg.data + "+"))


def _fan(strategy: str) -> list[str]:
    """a -> (b -> d), (c); returns the order in which callbacks ran."""
    container = test_container(strategy=strategy)  # type: ignore[arg-type]
    journal: list[str] = []
    for name, src, dst in [("b", "a", "bd"), ("c", "a", None), ("d", "bd", None)]:
        Relay(TestHandle(name, container=container), src=src, dst=dst, journal=journal)
    TestHandle("src", container=container).inject("/a", String(data="x"))
    return journal


def test_depth_first_runs_downstream_before_siblings() -> None:
    assert _fan("depth_first") == ["b:x", "d:x+", "c:x"]


def test_breadth_first_runs_siblings_before_downstream() -> None:
    assert _fan("breadth_first") == ["b:x", "c:x", "d:x+"]


def test_depth_first_delivers_inside_publish() -> None:
    node = TestHandle()
    seen: list[str] = []
    node.create_subscription(String, "t", lambda m: seen.append(m.data))
    pub = node.create_publisher(String, "t")
    pub.publish(String(data="now"))
    assert seen == ["now"]  # no spin needed: the callback ran inside publish()


def test_by_reference_every_subscriber_gets_the_same_object() -> None:
    container = test_container()
    node = TestHandle(container=container)
    got: list[object] = []
    for _ in range(3):
        node.create_subscription(String, "t", got.append)
    msg = String(data="shared")
    node.create_publisher(String, "t").publish(msg)
    assert len(got) == 3 and all(m is msg for m in got)


def test_queue_depth_drops_oldest_and_counts() -> None:
    container = test_container(strategy="breadth_first")
    node = TestHandle(container=container)
    seen: list[str] = []
    node.create_subscription(String, "t", lambda m: seen.append(m.data), qos=2)
    pub = node.create_publisher(String, "t")
    for i in range(5):
        pub.publish(String(data=str(i)))
    node.spin_some()
    assert seen == ["3", "4"]
    (stats,) = [s for s in container.stats() if s.kind == "subscription"]
    assert stats.dropped == 3 and stats.calls == 2


def test_cycles_fall_back_to_queueing_instead_of_overflowing_the_stack() -> None:
    node = TestHandle()
    pub = node.create_publisher(String, "loop")
    count = 0

    def again(msg: String) -> None:
        nonlocal count
        count += 1
        if count < 3 * MAX_NESTING:
            pub.publish(msg)

    node.create_subscription(String, "loop", again, qos=QoSProfile(depth=1000))
    pub.publish(String(data="spin"))
    node.spin_some()
    assert count == 3 * MAX_NESTING


def test_exceptions_are_logged_counted_and_do_not_stop_others() -> None:
    node = TestHandle()
    seen: list[str] = []

    def bad(_msg: String) -> None:
        raise ValueError("broken component")

    node.create_subscription(String, "t", bad)
    node.create_subscription(String, "t", lambda m: seen.append(m.data))
    node.inject("t", String(data="1"), String(data="2"))
    assert seen == ["1", "2"]
    failing = [s for s in node.container.stats() if s.exceptions]
    assert len(failing) == 1 and failing[0].exceptions == 2
    assert any("broken component" in text for level, text in node.records if level == "error")


def test_timers_on_a_manual_clock_are_exact_and_cancellable() -> None:
    node = TestHandle()
    ticks: list[int] = []
    timer = node.create_timer(0.1, lambda: ticks.append(node.now_ns()))
    node.advance(0.35)
    assert ticks == [100_000_000, 200_000_000, 300_000_000]
    timer.cancel()
    node.advance(1.0)
    assert len(ticks) == 3 and timer.is_canceled()
    timer.reset()
    node.advance(0.1)
    assert len(ticks) == 4


def test_stats_record_own_time_calls_and_rate() -> None:
    import time

    node = TestHandle()
    pub = node.create_publisher(String, "t")

    def slow(_msg: String) -> None:
        end = time.perf_counter_ns() + 2_000_000  # 2 ms of "work"
        while time.perf_counter_ns() < end:
            pass

    node.create_subscription(String, "t", slow)
    node.create_timer(0.01, lambda: pub.publish(String()))
    node.advance(0.1)
    by_kind = {s.kind: s for s in node.container.stats()}
    timer, sub = by_kind["timer"], by_kind["subscription"]
    assert timer.calls == 10 and sub.calls == 10
    # Rates come from the executor's clock, manual here: exactly 100 Hz.
    assert timer.rate_hz == pytest.approx(100.0) and sub.rate_hz == pytest.approx(100.0)
    # The subscriber ran inside the timer's publish; the timer's own time excludes it.
    assert sub.mean_ns >= 2_000_000 > timer.mean_ns


def test_publish_from_another_thread_is_queued_to_the_executor_thread() -> None:
    container = test_container()
    container.executor.clock = ManualClock()
    node = TestHandle(container=container)
    seen: list[int] = []
    node.create_subscription(String, "t", lambda m: seen.append(threading.get_ident()))
    pub = node.create_publisher(String, "t")
    done = threading.Event()
    spinning = threading.Event()
    spinner_id: list[int] = []

    def spin() -> None:
        spinner_id.append(threading.get_ident())
        container.executor.spin_until(lambda: bool(seen), timeout_s=10)
        done.set()

    container.executor.post(spinning.set)  # runs once the worker owns the executor
    thread = threading.Thread(target=spin)
    thread.start()
    assert spinning.wait(10)
    pub.publish(String(data="x"))  # from this (foreign) thread: queued, not run here
    assert done.wait(10)
    thread.join()
    assert seen == spinner_id


def test_advance_needs_a_manual_clock_and_strategy_is_checked() -> None:
    with pytest.raises(ExecutorError):
        ConsecutiveExecutor().advance(1.0)
    with pytest.raises(ExecutorError):
        ConsecutiveExecutor(strategy="random")  # type: ignore[arg-type]


def test_a_late_transient_local_joiner_sees_history_before_newer_messages() -> None:
    from rclpy.qos import DurabilityPolicy

    latched = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
    node = TestHandle()
    pub = node.create_publisher(String, "map", qos=latched)
    pub.publish(String(data="v1"))
    got: list[str] = []
    node.create_subscription(String, "map", lambda m: got.append(m.data), qos=latched)
    pub.publish(String(data="v2"))  # before any spin: the history must still come first
    node.spin_some()
    assert got == ["v1", "v2"]


def test_unloaded_components_are_dead() -> None:
    from efficient_comm import ComponentError

    container = test_container()
    talker = TestHandle("talker", container=container)
    listener = TestHandle("listener", container=container)
    got: list[str] = []
    listener.create_subscription(String, "t", lambda m: got.append(m.data))
    pub = talker.create_publisher(String, "t")
    timer = talker.create_timer(0.1, lambda: pub.publish(String(data="tick")))
    talker.close()
    with pytest.raises(ComponentError):
        pub.publish(String(data="after unload"))
    with pytest.raises(ExecutorError):
        timer.reset()
    container.advance(1.0)
    assert got == []


def test_next_timer_due_is_the_earliest_deadline_and_readable_from_another_thread() -> None:
    container = test_container(stats_period_s=0)  # no stats timer: only the test's own
    executor = container.executor
    assert executor.next_timer_due_ns() is None
    node = TestHandle(container=container)
    node.create_timer(0.5, lambda: None)
    node.create_timer(0.2, lambda: None)
    assert executor.next_timer_due_ns() == 200_000_000
    node.advance(0.2)  # the 0.2 s timer ran and is due again at 0.4 s
    seen: list[int | None] = []
    reader = threading.Thread(target=lambda: seen.append(executor.next_timer_due_ns()))
    reader.start()
    reader.join(5)
    assert seen == [400_000_000]


def test_a_clock_set_far_ahead_skips_the_missed_periods_of_older_timers() -> None:
    container = test_container(stats_period_s=0)
    node = TestHandle(container=container)
    ticks: list[int] = []
    node.create_timer(1.0, lambda: ticks.append(container.executor.clock.now_ns()))
    clock = container.executor.clock
    assert isinstance(clock, ManualClock)
    clock.set_ns(10**18)  # a simulated epoch; a billion periods after the timer's deadline
    node.advance(1.5)
    assert ticks == [10**18, 10**18 + 1_000_000_000]  # once for all missed, then in phase
