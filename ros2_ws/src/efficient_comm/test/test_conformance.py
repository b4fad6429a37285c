"""One suite, three backends: a component behaves the same standalone, composed and under test."""

from __future__ import annotations

import os
import socket
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import pytest
from rcl_interfaces.srv import DescribeParameters, SetParameters
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import Int32, String

from efficient_comm import ParameterError, ServiceFailedError, bind_parameters
from efficient_comm.handle import NodeHandle, ParameterValue
from efficient_comm_interfaces.msg import ExecutorStats
from efficient_comm_interfaces.srv import ListComponents, UnloadComponent

from .conformance import BACKENDS, harness

LATCHED = QoSProfile(
    depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL
)


class Shouter:
    """Upper-cases what it hears; fails on 'boom' (to prove the executor survives)."""

    def __init__(self, node: NodeHandle) -> None:
        self.node = node
        self.prefix = node.declare_parameter("prefix", ">")
        self.gain = node.declare_parameter("gain", 1.0)
        self.rejections = 0
        node.add_on_parameter_change(self._on_change)
        self.out = node.create_publisher(String, "out")
        self.status = node.create_publisher(String, "status", qos=LATCHED)
        self.status.publish(String(data=f"ready {node.fully_qualified_name}"))
        node.create_subscription(String, "in", self._on_in)

    def _on_change(self, changes: Mapping[str, ParameterValue]) -> None:
        gain = changes.get("gain")
        if gain is not None and float(gain) < 0:  # type: ignore[arg-type]
            self.rejections += 1
            raise ValueError("gain must not be negative")
        if "prefix" in changes:
            self.prefix = str(changes["prefix"])

    def _on_in(self, msg: String) -> None:
        if msg.data == "boom":
            raise RuntimeError("boom")
        self.out.publish(String(data=self.prefix + msg.data.upper()))


class Counter:
    """Publishes 0, 1, 2, ... on a timer."""

    def __init__(self, node: NodeHandle) -> None:
        rate = node.declare_parameter("rate_hz", 50.0)
        self.pub = node.create_publisher(String, "count")
        self.n = 0
        node.create_timer(1.0 / rate, self._tick)

    def _tick(self) -> None:
        self.pub.publish(String(data=str(self.n)))
        self.n += 1


class Adder:
    """A service: answers the request's id doubled (any srv type would do)."""

    def __init__(self, node: NodeHandle) -> None:
        node.create_service(UnloadComponent, "double", self._double)

    def _double(self, request: Any, response: Any) -> Any:
        if request.unique_id == 13:
            raise RuntimeError("unlucky")
        response.success = True
        response.error_message = str(request.unique_id * 2)
        return response


@pytest.fixture(params=BACKENDS)
def backend(request: pytest.FixtureRequest) -> str:
    return str(request.param)


def test_messages_flow_through_remapped_names(backend: str) -> None:
    with harness(backend, Shouter, name="shout", namespace="/robot",
                 remappings={"in": "/robot/heard"}) as h:
        out = h.collect("/robot/out", String)
        h.send("/robot/heard", String(data="hello"))
        assert h.wait_for(lambda: len(out) == 1)
        assert out[0].data == ">HELLO"
        assert h.handle.fully_qualified_name == "/robot/shout"


def test_a_raising_callback_does_not_stop_the_others(backend: str) -> None:
    with harness(backend, Shouter) as h:
        out = h.collect("/out", String)
        for text in ("a", "boom", "b"):
            h.send("/in", String(data=text))
        assert h.wait_for(lambda: len(out) == 2)
        assert [m.data for m in out] == [">A", ">B"]


def test_timers_fire_in_order(backend: str) -> None:
    with harness(backend, Counter, parameters={"rate_hz": 100.0}) as h:
        got = h.collect("/count", String)
        assert h.wait_for(lambda: len(got) >= 3)
        values = [int(m.data) for m in got]
        assert values == list(range(values[0], values[0] + len(values)))


