"""The standalone backend: one component as its own ROS 2 node and process.

This is what ``ros2 run`` starts. A package exposes a component with a console script::

    # setup.py: entry_points={"console_scripts": ["camera = my_pkg.camera:main"]}
    main = standalone_main(Camera, name="camera")

or runs any component without writing one::

    ros2 run efficient_comm standalone my_pkg.camera:Camera --ros-args -r image:=/cam/image

``--ros-args`` work as for any rclpy node: ``-r`` remaps (``__node:=``/``__ns:=`` too),
``-p`` parameters and ``--params-file``. The handle hands rclpy's own publishers back, so
a standalone component pays nothing for the indirection; callbacks are timed into the same
statistics the consecutive executor keeps.
"""

from __future__ import annotations

import argparse
import contextlib
import inspect
import sys
import time
from collections.abc import Callable, Sequence
from typing import Any, cast

import rclpy
from rclpy.context import Context
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.utilities import remove_ros_args

from ._closing import Closing
from ._failures import failure_outcome, failure_response, report_failure, without_answer
from ._future import Future
from ._graph import NodeGraph
from ._params import ParameterMethods, RclpyParameters
from ._qos import lost_events, to_profile
from ._signals import interrupt_calls, stop_on_sigterm
from .config import ComponentSpec, resolve_factory
from .errors import ComponentError
from .handle import (
    Client,
    Clock,
    ClockKind,
    Logger,
    MessageCallback,
    Publisher,
    QoSLike,
    Service,
    Subscription,
    Timer,
)
from .shm import enabled_from_env as shm_enabled_from_env
from .stats import CallbackKind, CallbackStats, StatsRegistry, StatsSnapshot
from .stats_publisher import DEFAULT_STATS_PERIOD_S, StatsPublisher, check_stats_period

#: Longest wait of an idle standalone node before Python's signal handlers get to run.
SIGNAL_CHECK_S = 0.1


class _NodeClock:
    """The rclpy node's clock; under ``use_sim_time`` it never reads a time earlier than
    one it already read (rclpy's would follow a /clock that went back)."""

    __slots__ = ("_clock", "_last")

    def __init__(self, node: Node) -> None:
        self._clock = node.get_clock()
        self._last = 0

    def now_ns(self) -> int:
        now = int(self._clock.now().nanoseconds)
        if now < self._last and getattr(self._clock, "ros_time_is_active", False):
            return self._last
        self._last = now
        return now


