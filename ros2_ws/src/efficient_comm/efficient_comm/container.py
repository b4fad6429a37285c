"""The Python component container: many components, one process, one thread.

What runs together is decided at deployment: a YAML file (see :mod:`efficient_comm.config`)
or ROS 2 services (``~/load_component``, ``~/unload_component``, ``~/list_components``)
say which component classes to create, under which names, remappings and parameters.
Components created here talk to each other by reference through the container's bus on
its :class:`~efficient_comm.executor.ConsecutiveExecutor`; with ``dds=True`` they are also
full ROS 2 nodes that other processes see and reach.

    with Container("robot") as container:
        container.add(Camera, name="camera")
        container.add(Detector, name="detector", remappings={"image": "/camera/image"})
        container.spin()

Time: the system clock by default, skewed (``clock_offset_s``, ``clock_drift_ppm``) to
stand in for a computer of its own; ``/clock`` from another process with ``sim_time=True``;
in lockstep with that process with ``lockstep="<participant>"`` (:mod:`efficient_comm.simtime`).
"""

from __future__ import annotations

import contextlib
import itertools
import os
import time
import traceback
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import rclpy
from rclpy.context import Context
from rclpy.duration import Duration
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.qos import ReliabilityPolicy

from ._clock import SimClock, SkewedClock, SystemClock
from ._closing import Closing
from ._names import apply_node_remaps, check_node_name, fully_qualified, parse_remaps
from ._signals import interrupt_calls, sigterm_calls
from .bus import Bus
from .composed import ComposedHandle, LocalService, RecordingLogger
from .config import ComponentSpec, parse_file, resolve_factory
from .dds import local_endpoints_ignored, prepare_process
from .errors import ComponentError, ConfigError, DdsSetupError, EfficientCommError
from .executor import ConsecutiveExecutor, GuardMode, Strategy
from .handle import Clock, ClockKind, Logger
from .shm import ShmTransport, enabled_from_env, threshold_from_env
from .simtime import LockstepParticipant, follow_clock
from .stats import StatsSnapshot
from .stats_publisher import DEFAULT_STATS_PERIOD_S, StatsPublisher, check_stats_period


@dataclass(frozen=True)
class LoadedComponent:
    unique_id: int
    full_node_name: str
    class_path: str
    instance: Any
    handle: ComposedHandle


@dataclass
class LoadReport:
    """What a configuration file loaded, and what it could not (with the reason)."""

    loaded: list[LoadedComponent] = field(default_factory=list)
    errors: list[EfficientCommError] = field(default_factory=list)


def _guard_from_env() -> GuardMode:
    value = os.environ.get("EFFICIENT_COMM_GUARD", "").lower()
    return "raise" if value == "raise" else value in ("1", "true", "yes", "on")