def test_parameters_default_override_change_and_reject(backend: str) -> None:
    with harness(backend, Shouter, parameters={"prefix": "#"}) as h:
        node, shouter = h.handle, h.component
        assert node.get_parameter("prefix") == "#"  # deployment override
        assert node.get_parameter("gain") == 1.0  # default
        node.set_parameter("prefix", "!")
        assert shouter.prefix == "!"  # on-change callback ran
        with pytest.raises(ParameterError):
            node.set_parameter("gain", -1.0)  # vetoed by the component
        assert node.get_parameter("gain") == 1.0 and shouter.rejections == 1
        with pytest.raises(ParameterError):
            node.set_parameter("gain", "loud")  # wrong type
        with pytest.raises(ParameterError):
            node.get_parameter("missing")
        with pytest.raises(ParameterError):
            node.declare_parameter("prefix", "again")


def test_transient_local_reaches_late_joiners(backend: str) -> None:
    with harness(backend, Shouter, name="late") as h:
        h.run_for(0.05)
        status = h.collect("/status", String, qos=LATCHED)
        assert h.wait_for(lambda: len(status) == 1)
        assert status[0].data == "ready /late"


def test_services_answer_and_a_failure_is_told_apart_from_an_answer(
    backend: str, capfd: pytest.CaptureFixture[str], caplog: pytest.LogCaptureFixture
) -> None:
    with harness(backend, Adder) as h:
        client = h.client(UnloadComponent, "/double")
        assert h.wait_for(client.service_is_ready)
        bad = client.call_async(UnloadComponent.Request(unique_id=13))
        good = client.call_async(UnloadComponent.Request(unique_id=21))
        assert h.wait_for(good.done)
        assert good.result().success and good.result().error_message == "42"
        assert h.wait_for(bad.done)
        # Same on every backend: the response says the call failed, and why; the server's
        # log names the service and the exception.
        assert bad.exception() is None and not bad.result().success
        assert "/double" in bad.result().error_message
        assert "unlucky" in bad.result().error_message
        logged = capfd.readouterr().err + caplog.text
        assert "service /double" in logged and "RuntimeError: unlucky" in logged, logged


class Lister:
    """A service whose type has no success field: the first call fails, the second works."""

    def __init__(self, node: NodeHandle) -> None:
        self.calls = 0
        node.create_service(ListComponents, "list", self._list)

    def _list(self, request: Any, response: Any) -> Any:
        self.calls += 1
        if self.calls == 1:
            raise RuntimeError("first call fails")
        response.full_node_names = ["/answered"]
        return response


def test_a_failure_of_a_service_without_success_field_is_no_answer(backend: str) -> None:
    with harness(backend, Lister) as h:
        client = h.client(ListComponents, "/list")
        assert h.wait_for(client.service_is_ready)
        bad = client.call_async(ListComponents.Request())
        assert h.wait_for(lambda: h.component.calls == 1)
        good = client.call_async(ListComponents.Request())
        assert h.wait_for(good.done)
        assert list(good.result().full_node_names) == ["/answered"]
        if backend == "test":  # a caller in the same process gets the exception
            assert isinstance(bad.exception(), ServiceFailedError)
            assert "first call fails" in str(bad.exception())
        else:  # an answer to the first call would have arrived before the second's
            assert not bad.done()


class Fussy:
    """Parameter edge cases: declare-time callbacks, lists, bugs in callbacks."""

    def __init__(self, node: NodeHandle) -> None:
        self.seen: list[dict[str, Any]] = []
        self.override_error: Exception | None = None
        node.declare_parameter("first", 1)
        node.add_on_parameter_change(self._on_change)
        node.declare_parameter("ints", [1, 2])
        try:
            node.declare_parameter("rate", 1.0)  # the deployment gives a string
        except ParameterError as exc:
            self.override_error = exc
        self.pub = node.create_publisher(String, "fussy_out")

    def _on_change(self, changes: Mapping[str, ParameterValue]) -> None:
        self.seen.append(dict(changes))
        if "first" in changes and changes["first"] == 13:
            raise KeyError("a bug in the callback")


def test_parameter_edge_cases_agree(backend: str) -> None:
    with harness(backend, Fussy, parameters={"rate": "fast"}) as h:
        node, fussy = h.handle, h.component
        # Declaring counts as setting, as in rclpy: the callback saw the later declaration.
        assert fussy.seen == [{"ints": [1, 2]}]
        assert fussy.override_error is not None
        with pytest.raises(ParameterError):
            node.set_parameter("ints", [1, 2.5])  # mixed lists are no ROS parameter
        with pytest.raises(ParameterError):
            node.set_parameter("first", 13)  # the callback raised something else
        assert node.get_parameter("first") == 1 and node.get_parameter("ints") == [1, 2]