class StandaloneHandle(ParameterMethods):
    """A node handle over a real rclpy node."""

    def __init__(self, node: Node, *, registry: StatsRegistry | None = None) -> None:
        self.rclpy_node = node
        self.registry = registry or StatsRegistry()
        self._params = RclpyParameters(node)
        self._clock = _NodeClock(node)

    @property
    def name(self) -> str:
        return self.rclpy_node.get_name()

    @property
    def namespace(self) -> str:
        return self.rclpy_node.get_namespace()

    @property
    def fully_qualified_name(self) -> str:
        return self.rclpy_node.get_fully_qualified_name()

    @property
    def logger(self) -> Logger:
        return cast(Logger, self.rclpy_node.get_logger())

    @property
    def clock(self) -> Clock:
        return self._clock

    # -- capabilities --------------------------------------------------------------------

    @property
    def clock_kind(self) -> ClockKind:
        """"sim" under ``use_sim_time`` (rclpy's own: ``-p use_sim_time:=true`` or
        ``Standalone(sim_time=True)``; time stands at 0 until /clock), else "system"."""
        return "sim" if self.rclpy_node.get_parameter("use_sim_time").value else "system"

    @property
    def graph(self) -> NodeGraph:
        return NodeGraph(bus=None, node=self.rclpy_node)

    @property
    def timer_schedule(self) -> None:
        """rclpy's executor keeps its timers to itself."""
        return None

    def resolve_topic_name(self, topic: str) -> str:
        return str(self.rclpy_node.resolve_topic_name(topic))

    def observe_in_process(
        self, msg_type: type, topic: str, callback: MessageCallback
    ) -> None:
        """One component a process: there is nobody else in it to observe."""
        return None

    def _timed(
        self, kind: CallbackKind, name: str, callback: Callable[..., Any], *, period_ns: int = 0
    ) -> Callable[..., Any]:
        """Record time and frequency, and log (not propagate) exceptions, like composed."""
        stats = self.registry.add(self.fully_qualified_name, kind, name, period_ns=period_ns)
        return self._guarded(stats, callback)

    def _guarded(
        self,
        stats: CallbackStats,
        callback: Callable[..., Any],
        *,
        what: str = "",
        on_failure: Callable[[BaseException], Any] | None = None,
    ) -> Callable[..., Any]:
        logger = self.logger
        what = what or f"{stats.kind} {stats.name}"

        def timed(*args: Any) -> Any:
            start = time.perf_counter_ns()
            try:
                return callback(*args)
            except Exception as exc:
                report_failure(stats, logger, what, time.monotonic_ns())
                return on_failure(exc) if on_failure is not None else None
            finally:
                stats.record(start, time.perf_counter_ns() - start)

        return timed

    def create_publisher(self, msg_type: type, topic: str, *, qos: QoSLike = 10) -> Publisher:
        return self.rclpy_node.create_publisher(msg_type, topic, to_profile(qos))

    def create_subscription(
        self, msg_type: type, topic: str, callback: MessageCallback, *, qos: QoSLike = 10,
        on_lost: Callable[[int], None] | None = None,
    ) -> Subscription:
        name = self.rclpy_node.resolve_topic_name(topic)
        return self.rclpy_node.create_subscription(
            msg_type, topic, self._timed("subscription", name, callback), to_profile(qos),
            event_callbacks=lost_events(on_lost),
        )

    def create_timer(self, period_s: float, callback: Callable[[], None]) -> Timer:
        if not period_s > 0:
            raise ValueError(f"timer period must be positive, got {period_s!r}")
        name = getattr(callback, "__qualname__", "")
        return self.rclpy_node.create_timer(
            period_s, self._timed("timer", name, callback, period_ns=round(period_s * 1e9))
        )

    def create_service(
        self, srv_type: type, name: str, callback: Callable[[Any, Any], Any]
    ) -> Service:
        full = self.rclpy_node.resolve_service_name(name)
        stats = self.registry.add(self.fully_qualified_name, "service", full)
        timed = self._guarded(
            stats, callback, what=f"service {full} ({failure_outcome(srv_type)})",
            on_failure=lambda exc: failure_response(srv_type, full, exc),
        )
        service = self.rclpy_node.create_service(srv_type, name, timed)
        without_answer(service)  # a failure without a failure response stays unanswered
        return service

    def create_client(self, srv_type: type, name: str) -> Client:
        return StandaloneClient(self, srv_type, name)

    def destroy_publisher(self, publisher: Publisher) -> None:
        self.rclpy_node.destroy_publisher(publisher)  # type: ignore[arg-type]

    def destroy_subscription(self, subscription: Subscription) -> None:
        self.rclpy_node.destroy_subscription(subscription)  # type: ignore[arg-type]

    def destroy_timer(self, timer: Timer) -> None:
        self.rclpy_node.destroy_timer(timer)  # type: ignore[arg-type]



class StandaloneClient:
    """An rclpy client whose futures run done-callbacks like every other callback."""

    def __init__(self, handle: StandaloneHandle, srv_type: type, name: str) -> None:
        self._client = handle.rclpy_node.create_client(srv_type, name)
        self._handle = handle
        self._name = self._client.srv_name
        self._stats = handle.registry.add(handle.fully_qualified_name, "client", self._name)

    @property
    def srv_name(self) -> str:
        return self._name

    def service_is_ready(self) -> bool:
        return self._client.service_is_ready()

    def call_async(self, request: Any, /) -> Future:
        future = Future(
            lambda callback, done: self._handle._guarded(self._stats, callback)(done)
        )
        self._client.call_async(request).add_done_callback(
            lambda done: future.set_result(done.result())
        )
        return future


