"""Clock kinds in one process: simulated time (SimClock) on the executor, skewed system
clocks, and the options that choose them. Across processes: tests/test_simtime.py and
tests/test_lockstep.py."""

from __future__ import annotations

import re
import time
from pathlib import Path

import pytest
from rclpy.qos import QoSProfile
from std_msgs.msg import String

from efficient_comm import (
    ConfigError,
    Container,
    ExecutorError,
    SimClock,
    SkewedClock,
    Standalone,
    StepCoordinator,
)
from efficient_comm.bus import Bus
from efficient_comm.dds import LOCKSTEP_HEARTBEAT_NS, _with_ignore_local
from efficient_comm.executor import ConsecutiveExecutor
from efficient_comm.handle import NodeHandle
from efficient_comm.stats import CallbackStats
from efficient_comm.testing import TestHandle, isolated_domain_id

MS = 1_000_000


class Ticker:
    """Remembers the clock's reading at each of its timer's calls."""

    def __init__(self, node: NodeHandle, period_s: float = 0.1) -> None:
        self.node = node
        self.calls: list[int] = []
        node.create_timer(period_s, lambda: self.calls.append(node.clock.now_ns()))


def _timer(executor: ConsecutiveExecutor, period_s: float, calls: list[int]) -> None:
    executor.create_timer(period_s, lambda: calls.append(executor.clock.now_ns()),
                          stats=CallbackStats("n", "timer", "t"), logger=TestHandle().logger)


def test_sim_clock_stands_at_zero_and_never_goes_back() -> None:
    clock = SimClock()
    assert (clock.now_ns(), clock.target_ns, clock.started) == (0, 0, False)
    assert clock.receive(500 * MS)
    assert clock.started and clock.target_ns == 500 * MS
    assert clock.now_ns() == 0  # the executor moves it, timer by timer
    assert not clock.receive(200 * MS)  # a source that restarted: ignored and counted
    assert clock.target_ns == 500 * MS and clock.ignored == 1
    clock.set_ns(300 * MS)
    with pytest.raises(ValueError, match="cannot go back"):
        clock.set_ns(100 * MS)


def test_executor_on_sim_clock_fires_each_timer_at_its_deadline() -> None:
    clock = SimClock()
    executor = ConsecutiveExecutor(clock=clock)
    assert executor.clock_kind == "sim"
    calls: list[int] = []
    _timer(executor, 0.1, calls)
    executor.spin_once(0.0)
    assert calls == []  # no /clock yet: time stands at 0, no wall time counts
    clock.receive(350 * MS)  # what the /clock subscription does
    executor.spin_once(0.0)
    assert calls == [100 * MS, 200 * MS, 300 * MS]
    assert clock.now_ns() == 350 * MS
    with pytest.raises(ExecutorError, match="SimClock moves when /clock says"):
        executor.advance(0.1)


def test_container_options_choose_the_clock() -> None:
    with Container("c", dds=False, clock_offset_s=-3.5, clock_drift_ppm=20.0,
                   stats_period_s=0) as skewed:
        ticker = skewed.add(Ticker, name="ticker")
        assert ticker.node.clock_kind == "system"
        assert isinstance(ticker.node.clock, SkewedClock)
        # Half a second of slack for a loaded machine, against an offset of 3.5 s.
        assert abs(ticker.node.clock.now_ns() - time.time_ns() + 3_500 * MS) < 500 * MS
        assert skewed.spin_until(lambda: len(ticker.calls) >= 2, timeout_s=10)
        assert abs(ticker.calls[-1] - time.time_ns() + 3_500 * MS) < 500 * MS


@pytest.mark.parametrize(
    ("options", "match"),
    [
        ({"sim_time": True, "dds": False}, "need DDS"),
        ({"lockstep": "blue1", "dds": False}, "need DDS"),
        ({"sim_time": True, "clock_offset_s": 1.0}, "no clock, clock_offset_s"),
        ({"clock_offset_s": 1.0, "clock": SimClock(), "dds": False}, "not with a clock"),
    ],
)
def test_bad_clock_options_are_refused(options: dict[str, object], match: str) -> None:
    with pytest.raises(ConfigError, match=match):
        Container("c", stats_period_s=0, **options)  # type: ignore[arg-type]