@pytest.mark.parametrize("dds_backend", ["standalone", "composed"])
def test_arrays_set_over_the_parameter_services_reach_the_component_as_lists(
    dds_backend: str,
) -> None:
    """``ros2 param set`` (or a GUI) sets through the node's service: rclpy hands the array
    out as ``array.array``, which compares unequal to the list the component declared."""
    with harness(dds_backend, Fussy) as h:
        client = h.client(SetParameters, "/dut/set_parameters")
        assert h.wait_for(client.service_is_ready)
        request = SetParameters.Request(
            parameters=[Parameter("ints", value=[3, 4]).to_parameter_msg()])
        future = client.call_async(request)
        assert h.wait_for(future.done)
        assert future.result().results[0].successful
        assert h.component.seen[-1] == {"ints": [3, 4]}
        assert h.handle.get_parameter("ints") == [3, 4]


class Labeller:
    """Declares a parameter the deployment gives no value (``-p label:=#``)."""

    def __init__(self, node: NodeHandle) -> None:
        self.error: ParameterError | None = None
        try:
            node.declare_parameter("label", ">")
        except ParameterError as exc:
            self.error = exc


def test_an_override_with_no_value_is_refused_naming_the_parameter(backend: str) -> None:
    with harness(backend, Labeller, parameters={"label": None}) as h:
        assert h.component.error is not None, "a None override was accepted"
        assert "'label'" in str(h.component.error)
        with pytest.raises(ParameterError):
            h.handle.get_parameter("label")  # nothing was declared


def test_subscription_count_tells_whether_anyone_listens(backend: str) -> None:
    with harness(backend, Fussy) as h:
        assert h.component.pub.get_subscription_count() == 0
        h.collect("/fussy_out", String)
        assert h.wait_for(lambda: h.component.pub.get_subscription_count() == 1)


class Caller:
    """Calls /double and raises in its done-callback."""

    def __init__(self, node: NodeHandle) -> None:
        self.client = node.create_client(UnloadComponent, "/double")
        self.answers: list[str] = []

    def ask(self, n: int) -> None:
        def done(future: Any) -> None:
            self.answers.append(future.result().error_message)
            raise RuntimeError("bug in a done-callback")

        self.client.call_async(UnloadComponent.Request(unique_id=n)).add_done_callback(done)


def test_failing_done_callbacks_are_contained(backend: str) -> None:
    with harness(backend, Caller) as h:
        h.serve(Adder)
        caller = h.component
        assert h.wait_for(caller.client.service_is_ready)
        caller.ask(1)
        caller.ask(2)
        assert h.wait_for(lambda: len(caller.answers) == 2)
        assert sorted(caller.answers) == ["2", "4"]


BEST_EFFORT = QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT)


class Prober:
    """Publishes best effort on ``probe``; the capabilities are asked of its handle."""

    def __init__(self, node: NodeHandle) -> None:
        self.pub = node.create_publisher(String, "probe", qos=BEST_EFFORT)


class Elsewhere:
    """Another node's latched publisher."""

    def __init__(self, node: NodeHandle) -> None:
        self.pub = node.create_publisher(Int32, "/elsewhere", qos=LATCHED)