class Standalone(Closing):
    """One component on its own rclpy context, node and executor (a context manager).

    ``args`` are command-line arguments (``--ros-args`` ones are honoured).
    """

    def __init__(
        self,
        factory: Callable[[Any], Any],
        *,
        name: str,
        namespace: str | None = None,
        args: Sequence[str] | None = None,
        domain_id: int | None = None,
        stats_period_s: float = DEFAULT_STATS_PERIOD_S,
        sim_time: bool = False,
    ) -> None:
        """``sim_time``: follow /clock (rclpy's ``use_sim_time``; lockstep needs a container)."""
        check_stats_period(stats_period_s)
        self.stats_publisher: StatsPublisher | None = None
        self.context = Context()
        rclpy.init(args=list(args) if args is not None else None, context=self.context,
                   domain_id=domain_id)
        try:
            overrides = [Parameter("use_sim_time", value=True)] if sim_time else []
            self.node = Node(name, namespace=namespace, context=self.context,
                             parameter_overrides=overrides)
            self.handle = StandaloneHandle(self.node)
            if shm_enabled_from_env():  # what a user who set it for every process expects
                self.node.get_logger().warning(
                    "no shared memory for a standalone node (EFFICIENT_COMM_SHM is set); DDS "
                    "carries its topics: run it in a container (`ros2 run efficient_comm "
                    "container --config FILE`) for shared memory")
            # Declared before the component exists, so its parameter callbacks never see it.
            period_s = self._stats_period(stats_period_s)
            try:
                self.component = factory(self.handle)
            except Exception as exc:
                raise ComponentError(
                    f"constructing {getattr(factory, '__qualname__', factory)} as "
                    f"{self.node.get_fully_qualified_name()} raised {exc!r}"
                ) from exc
            if period_s > 0:
                self.stats_publisher = StatsPublisher(
                    self.handle,
                    registry=self.handle.registry,
                    period_s=period_s,
                    process_name=self.node.get_fully_qualified_name(),
                )
            self.executor = SingleThreadedExecutor(context=self.context)
            self.executor.add_node(self.node)
        except BaseException:
            self.context.try_shutdown()
            raise

    def _stats_period(self, default_s: float) -> float:
        """The ``stats_period_s`` parameter: how often ``<node namespace>/efficient_comm/stats``
        is published (``-p stats_period_s:=0.0`` turns it off)."""
        try:
            return check_stats_period(
                self.handle.declare_parameter("stats_period_s", float(default_s))
            )
        except ValueError as exc:
            raise ComponentError(f"{self.node.get_fully_qualified_name()}: {exc}") from exc

    def spin(self) -> None:
        """Run until Ctrl-C, SIGTERM or :meth:`close` from another thread.

        Waits are bounded (:data:`SIGNAL_CHECK_S`): rclpy installs no signal handler for a
        context of our own, so Python's handlers, which run only between waits, are what
        stop the node; an unbounded wait of an idle node would never let them run.
        """
        interrupted = False

        def stop() -> None:  # the first Ctrl-C: between two callbacks (see interrupt_calls)
            nonlocal interrupted
            interrupted = True

        with interrupt_calls(stop), contextlib.suppress(
            KeyboardInterrupt, ExternalShutdownException
        ):
            while self.context.ok() and not interrupted:
                self.executor.spin_once(timeout_sec=SIGNAL_CHECK_S)

    def spin_once(self, timeout_s: float | None = None) -> None:
        self.executor.spin_once(timeout_sec=timeout_s)

    def stats(self) -> list[StatsSnapshot]:
        return self.handle.registry.snapshot()

    def close(self) -> None:
        close = getattr(self.component, "close", None) if hasattr(self, "component") else None
        try:
            if callable(close):
                close()
        finally:
            self.executor.shutdown()
            self.node.destroy_node()
            self.context.try_shutdown()



def run_standalone(
    factory: Callable[[Any], Any], *, name: str, args: Sequence[str] | None = None
) -> int:
    """Run ``factory`` as a standalone node until interrupted; returns an exit code.

    What a console script's ``main`` does (see :func:`standalone_main`), for commands that
    parse options of their own first: a bad component prints one ``error:`` line (1).
    """
    stop_on_sigterm()
    try:
        with Standalone(factory, name=name, args=sys.argv if args is None else args) as node:
            node.spin()
    except ComponentError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        pass  # interrupted while starting: the with-block has cleaned up
    return 0


def standalone_main(factory: Callable[[Any], Any], *, name: str) -> Callable[[], int]:
    """A console-script ``main`` that runs ``factory`` as node ``name``.

    Its command line takes ``--ros-args ...`` and ``--help``, nothing else: ``--help``
    prints what the node is and how to configure it and exits 0 before anything starts;
    an argument of another kind is refused with one line and exit status 2 (argparse's).
    """

    def main(argv: Sequence[str] | None = None) -> int:
        args = list(sys.argv if argv is None else [name, *argv])
        doc = (inspect.getdoc(inspect.getmodule(factory)) or factory.__doc__ or "").strip()
        parser = argparse.ArgumentParser(
            prog=name, usage=f"{name} [-h] [--ros-args ...]",
            description=doc.split("\n\n")[0] if doc else None,
            epilog="ROS arguments: --ros-args -p NAME:=VALUE (parameters), -r FROM:=TO "
            "(remapping), --params-file FILE.",
        )
        parser.parse_args(remove_ros_args(args)[1:])
        return run_standalone(factory, name=name, args=args)

    return main


def cli(argv: Sequence[str] | None = None) -> int:
    """``standalone CLASS_PATH [--name NAME] [--ros-args ...]``: any component, own node."""
    argv = list(sys.argv if argv is None else argv)
    parser = argparse.ArgumentParser(prog="standalone", description=cli.__doc__)
    parser.add_argument("class_path", help="module:Class or an efficient_comm.components entry")
    parser.add_argument("--name", help="node name (default: the class name in snake_case)")
    options = parser.parse_args(remove_ros_args(argv)[1:])
    spec = ComponentSpec(class_path=options.class_path, name=options.name or "", source="cli")
    try:
        factory = resolve_factory(spec)
    except ComponentError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    default = "".join(
        "_" + c.lower() if c.isupper() else c for c in getattr(factory, "__name__", "node")
    ).lstrip("_")
    return run_standalone(factory, name=options.name or default, args=argv)