@pytest.mark.parametrize("name", ["", "1robot", "blue 1", "blue/1"])
def test_bad_participant_names_are_refused(name: str) -> None:
    with pytest.raises(ConfigError, match="participant name"):
        Container("c", lockstep=name, stats_period_s=0)
    with pytest.raises(ConfigError, match="participant name"):
        StepCoordinator([name])


def test_container_and_standalone_tell_components_sim_time() -> None:
    domain = isolated_domain_id()
    with Container("c", sim_time=True, stats_period_s=0, domain_id=domain) as container:
        ticker = container.add(Ticker, name="ticker")
        assert ticker.node.clock_kind == "sim" and container.clock_kind == "sim"
        assert ticker.node.clock.now_ns() == 0  # before the first /clock message
    with Standalone(Ticker, name="ticker", sim_time=True, domain_id=domain) as node:
        assert node.handle.clock_kind == "sim"
        assert node.handle.clock.now_ns() == 0
    with Standalone(Ticker, name="ticker", domain_id=domain) as node:
        assert node.handle.clock_kind == "system"


def test_lockstep_processes_acknowledge_heartbeats_at_once(tmp_path: Path) -> None:
    """Each step waits for its messages' acknowledgements: Fast DDS's default 5 ms delay
    before a reader answers a heartbeat was most of a step (efficient_comm.dds)."""
    plain = _with_ignore_local(None)
    prompt = _with_ignore_local(None, prompt_acks=True)
    assert "heartbeatResponseDelay" not in plain
    assert re.search(r"<heartbeatResponseDelay><sec>0</sec><nanosec>0</nanosec>", prompt)
    own = tmp_path / "own.xml"  # a user's own default reader profile is left alone
    own.write_text('<profiles><data_reader profile_name="mine" is_default_profile="true">'
                   "<topic><historyQos><kind>KEEP_ALL</kind></historyQos></topic>"
                   "</data_reader></profiles>")
    kept = _with_ignore_local(own, prompt_acks=True)
    assert "heartbeatResponseDelay" not in kept and "KEEP_ALL" in kept


def test_lockstep_processes_send_heartbeats_while_a_step_waits(tmp_path: Path) -> None:
    """A reader acknowledges on a heartbeat; Fast DDS's writers send one every 3 s unless
    told otherwise (tests/test_lockstep.py has a plain reader that this held)."""
    plain = _with_ignore_local(None)
    prompt = _with_ignore_local(None, prompt_acks=True)
    assert "heartbeatPeriod" not in plain
    ns = f"{LOCKSTEP_HEARTBEAT_NS % 1_000_000_000}"
    assert re.search(rf"<data_writer [^>]*><times><heartbeatPeriod><sec>0</sec>"
                     rf"<nanosec>{ns}</nanosec>", prompt), prompt
    own = tmp_path / "own.xml"  # a user's own default writer profile is left alone
    own.write_text('<profiles><data_writer profile_name="mine" is_default_profile="true">'
                   "<times><heartbeatPeriod><sec>1</sec></heartbeatPeriod></times>"
                   "</data_writer></profiles>")
    kept = _with_ignore_local(own, prompt_acks=True)
    assert kept.count("heartbeatPeriod>") == 2 and "<sec>1</sec>" in kept
    assert "heartbeatResponseDelay" in kept  # the reader's default is still added