def test_capabilities_names_graph_clock_kind_and_timer_schedule(backend: str) -> None:
    with harness(backend, Prober, name="prober", namespace="/robot",
                 remappings={"probe": "/robot/probed"}, stats_period_s=0.0) as h:
        node: NodeHandle = h.handle
        assert node.resolve_topic_name("probe") == "/robot/probed"
        assert node.resolve_topic_name("x") == "/robot/x"
        assert node.resolve_topic_name("~/x") == "/robot/prober/x"
        assert node.clock_kind == ("manual" if backend == "test" else "system")

        h.serve(Elsewhere)
        assert h.wait_for(lambda: "/elsewhere" in node.graph.topic_names_and_types())
        types = node.graph.topic_names_and_types()
        assert types["/robot/probed"] == ["std_msgs/msg/String"]
        assert types["/elsewhere"] == ["std_msgs/msg/Int32"]
        # The component's own publisher is counted once (in-process and DDS alike).
        assert [q.reliability for q in node.graph.publishers_qos("/robot/probed")] == [
            ReliabilityPolicy.BEST_EFFORT
        ]
        assert h.wait_for(lambda: len(node.graph.publishers_qos("/elsewhere")) == 1)
        (offered,) = node.graph.publishers_qos("/elsewhere")
        assert offered.durability == DurabilityPolicy.TRANSIENT_LOCAL
        assert node.graph.publishers_qos("/nobody") == []

        observed: list[Any] = []
        tap = node.observe_in_process(String, "probe", observed.append)
        if backend == "standalone":
            assert tap is None  # one component a process: nobody else to observe
        else:
            assert tap is not None
            prober: Prober = h.component
            assert prober.pub.get_subscription_count() == 0  # an observer wants nothing
            prober.pub.publish(String(data="seen"))
            assert h.wait_for(lambda: [m.data for m in observed] == ["seen"])
            node.destroy_subscription(tap)
            prober.pub.publish(String(data="not seen"))
            assert [m.data for m in observed] == ["seen"]

        schedule = node.timer_schedule
        if backend == "standalone":
            assert schedule is None  # rclpy's executor does not tell
        else:
            # No timer (the stats topic, which has one, is off here).
            assert schedule is not None and schedule.next_timer_due_ns() is None
            node.create_timer(2.0, lambda: None)
            due = schedule.next_timer_due_ns()
            assert due is not None and 0 < due - schedule.clock.now_ns() <= 2_000_000_000


class Busy:
    """A 20 Hz timer and a subscription that fails on 'boom': something for the stats."""

    def __init__(self, node: NodeHandle) -> None:
        node.create_subscription(String, "in", self._on_in)
        node.create_timer(0.05, self._tick)
        self.ticks = 0

    def _tick(self) -> None:
        self.ticks += 1

    def _on_in(self, msg: String) -> None:
        if msg.data == "boom":
            raise RuntimeError("boom")


def test_callback_statistics_are_published_only_while_someone_listens(backend: str) -> None:
    with harness(backend, Busy, name="busy", namespace="/robot", stats_period_s=0.2) as h:
        h.run_for(0.5)
        assert h.component.ticks > 0
        assert h.stats_publisher.published == 0  # nobody listened: no snapshot was computed
        got = h.collect("/robot/efficient_comm/stats", ExecutorStats)
        h.send("/robot/in", String(data="boom"))
        h.send("/robot/in", String(data="fine"))

        def rows() -> dict[str, Any]:
            """The latest message's rows of /robot/busy by kind, once both calls counted."""
            for msg in reversed(got):
                mine = {c.kind: c for c in msg.callbacks
                        if c.node == "/robot/busy" and c.name != "StatsPublisher._tick"}
                if "subscription" in mine and mine["subscription"].calls == 2:
                    return mine
            return {}

        assert h.wait_for(lambda: bool(rows()) and rows()["timer"].rate_hz > 0)
        assert h.stats_publisher.published >= 1
        msg = got[-1]
        assert msg.pid == os.getpid() and msg.hostname == socket.gethostname()
        assert msg.window_ns > 0 and msg.process_name
        sub, timer = rows()["subscription"], rows()["timer"]
        assert (sub.name, sub.exceptions, sub.drops, sub.period_ns) == ("/robot/in", 1, 0, 0)
        assert timer.period_ns == 50_000_000 and timer.exceptions == 0
        assert timer.calls >= h.component.ticks - 1 > 0
        assert timer.mean_ns > 0 and 0 < timer.p95_ns <= timer.max_ns
        # The publisher's own timer is a callback like the others: being watched shows.
        assert any(c.name == "StatsPublisher._tick" for c in msg.callbacks)
        if backend == "test":  # manual time: every later window of 0.2 s holds 4 ticks
            count = len(got)
            h.run_for(0.4)
            assert len(got) == count + 2
            (tick,) = [c for c in got[-1].callbacks if c.name == "Busy._tick"]
            assert (tick.rate_hz, got[-1].window_ns) == (20.0, 200_000_000)


