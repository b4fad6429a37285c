"""The composed backend: a component's handle inside a :class:`~efficient_comm.Container`.

Publishing goes through the container's bus (by reference, on the consecutive executor).
When the container talks DDS, each component also gets a real rclpy node, so that the
ROS graph shows it (``ros2 node list``, ``ros2 topic info``, ``ros2 param``) and peers in
other processes can reach it: every publisher has a DDS writer that is written to only
while DDS reports a matched reader (always, for TRANSIENT_LOCAL, so late joiners get the
history), and every subscription has a DDS reader. The participant ignores its own
endpoints (:mod:`efficient_comm.dds`), so nothing is delivered twice.
"""

from __future__ import annotations

import logging
from collections import deque
from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Any

from rclpy.event_handler import PublisherEventCallbacks
from rclpy.node import Node
from rclpy.parameter import Parameter

from ._failures import failure_outcome, failure_response, local_failure, without_answer
from ._future import Future
from ._graph import NodeGraph
from ._names import Resolver, check_node_name, fully_qualified
from ._params import LocalParameters, ParameterMethods, RclpyParameters, parameter_type
from ._qos import is_transient_local, lost_events, to_profile
from .bus import LocalPublisher, LocalSubscription
from .errors import ComponentError
from .executor import ExecutorTimer
from .handle import (
    Clock,
    ClockKind,
    Logger,
    MessageCallback,
    Publisher,
    QoSLike,
    Subscription,
    Timer,
    TimerSchedule,
)

if TYPE_CHECKING:
    from .container import Container


class RecordingLogger:
    """A logger for nodes without rcl logging: Python ``logging``, plus the last records.

    Tests read :attr:`records` (``(level, message)`` pairs) to assert on warnings.
    """

    def __init__(self, name: str, *, keep: int = 1000) -> None:
        self._log = logging.getLogger("efficient_comm" + name.replace("/", "."))
        self.records: deque[tuple[str, str]] = deque(maxlen=keep)

    def _emit(self, level: str, message: str) -> None:
        self.records.append((level, message))
        self._log.log(logging.getLevelName(level.upper()), message)

    def debug(self, message: str, /) -> None:
        self._emit("debug", message)

    def info(self, message: str, /) -> None:
        self._emit("info", message)

    def warning(self, message: str, /) -> None:
        self._emit("warning", message)

    def error(self, message: str, /) -> None:
        self._emit("error", message)


class LocalService:
    """A service callback reachable by in-process clients without DDS."""

    __slots__ = ("callback", "handle", "service_name", "srv_type", "stats", "what")

    def __init__(
        self, handle: ComposedHandle, srv_type: type, name: str, callback: Callable[..., Any]
    ) -> None:
        self.handle = handle
        self.srv_type = srv_type
        self.service_name = name
        self.callback = callback
        self.stats = handle._container.executor.registry.add(
            handle.fully_qualified_name, "service", name
        )
        self.what = f"service {name} ({failure_outcome(srv_type)})"

    def serve(self, request: Any) -> tuple[Any | None, BaseException | None]:
        """``(response, None)``, or if the callback raised (logged and counted):
        ``(failure response or None, the exception)`` (see :mod:`efficient_comm._failures`)."""
        ok, response = self.handle._container.executor.call(
            self.stats, self.handle.logger, self.what,
            self.callback, request, getattr(self.srv_type, "Response")(),  # noqa: B009
        )
        if ok:
            return response, None
        return failure_response(self.srv_type, self.service_name, response), response


class ComposedClient:
    """Calls an in-process service directly, or a remote one over DDS."""

    def __init__(self, handle: ComposedHandle, srv_type: type, name: str) -> None:
        self._handle = handle
        self._srv_type = srv_type
        self._name = name
        node = handle.rclpy_node
        self._dds = node.create_client(srv_type, name) if node is not None else None
        executor = handle._container.executor
        stats = executor.registry.add(handle.fully_qualified_name, "client", name)
        logger = handle.logger

        def invoke(callback: Callable[[Future], None], future: Future) -> None:
            executor.call(stats, logger, f"done-callback of {name}", callback, future)

        self._invoke = invoke

    @property
    def srv_name(self) -> str:
        return self._name

    def service_is_ready(self) -> bool:
        if self._name in self._handle._container._services:
            return True
        return self._dds is not None and self._dds.service_is_ready()

    def call_async(self, request: Any, /) -> Future:
        future = Future(self._invoke)
        local = self._handle._container._services.get(self._name)
        if local is not None:
            def answer() -> None:
                response, error = local.serve(request)
                if response is None and error is not None:
                    future.set_exception(local_failure(local.service_name, error))
                else:
                    future.set_result(response)

            self._handle._container.executor.post(answer)
        elif self._dds is not None:
            self._dds.call_async(request).add_done_callback(
                lambda done: future.set_result(done.result())
            )
        # else, like rclpy: nobody answers until a server appears
        return future

    def destroy(self) -> None:
        if self._dds is not None and self._handle.rclpy_node is not None:
            self._handle.rclpy_node.destroy_client(self._dds)