class _Participant:
    """The barrier's participant end as the executor sees it, without DDS."""

    def __init__(self) -> None:
        self.joined = True
        self.intake_due: int | None = None
        self.last_intake_ns = -1
        self.acks: list[tuple[str, int]] = []

    def take(self) -> int:
        return 0  # no DDS readers: the test calls receive_remote as they would

    def wait(self, timeout_s: float) -> None:
        pass

    def wake(self) -> None:
        pass

    def done_intake(self, t_ns: int) -> None:
        self.acks.append(("intake", t_ns))

    def done_step(self, t_ns: int) -> None:
        self.acks.append(("step", t_ns))

    def step_started(self, start_ns: int) -> None:
        self.acks.append(("start", start_ns))  # the hooks of links outside DDS run here


def _lockstep_bus() -> tuple[SimClock, ConsecutiveExecutor, _Participant, Bus]:
    """An executor on simulated time attached to a recording lockstep participant, and a
    bus on it: what a container in lockstep has, without DDS."""
    clock = SimClock()
    executor = ConsecutiveExecutor(clock=clock)
    participant = _Participant()
    executor.attach_lockstep(participant)  # type: ignore[arg-type]
    return clock, executor, participant, Bus(executor)


def test_lockstep_holds_remote_messages_until_an_intake_and_delivers_them_in_order() -> None:
    clock, executor, participant, bus = _lockstep_bus()
    heard: list[str] = []
    logger = TestHandle().logger
    subs = {
        name: (bus.add_subscription(
            name, String, lambda m: heard.append(m.data), QoSProfile(depth=2),
            stats=CallbackStats("n", "subscription", name), logger=logger,
        ),)
        for name in ("/b", "/a")
    }
    for topic, data in [("/b", "b1"), ("/a", "a1"), ("/b", "b2"), ("/b", "b3")]:
        executor.receive_remote(subs[topic], String(data=data))  # what DDS readers call
    executor.spin_once(0.0)
    assert heard == [] and participant.acks == []  # held: no intake yet
    participant.intake_due = 0
    executor.spin_once(0.0)
    assert heard == [] and participant.acks == [("intake", 0)]  # taken in, nothing runs
    executor.receive_remote(subs["/a"], String(data="a2"))  # too late for this step
    clock.receive(10 * MS)
    executor.spin_once(0.0)
    # By topic name, each in arrival order; /b kept its depth (2): b1 dropped and counted.
    assert heard == ["a1", "b2", "b3"]
    assert subs["/b"][0].stats.dropped == 1
    assert participant.acks[-2:] == [("start", 0), ("step", 10 * MS)]
    participant.intake_due = 10 * MS
    clock.receive(20 * MS)
    executor.spin_once(0.0)
    assert heard[3:] == ["a2"] and participant.acks[-1] == ("step", 20 * MS)


def test_a_step_without_an_intake_round_takes_its_inbox_first() -> None:
    """One round (a coordinator's only participant): /clock implies the intake, so what
    was held before it is delivered in this step, and only the step is acknowledged."""
    clock, executor, participant, bus = _lockstep_bus()
    heard: list[str] = []
    sub = bus.add_subscription(
        "/a", String, lambda m: heard.append(m.data), QoSProfile(depth=5),
        stats=CallbackStats("n", "subscription", "/a"), logger=TestHandle().logger,
    )
    executor.receive_remote((sub,), String(data="a1"))
    executor.spin_once(0.0)
    assert heard == []  # held until the step
    clock.receive(10 * MS)
    executor.spin_once(0.0)
    assert heard == ["a1"] and participant.acks == [("start", 0), ("step", 10 * MS)]
    assert participant.last_intake_ns == 0
    executor.receive_remote((sub,), String(data="a2"))  # sent in the step: the next one's
    clock.receive(20 * MS)
    executor.spin_once(0.0)
    assert heard == ["a1", "a2"] and participant.acks[-1] == ("step", 20 * MS)


def test_a_coordinator_of_one_participant_has_one_round() -> None:
    with StepCoordinator(["solo"], domain_id=isolated_domain_id()) as one, \
            StepCoordinator(["a", "b"], domain_id=isolated_domain_id()) as two:
        assert one.one_round and not two.one_round