class Ranged:
    """Declares numeric parameters with ranges, as components with limits do."""

    def __init__(self, node: NodeHandle) -> None:
        self.errors: dict[str, ParameterError] = {}
        self.quality = node.declare_parameter("quality", 80, range=(1, 100))
        self.gain = node.declare_parameter("gain", 1.0, range=(0.0, 2.0, 0.5))
        for name, default, limits in (("from_override", 5, (1, 10)),
                                      ("text", "a", (0, 1)), ("float_ints", 1, (0.0, 1.5))):
            try:
                node.declare_parameter(name, default, range=limits)
            except ParameterError as exc:
                self.errors[name] = exc


def test_ranges_are_enforced_alike_on_every_backend(backend: str) -> None:
    with harness(backend, Ranged, parameters={"from_override": 11}) as h:
        node, ranged = h.handle, h.component
        assert (ranged.quality, ranged.gain) == (80, 1.0)
        assert set(ranged.errors) == {"from_override", "text", "float_ints"}
        assert "'from_override'" in str(ranged.errors["from_override"])
        for name, value in (("quality", 1), ("quality", 100), ("gain", 2.0), ("gain", 0.5)):
            node.set_parameter(name, value)  # the ends and the step grid are allowed
            assert node.get_parameter(name) == value
        for name, value in (("quality", 0), ("quality", 101), ("gain", -0.5), ("gain", 0.7)):
            with pytest.raises(ParameterError, match=name):
                node.set_parameter(name, value)
        assert (node.get_parameter("quality"), node.get_parameter("gain")) == (100, 0.5)


@pytest.mark.parametrize("dds_backend", ["standalone", "composed"])
def test_ranges_reach_the_descriptor_that_tools_describe(dds_backend: str) -> None:
    """What ``ros2 param describe`` and the GUI read: the ranges in the node's descriptor."""
    with harness(dds_backend, Ranged) as h:
        client = h.client(DescribeParameters, "/dut/describe_parameters")
        assert h.wait_for(client.service_is_ready)
        future = client.call_async(DescribeParameters.Request(names=["quality", "gain"]))
        assert h.wait_for(future.done)
        quality, gain = future.result().descriptors
        assert [(r.from_value, r.to_value, r.step) for r in quality.integer_range] == [(1, 100, 0)]
        assert [(r.from_value, r.to_value, r.step)
                for r in gain.floating_point_range] == [(0.0, 2.0, 0.5)]


@dataclass(frozen=True)
class Figures:
    gain: float = 1.0
    count: int = 3
    label: str = "a"

    def check(self) -> None:
        if self.gain <= 0 or self.count > 10 * self.gain:
            raise ValueError(f"gain must be > 0 and count <= 10 * gain: {self}")


class Tuned:
    """Binds a parameter dataclass, as the walk and the kick do."""

    def __init__(self, node: NodeHandle) -> None:
        self.seen: list[Figures] = []
        self.figures = bind_parameters(node, Figures(), check=Figures.check,
                                       on_change=self.seen.append, ranges={"count": (0, 20)})


def test_a_bound_dataclass_is_declared_kept_current_and_vetoed_alike(backend: str) -> None:
    with harness(backend, Tuned, parameters={"count": 5}) as h:
        node, tuned = h.handle, h.component
        assert tuned.figures.value == Figures(gain=1.0, count=5, label="a")  # override wins
        assert [node.get_parameter(n) for n in ("gain", "count", "label")] == [1.0, 5, "a"]
        node.set_parameter("gain", 2.0)
        node.set_parameter("label", "b")
        assert tuned.figures.value == Figures(gain=2.0, count=5, label="b")
        assert tuned.seen[-1] == tuned.figures.value
        with pytest.raises(ParameterError, match="count <= 10"):
            node.set_parameter("gain", 0.1)  # the dataclass's check vetoes the combination
        with pytest.raises(ParameterError, match="count"):
            node.set_parameter("count", 21)  # the declared range
        with pytest.raises(ParameterError):
            node.set_parameter("count", 2.0)  # the field's type
        assert tuned.figures.value == Figures(gain=2.0, count=5, label="b")
        assert node.get_parameter("gain") == 2.0 and len(tuned.seen) == 2


class Misbound:
    def __init__(self, node: NodeHandle) -> None:
        bind_parameters(node, Figures(), check=Figures.check)


def test_a_deployment_the_check_refuses_fails_the_component(backend: str) -> None:
    with pytest.raises(Exception, match="gain must be > 0"), \
            harness(backend, Misbound, parameters={"gain": -1.0}):
        pass