class Container(Closing):
    """Hosts components; a context manager that unloads them all on exit.

    Like the components it hosts, a container belongs to one thread: add and unload
    components before spinning or from a callback (the load/unload services do), and
    publish from other threads only (such publishes are queued to the executor thread).
    """

    def __init__(
        self,
        name: str = "container",
        *,
        namespace: str = "/",
        strategy: Strategy = "depth_first",
        dds: bool = True,
        domain_id: int | None = None,
        clock: Clock | None = None,
        guard_mutation: GuardMode | None = None,
        serve: bool = True,
        args: Sequence[str] | None = None,
        stats_period_s: float = DEFAULT_STATS_PERIOD_S,
        stats_namespace: str = "/",
        sim_time: bool = False,
        lockstep: str | None = None,
        lockstep_flush_timeout_s: float = 5.0,
        clock_offset_s: float = 0.0,
        clock_drift_ppm: float = 0.0,
        shm: bool | None = None,
        shm_threshold_bytes: int | None = None,
    ) -> None:
        """``sim_time``: follow ``/clock`` from another process; ``lockstep``: run in
        lockstep with it as the named participant (implies ``sim_time``); see
        :mod:`efficient_comm.simtime`. ``clock_offset_s``, ``clock_drift_ppm``: run on the
        system clock shifted and running fast by that much, as on a separate computer
        (components' ``clock`` and timers; rclpy's own stamps, such as /rosout's, keep the
        true clock). ``lockstep_flush_timeout_s`` bounds each step's wait for DDS readers.
        ``shm``: large messages to and from other processes of this machine through shared
        memory (default: ``EFFICIENT_COMM_SHM``), from arrays of ``shm_threshold_bytes``
        (default: ``EFFICIENT_COMM_SHM_THRESHOLD``, else 64 KiB); see :mod:`efficient_comm.shm`.
        """
        self.name, self.namespace = check_node_name(name, namespace)
        clock = self._choose_clock(clock, dds=dds, sim_time=sim_time or lockstep is not None,
                                   offset_s=clock_offset_s, drift_ppm=clock_drift_ppm)
        try:
            stats_period_s = check_stats_period(stats_period_s)
        except ValueError as exc:
            raise ConfigError(f"container {self.name}: {exc}") from exc
        try:
            check_node_name(f"{self.name}_stats", stats_namespace)
        except ValueError as exc:  # rclpy's text points at the character on a second line
            reason = str(exc).splitlines()[0].rstrip(":")
            raise ConfigError(
                f"container {self.name}: stats_namespace {stats_namespace!r}: {reason}"
            ) from exc
        self.stats_publisher: StatsPublisher | None = None
        self._stats_handle: ComposedHandle | None = None
        self.context: Context | None = None
        self._services: dict[str, LocalService] = {}
        self._components: dict[int, LoadedComponent] = {}
        self._ids = itertools.count(1)
        self._node: Any = None
        logger: Logger = RecordingLogger(fully_qualified(self.name, self.namespace))
        if dds:
            prepare_process(prompt_acks=isinstance(clock, SimClock))  # see efficient_comm.dds
            self.context = Context()
            # Global --ros-args (e.g. __node:=, __ns:= from ros2 launch) apply to the
            # container's own node only; components get theirs from their entries.
            rclpy.init(args=list(args) if args is not None else None, context=self.context,
                       domain_id=domain_id)
            if not local_endpoints_ignored(self.context):
                self.context.try_shutdown()
                raise DdsSetupError(
                    "this process's DDS participant matches its own endpoints, so composed "
                    "subscribers would receive every message twice. Call "
                    "efficient_comm.dds.prepare_process() before the first rclpy.init() "
                    "of the process (and use Fast DDS), or create the container with dds=False."
                )
            self._node = rclpy.create_node(self.name, namespace=self.namespace,
                                           context=self.context)
            self.name, self.namespace = self._node.get_name(), self._node.get_namespace()
            logger = self._node.get_logger()
        self.logger = logger
        self.executor = ConsecutiveExecutor(
            strategy=strategy,
            clock=clock,
            guard_mutation=_guard_from_env() if guard_mutation is None else guard_mutation,
            logger=logger,
        )
        self.bus = Bus(self.executor)
        self.shm: ShmTransport | None = None
        if shm if shm is not None else enabled_from_env():
            self.shm = self._start_shm(shm_threshold_bytes)
        self._rclpy_executor: SingleThreadedExecutor | None = None
        if self.context is not None:
            self._rclpy_executor = SingleThreadedExecutor(context=self.context)
            self._rclpy_executor.add_node(self._node)
            # A guard condition with a callback ends the rclpy wait it is triggered in (see
            # ConsecutiveExecutor.attach_dds); its callback has nothing to do.
            wake = self._node.create_guard_condition(lambda: None)
            self.executor.attach_dds(self._rclpy_executor, wake=wake.trigger)
            if serve:
                from ._services import serve_container

                serve_container(self, self._node)
        self.lockstep: LockstepParticipant | None = None
        if isinstance(clock, SimClock) and self._node is not None:
            if lockstep is not None:  # /clock on the barrier's own node
                self.lockstep = LockstepParticipant(
                    self, lockstep, clock=clock, flush_timeout_s=lockstep_flush_timeout_s
                )
                self.executor.attach_lockstep(self.lockstep)
            else:
                follow_clock(self._node, clock, reliable=False)
        if stats_period_s > 0:
            self._start_stats(stats_period_s, stats_namespace)

    def _start_shm(self, threshold: int | None) -> ShmTransport | None:
        """The shared-memory transport, or None with one log line saying why not."""
        why = "the container has no DDS" if self.context is None else ""
        if not why:
            try:
                return ShmTransport(
                    domain_id=self.context.get_domain_id() if self.context else 0,
                    threshold_bytes=threshold_from_env() if threshold is None else threshold,
                    executor=self.executor,
                )
            except Exception as exc:  # iceoryx2 missing, or refusing (/dev/shm, limits)
                why = f"{type(exc).__name__}: {exc}"
        self.logger.warning(f"container {self.name}: no shared memory ({why}); DDS carries "
                            "every message")
        return None

    def _choose_clock(
        self, clock: Clock | None, *, dds: bool, sim_time: bool, offset_s: float,
        drift_ppm: float,
    ) -> Clock | None:
        what = f"container {self.name}"
        skewed = bool(offset_s or drift_ppm)
        if sim_time:
            if not dds:
                raise ConfigError(f"{what}: sim_time and lockstep need DDS (/clock comes from "
                                  "another process)")
            if clock is not None or skewed:
                raise ConfigError(f"{what}: sim_time and lockstep run on /clock: no clock, "
                                  "clock_offset_s or clock_drift_ppm with them")
            return SimClock()
        if skewed:
            if clock is not None:
                raise ConfigError(f"{what}: clock_offset_s and clock_drift_ppm skew the system "
                                  "clock: not with a clock of your own")
            base = SystemClock()
            return SkewedClock(base, offset_ns=round(offset_s * 1e9), drift_ppm=drift_ppm,
                               epoch_ns=base.now_ns())
        return clock

    def _start_stats(self, period_s: float, namespace: str) -> None:
        """``<stats_namespace>/efficient_comm/stats`` from a handle of the container's own.

        Not a component (``components()`` and the list service do not show it), but a
        composed handle like theirs, so in-process and DDS listeners both count.
        """
        handle = ComposedHandle(
            self, name=f"{self.name}_stats", namespace=namespace, remappings={}, parameters={}
        )
        self._stats_handle = handle
        self.stats_publisher = StatsPublisher(
            handle,
            registry=self.executor.registry,
            period_s=period_s,
            process_name=fully_qualified(self.name, self.namespace),
        )
        if handle.rclpy_node is not None and self._rclpy_executor is not None:
            self._rclpy_executor.add_node(handle.rclpy_node)

    # -- composition ----------------------------------------------------------------------

    def add(
        self,
        factory: Callable[[Any], Any],
        *,
        name: str,
        namespace: str = "/",
        remappings: Mapping[str, str] | Iterable[str] | None = None,
        parameters: Mapping[str, Any] | None = None,
    ) -> Any:
        """Create ``factory(handle)`` as component ``name``; returns the instance."""
        return self._create(
            factory,
            ComponentSpec(
                class_path=getattr(factory, "__qualname__", repr(factory)),
                name=name,
                namespace=namespace,
                remappings=parse_remaps(remappings or {}),
                parameters=dict(parameters or {}),
                source="Container.add",
            ),
        ).instance

    def load(self, spec: ComponentSpec) -> LoadedComponent:
        """Create the component ``spec`` describes; raises ComponentError naming its source."""
        return self._create(resolve_factory(spec), spec)

    def _create(self, factory: Callable[[Any], Any], spec: ComponentSpec) -> LoadedComponent:
        try:
            name, namespace, remaps = apply_node_remaps(
                spec.name, spec.namespace, spec.remappings
            )
            name, namespace = check_node_name(name, namespace)
            fqn = fully_qualified(name, namespace)
            for loaded in self._components.values():
                if loaded.full_node_name == fqn:
                    raise ComponentError(f"node name {fqn} is already taken by {loaded.class_path}")
            handle = ComposedHandle(
                self,
                name=name,
                namespace=namespace,
                remappings=remaps,
                parameters=spec.parameters,
            )
        except EfficientCommError as exc:
            raise ComponentError(f"{spec.source}: {exc}") from exc
        except Exception as exc:  # rclpy refusing something we did not foresee
            raise ComponentError(f"{spec.source}: creating node {spec.name!r}: {exc!r}") from exc
        try:
            instance = factory(handle)
        except Exception as exc:
            handle.close()
            raise ComponentError(
                f"{spec.source}: constructing {spec.class_path} as {fqn} raised {exc!r}\n"
                + traceback.format_exc().rstrip()
            ) from exc
        if handle.rclpy_node is not None and self._rclpy_executor is not None:
            self._rclpy_executor.add_node(handle.rclpy_node)
        loaded = LoadedComponent(next(self._ids), fqn, spec.class_path, instance, handle)
        self._components[loaded.unique_id] = loaded
        return loaded

    def load_file(self, path: str | Path) -> LoadReport:
        """Load every component a container file lists; errors are reported, not raised."""
        report = LoadReport()
        try:
            specs = parse_file(Path(path))
        except ConfigError as exc:
            report.errors.append(exc)
            specs = []
        for spec in specs:
            if isinstance(spec, ConfigError):
                report.errors.append(spec)
                continue
            try:
                report.loaded.append(self.load(spec))
            except EfficientCommError as exc:
                report.errors.append(exc)
        for error in report.errors:
            self.logger.error(str(error))
        return report

    def unload(self, unique_id: int) -> None:
        loaded = self._components.pop(unique_id, None)
        if loaded is None:
            raise ComponentError(f"no component with id {unique_id} in {self.name}")
        close = getattr(loaded.instance, "close", None)
        try:
            if callable(close):
                close()
        finally:
            node = loaded.handle.rclpy_node
            if node is not None and self._rclpy_executor is not None:
                self._rclpy_executor.remove_node(node)
            loaded.handle.close()

    def components(self) -> list[LoadedComponent]:
        return list(self._components.values())

    # -- running --------------------------------------------------------------------------

    def spin(self) -> None:
        """Run until :meth:`shutdown`, Ctrl-C or SIGTERM.

        Ctrl-C stops the loop between two callbacks, as :meth:`shutdown` does (a second
        Ctrl-C interrupts a callback that hangs): a ``KeyboardInterrupt`` raised inside
        rclpy's take ends in a RuntimeError traceback instead (``_signals.interrupt_calls``).

        SIGTERM (what ``ros2 launch``, ``docker stop`` and service managers send) would
        otherwise kill the process with no component's ``close()`` run; here it stops the
        loop as :meth:`shutdown` does, so the ``with`` block unloads every component. (In
        the main thread, unless the program installed a SIGTERM handler of its own.)
        """
        with sigterm_calls(self.shutdown), interrupt_calls(self.shutdown), contextlib.suppress(
            KeyboardInterrupt, ExternalShutdownException
        ):
            if self.lockstep is not None:
                self.lockstep.join()  # a lockstep participant is ready when it spins
            self.executor.spin()

    def spin_once(self, timeout_s: float | None = None) -> None:
        self.executor.spin_once(timeout_s)

    def spin_for(self, duration_s: float) -> None:
        self.executor.spin_for(duration_s)

    def spin_until(self, predicate: Callable[[], bool], *, timeout_s: float) -> bool:
        return self.executor.spin_until(predicate, timeout_s=timeout_s)

    def advance(self, duration_s: float) -> None:
        self.executor.advance(duration_s)

    def stats(self) -> list[StatsSnapshot]:
        return self.executor.stats()

    def flush_dds(self, *, timeout_s: float) -> list[str]:
        """Wait until every matched reliable DDS reader has acknowledged what the
        components wrote; returns the topics whose readers did not within ``timeout_s``.

        What a lockstep step does before acknowledging (:mod:`efficient_comm.simtime`):
        afterwards every message is in its readers' DDS caches. Best-effort writers have
        nothing to wait for.
        """
        late: list[str] = []
        end = time.monotonic() + timeout_s
        for name in sorted(self.bus.topics()):
            for pub in self.bus.publishers(name):
                writer = pub.dds
                if writer is None or pub.qos.reliability != ReliabilityPolicy.RELIABLE:
                    continue
                if not (pub.dds_matched or pub.dds_always):
                    continue  # it wrote nothing to DDS: nobody outside matched it
                left = max(0.0, end - time.monotonic())
                if not writer.wait_for_all_acked(Duration(nanoseconds=round(left * 1e9))):
                    late.append(name)
        return late

    def publisher_nodes(self, topic: str) -> list[str]:
        """The nodes (full names) publishing ``topic`` (a full name) that DDS knows of, in
        any process, this one's included; none without DDS. The graph as discovery has it
        so far: poll it to wait for a peer."""
        if self._node is None:
            return []
        return [_full_name(i) for i in self._node.get_publishers_info_by_topic(topic)]

    def subscriber_nodes(self, topic: str) -> list[str]:
        """The nodes subscribing ``topic``, as :meth:`publisher_nodes` finds publishers."""
        if self._node is None:
            return []
        return [_full_name(i) for i in self._node.get_subscriptions_info_by_topic(topic)]

    def take_dds(self) -> int:
        """Run every callback DDS has ready now, without waiting (a world taking what the
        robots sent in a lockstep step); returns how many ran."""
        return self.executor.take_dds()

    @property
    def clock_kind(self) -> ClockKind:
        """Whether the components' clock runs by itself or only in :meth:`advance`."""
        return self.executor.clock_kind

    def shutdown(self) -> None:
        self.executor.shutdown()

    def close(self) -> None:
        """Unload every component (newest first) and leave DDS.

        An interrupt while one component closes (a second SIGTERM: the parent that stopped
        this process died meanwhile and the kernel sent its death signal) does not skip the
        others: it is raised once every component has closed. A component left open can
        keep the process from ever exiting (a Zenoh session's callback thread is not a
        daemon), and a match's robots outlived their world by hours so.
        """
        interrupted: BaseException | None = None
        for unique_id in sorted(self._components, reverse=True):
            try:
                self.unload(unique_id)
            except Exception as exc:
                self.logger.error(f"unloading component {unique_id} raised {exc!r}")
            except KeyboardInterrupt as exc:
                interrupted = interrupted or exc
        self._leave()
        if interrupted is not None:
            raise interrupted

    def _leave(self) -> None:
        """What :meth:`close` does once the components are unloaded: leave DDS."""
        if self._stats_handle is not None:
            node = self._stats_handle.rclpy_node
            if node is not None and self._rclpy_executor is not None:
                self._rclpy_executor.remove_node(node)
            self._stats_handle.close()
            self._stats_handle = None
        if self.lockstep is not None:
            self.executor.detach_lockstep()
            self.lockstep.close()
        if self._rclpy_executor is not None:
            self.executor.detach_dds()
            self._rclpy_executor.shutdown()
            self._rclpy_executor = None
        if self.shm is not None:
            self.shm.close()
            self.shm = None
        if self._node is not None:
            self._node.destroy_node()
            self._node = None
        if self.context is not None:
            self.context.try_shutdown()


def _full_name(info: Any) -> str:
    """``/ns/name`` of a graph endpoint's node."""
    return f"{info.node_namespace.rstrip('/')}/{info.node_name}"
