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
"""

from __future__ import annotations

import contextlib
import itertools
import os
import traceback
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import rclpy
from rclpy.context import Context
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor

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
    ) -> None:
        self.name, self.namespace = check_node_name(name, namespace)
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
            prepare_process()
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
        if stats_period_s > 0:
            self._start_stats(stats_period_s, stats_namespace)

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

    @property
    def clock_kind(self) -> ClockKind:
        """Whether the components' clock runs by itself or only in :meth:`advance`."""
        return self.executor.clock_kind

    def shutdown(self) -> None:
        self.executor.shutdown()

    def close(self) -> None:
        """Unload every component (newest first) and leave DDS."""
        for unique_id in sorted(self._components, reverse=True):
            try:
                self.unload(unique_id)
            except Exception as exc:
                self.logger.error(f"unloading component {unique_id} raised {exc!r}")
        if self._stats_handle is not None:
            node = self._stats_handle.rclpy_node
            if node is not None and self._rclpy_executor is not None:
                self._rclpy_executor.remove_node(node)
            self._stats_handle.close()
            self._stats_handle = None
        if self._rclpy_executor is not None:
            self.executor.detach_dds()
            self._rclpy_executor.shutdown()
            self._rclpy_executor = None
        if self._node is not None:
            self._node.destroy_node()
            self._node = None
        if self.context is not None:
            self.context.try_shutdown()