class ComposedHandle(ParameterMethods):
    """The node handle of one composed component. Created by the container."""

    def __init__(
        self,
        container: Container,
        *,
        name: str,
        namespace: str,
        remappings: Mapping[str, str],
        parameters: Mapping[str, Any],
    ) -> None:
        self._container = container
        self._name, self._namespace = check_node_name(name, namespace)
        self._fqn = fully_qualified(self._name, self._namespace)
        self._resolver = Resolver(self._name, self._namespace, remappings)
        self._publishers: list[LocalPublisher] = []
        self._subscriptions: list[LocalSubscription] = []
        self._timers: list[ExecutorTimer] = []
        self._services: list[str] = []
        self._clients: list[ComposedClient] = []
        self.rclpy_node: Node | None = None
        self._logger: Logger
        self._params: LocalParameters | RclpyParameters
        for key, value in parameters.items():
            parameter_type(key, value)  # refuse bad overrides before anything is created
        if container.context is not None:
            node = Node(
                self._name,
                namespace=self._namespace,
                context=container.context,
                use_global_arguments=False,
                parameter_overrides=[Parameter(k, value=v) for k, v in parameters.items()],
            )
            self.rclpy_node = node
            self._logger = node.get_logger()
            self._params = RclpyParameters(node)
        else:
            self._logger = RecordingLogger(self._fqn)
            self._params = LocalParameters(parameters)

    # -- identity ----------------------------------------------------------------------------

    @property
    def name(self) -> str:
        return self._name

    @property
    def namespace(self) -> str:
        return self._namespace

    @property
    def fully_qualified_name(self) -> str:
        return self._fqn

    @property
    def logger(self) -> Logger:
        return self._logger

    @property
    def container(self) -> Container:
        """The container this component runs in: its ``bus`` (in-process topics) and its
        ``executor`` (timers), for components that adapt to how they are composed."""
        return self._container

    @property
    def clock(self) -> Clock:
        return self._container.executor.clock

    # -- capabilities --------------------------------------------------------------------

    @property
    def clock_kind(self) -> ClockKind:
        return self._container.executor.clock_kind

    @property
    def graph(self) -> NodeGraph:
        return NodeGraph(bus=self._container.bus, node=self.rclpy_node)

    @property
    def timer_schedule(self) -> TimerSchedule:
        return self._container.executor

    def resolve_topic_name(self, topic: str) -> str:
        """The full name ``topic`` has for this node (namespace and remapping applied)."""
        return self._resolver.resolve(topic)

    # -- communication -------------------------------------------------------------------

    def create_publisher(
        self, msg_type: type, topic: str, *, qos: QoSLike = 10
    ) -> LocalPublisher:
        name = self.resolve_topic_name(topic)
        profile = to_profile(qos)
        pub = self._container.bus.add_publisher(
            name, msg_type, profile, owner=self._fqn, logger=self._logger
        )
        node = self.rclpy_node
        if node is not None:

            def matched(status: Any, pub: LocalPublisher = pub) -> None:
                pub.dds_matched = status.current_count

            pub.dds = node.create_publisher(
                msg_type, name, profile, event_callbacks=PublisherEventCallbacks(matched=matched)
            )
            pub.dds_always = is_transient_local(profile)
            pub.dds_matched = pub.dds.get_subscription_count()
            if self._container.shm is not None:
                pub.shm = self._container.shm.publisher(pub, self._logger)
        self._publishers.append(pub)
        return pub

    def create_subscription(
        self, msg_type: type, topic: str, callback: MessageCallback, *, qos: QoSLike = 10,
        on_lost: Callable[[int], None] | None = None,
    ) -> LocalSubscription:
        name = self.resolve_topic_name(topic)
        profile = to_profile(qos)
        executor = self._container.executor
        stats = executor.registry.add(self._fqn, "subscription", name)
        sub = self._container.bus.add_subscription(
            name, msg_type, callback, profile, stats=stats, logger=self._logger
        )
        node = self.rclpy_node
        if node is not None:
            # Only peers in other processes reach this reader (local endpoints are ignored).
            remote = (sub,)
            shm = self._container.shm
            sub.shm = shm.subscription(sub, self._logger, on_lost) if shm is not None else None
            sub.dds = node.create_subscription(
                msg_type, name,
                sub.shm.from_dds if sub.shm is not None
                else lambda msg: executor.receive_remote(remote, msg),
                profile, event_callbacks=lost_events(on_lost),
            )
        self._subscriptions.append(sub)
        return sub

    def observe_in_process(
        self, msg_type: type, topic: str, callback: MessageCallback
    ) -> LocalSubscription:
        name = self.resolve_topic_name(topic)
        stats = self._container.executor.registry.add(
            self._fqn, "subscription", f"{name} (in-process observer)"
        )
        sub = self._container.bus.add_observer(
            name, msg_type, callback, stats=stats, logger=self._logger
        )
        self._subscriptions.append(sub)
        return sub

    def create_timer(self, period_s: float, callback: Callable[[], None]) -> ExecutorTimer:
        executor = self._container.executor
        stats = executor.registry.add(
            self._fqn, "timer", getattr(callback, "__qualname__", ""),
            period_ns=round(period_s * 1e9) if period_s > 0 else 0,
        )
        timer = executor.create_timer(period_s, callback, stats=stats, logger=self._logger)
        self._timers.append(timer)
        return timer

    def create_service(
        self, srv_type: type, name: str, callback: Callable[[Any, Any], Any]
    ) -> LocalService:
        full = self.resolve_topic_name(name)
        services = self._container._services
        if full in services:
            raise ComponentError(
                f"service {full} is already provided in this process by "
                f"{services[full].handle.fully_qualified_name}"
            )
        service = services[full] = LocalService(self, srv_type, full, callback)
        self._services.append(full)
        node = self.rclpy_node
        if node is not None:
            without_answer(
                node.create_service(srv_type, full, lambda request, _: service.serve(request)[0])
            )
        return service

    def create_client(self, srv_type: type, name: str) -> ComposedClient:
        client = ComposedClient(self, srv_type, self.resolve_topic_name(name))
        self._clients.append(client)
        return client


    # -- teardown ------------------------------------------------------------------------

    def destroy_publisher(self, publisher: Publisher) -> None:
        assert isinstance(publisher, LocalPublisher)
        if publisher in self._publishers:
            self._publishers.remove(publisher)
            self._destroy_publisher(publisher)

    def _destroy_publisher(self, publisher: LocalPublisher) -> None:
        dds = publisher.dds
        self._container.bus.remove_publisher(publisher)
        if dds is not None and self.rclpy_node is not None:
            self.rclpy_node.destroy_publisher(dds)

    def destroy_subscription(self, subscription: Subscription) -> None:
        assert isinstance(subscription, LocalSubscription)
        if subscription in self._subscriptions:
            self._subscriptions.remove(subscription)
            self._destroy_subscription(subscription)

    def _destroy_subscription(self, subscription: LocalSubscription) -> None:
        self._container.bus.remove_subscription(subscription)
        if subscription.shm is not None:
            subscription.shm.close()
            subscription.shm = None
        if subscription.dds is not None and self.rclpy_node is not None:
            self.rclpy_node.destroy_subscription(subscription.dds)
            subscription.dds = None

    def destroy_timer(self, timer: Timer) -> None:
        assert isinstance(timer, ExecutorTimer)
        timer.close()
        if timer in self._timers:
            self._timers.remove(timer)

    def close(self) -> None:
        """Remove every endpoint, timer and service this handle created, and its node.

        What the component still holds is dead afterwards: publishing raises, timers stay
        cancelled.
        """
        for pub in self._publishers:
            self._destroy_publisher(pub)
        for sub in self._subscriptions:
            self._destroy_subscription(sub)
        for timer in self._timers:
            timer.close()
        for client in self._clients:
            client.destroy()
        for service in self._services:
            self._container._services.pop(service, None)
        self._publishers.clear()
        self._subscriptions.clear()
        self._timers.clear()
        self._services.clear()
        self._clients.clear()
        self._container.executor.registry.remove_node(self._fqn)
        if self.rclpy_node is not None:
            self.rclpy_node.destroy_node()
            self.rclpy_node = None
