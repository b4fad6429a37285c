"""Waits on DDS with one wait set kept across waits, instead of rclpy's executor, which
builds a new one on every wait, in Python, from every entity of its nodes: each
subscription and publisher with its QoS event handlers, each guard condition, an ExitStack
entry per handle.

* :class:`ReaderWait`: a few subscriptions and a guard, the lockstep barrier's two ends
  every round. rclpy's wait cost about 0.23 ms for the barrier's small node on the
  project's two-core machine, several times a step; in a profile of a lockstep team match
  it was a third of each robot's main-thread CPU, and as much of the world's.
* :class:`NodesWait`: every subscription, service, client, timer and guard of a
  container's nodes, the executor's DDS wait in real time (``ConsecutiveExecutor``); what
  it found is a :class:`DdsReady`, which the executor runs.

Each wait puts the same handles in again (rcl empties a wait set on every wait); samples
of ready subscriptions are taken all at once (:func:`~efficient_comm.executor.take_samples`).
Ctrl-C ends a wait at once: the wait set holds a guard condition rclpy's signal handler
triggers, as its executors' do.
"""

from __future__ import annotations

import contextlib
from dataclasses import dataclass, field
from typing import Any

from rclpy.context import Context
from rclpy.event_handler import QoSPublisherEventType
from rclpy.exceptions import InvalidHandle
from rclpy.executors import ExternalShutdownException
from rclpy.guard_condition import GuardCondition
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.signals import SignalHandlerGuardCondition
from rclpy.subscription import Subscription

from .executor import take_samples

__all__ = ["DdsReady", "NodesWait", "ReaderWait"]

_PUBLISHER_MATCHED = QoSPublisherEventType.RCL_PUBLISHER_MATCHED
#: Services of these packages (every node's parameter services and its type-description
#: service, rclpy makes seven a node) are not in :class:`NodesWait`'s wait set: the caller
#: answers them through rclpy's wait every ``DDS_EVENTS_POLL_NS``.
POLLED_SERVICES = ("rcl_interfaces.srv.", "type_description_interfaces.srv.")


def polled(service: Any) -> bool:
    """Whether ``service`` is answered by the caller's poll, not waited on."""
    return str(getattr(service.srv_type, "__module__", "")).startswith(POLLED_SERVICES)


class ReaderWait:
    """Wait for samples on ``subscriptions`` (more with :meth:`add`) or for ``guard`` to be
    triggered (another thread's wake-up), and run the callbacks of what came. Not
    thread-safe: one thread waits (another may trigger ``guard``). QoS events (liveliness)
    are not waited on: :class:`~efficient_comm.simtime.StepCoordinator` runs its rclpy
    executor for those now and then."""

    def __init__(self, context: Context, subscriptions: tuple[Subscription, ...] = (), *,
                 guard: GuardCondition | None = None) -> None:
        self._context = context
        self._sigint = SignalHandlerGuardCondition(context)
        self._guards = (self._sigint,) if guard is None else (guard, self._sigint)
        self._subs: list[Subscription] = list(subscriptions)
        self._set: Any = None  # made on the first wait after a change

    def add(self, subscription: Subscription) -> None:
        self._subs.append(subscription)
        self._set = None

    def wait(self, timeout_s: float) -> int:
        """Wait up to ``timeout_s`` (0: only look), then take every sample each ready
        subscription holds and run its callback; returns how many ran. Raises rclpy's
        ExternalShutdownException once the context is shut down, as its executors do."""
        if not self._context.ok():
            raise ExternalShutdownException()
        subs = self._subs
        with contextlib.ExitStack() as held:  # no handle is destroyed while waited on
            try:
                for entity in (*subs, *self._guards):
                    held.enter_context(entity.handle)
            except InvalidHandle:  # a subscription destroyed meanwhile: drop it
                self._subs = [s for s in subs if _valid(s)]
                self._set = None
                return 0
            context = self._context.handle
            if context is None:  # shut down (rclpy gives no handle then)
                raise ExternalShutdownException()
            held.enter_context(context)
            if self._set is None:
                self._set = _rclpy.WaitSet(len(subs), len(self._guards), 0, 0, 0, 0, context)
            wait_set = self._set
            wait_set.clear_entities()
            for sub in subs:
                wait_set.add_subscription(sub.handle)
            for guard in self._guards:
                wait_set.add_guard_condition(guard.handle)
            wait_set.wait(max(0, round(timeout_s * 1e9)))
            ready = wait_set.get_ready_entities("subscription")
            ready_subs = [sub for sub in subs if sub.handle.pointer in ready]
        if not self._context.ok():
            raise ExternalShutdownException()
        return sum(take_samples(sub) for sub in ready_subs)

    def close(self) -> None:
        with contextlib.suppress(InvalidHandle, ValueError):
            self._sigint.destroy()
        self._set = None


def _valid(sub: Subscription) -> bool:
    try:
        with sub.handle:
            return True
    except InvalidHandle:
        return False


@dataclass(slots=True)
class DdsReady:
    """What a :class:`NodesWait` found, for the executor's thread to run
    (``ConsecutiveExecutor._run_dds_items``)."""

    #: Ready subscriptions, their samples not taken yet.
    subs: list[Any] = field(default_factory=list)
    #: Triggered guard conditions (their callbacks not run yet).
    guards: list[Any] = field(default_factory=list)
    #: A service, client or rclpy timer is ready: rclpy's executor runs it.
    other: bool = False
    #: Publishers' "matched" events, taken: ``(handler, data)``, callbacks not run yet.
    events: list[tuple[Any, Any]] = field(default_factory=list)
    #: Time for rclpy's wait over the other QoS events (``DDS_EVENTS_POLL_NS``).
    poll_events: bool = False

    def __bool__(self) -> bool:
        return bool(self.subs or self.guards or self.other or self.events or self.poll_events)


class NodesWait:
    """Wait on every subscription, service, client, rclpy timer and guard condition of an
    rclpy executor's nodes, with one wait set rebuilt only when those change.

    What a container's executor blocks in between its timers when it talks DDS in real
    time. rclpy's own wait (``Executor._wait_for_ready_callbacks``) rebuilds its wait set on
    every call and adds each entity's QoS event handlers too (three or more per publisher
    and subscription): about 7 ms of CPU a wait for 20 nodes with their parameter services
    on the project's machine, against 0.8 ms here; in profiles of the team match that
    wait was a third of the world's main thread and a quarter of each robot's. QoS events
    are left out (hundreds of them; the caller polls them now and then, :class:`PolledWait`)
    but for the publishers' "matched" events, which are taken here for the caller to run
    at once: a composed publisher writes DDS only while a reader is matched
    (efficient_comm.bus), so a late event would drop what a new subscriber should get.

    The nodes' parameter services are left out too (:data:`POLLED_SERVICES`): seven a node,
    157 of a 20-component container's 221 entities, and the rmw's wait costs by the entity.
    Measured on such a container (20 nodes, 40 readers; three runs on a quiet machine): a
    wait that only looks took 0.64, 1.13 and 1.13 ms with them, 0.42, 0.22 and 0.38 without
    (the soccer demo's process: 3.7 % less CPU in 15 s of play). They
    are answered by the caller's poll (:class:`PolledWait`, every ``DDS_EVENTS_POLL_NS``), so
    ``ros2 param get`` from another process waits up to that much longer.
    """

    def __init__(self, executor: Any) -> None:
        self._executor = executor
        self._context: Context = executor.context
        self._sigint = SignalHandlerGuardCondition(self._context)
        self._key: tuple[tuple[int, ...], ...] | None = None
        self._set: Any = None
        self._subs: list[Any] = []
        self._services: list[Any] = []
        self._clients: list[Any] = []
        self._timers: list[Any] = []
        self._guards: list[Any] = []
        self._matched: list[Any] = []

    def _refresh(self) -> None:
        nodes = self._executor.get_nodes()
        key = tuple((id(n), len(n._subscriptions), len(n._services), len(n._clients),
                     len(n._timers), len(n._guards), len(n._publishers)) for n in nodes)
        if key == self._key:
            return
        self._key, self._set = key, None
        self._matched = [h for n in nodes for p in n._publishers for h in p.event_handlers
                         if h.event_type == _PUBLISHER_MATCHED]
        self._subs = [e for n in nodes for e in n._subscriptions]
        self._services = [e for n in nodes for e in n._services if not polled(e)]
        self._clients = [e for n in nodes for e in n._clients]
        self._timers = [e for n in nodes for e in n._timers]
        self._guards = [e for n in nodes for e in n._guards] + [self._sigint]

    def wait(self, timeout_s: float) -> DdsReady:
        """Wait up to ``timeout_s``; returns what is ready, nothing run or taken but the
        "matched" events' data. Raises rclpy's ExternalShutdownException once the context
        is shut down."""
        if not self._context.ok():
            raise ExternalShutdownException()
        self._refresh()
        groups = (self._subs, self._services, self._clients, self._timers, self._guards)
        with contextlib.ExitStack() as held:
            try:
                for group in groups:
                    for entity in group:
                        held.enter_context(entity.handle)
                for handler in self._matched:
                    held.enter_context(handler)
            except InvalidHandle:  # destroyed meanwhile: look again next time
                self._key = None
                return DdsReady()
            context = self._context.handle
            if context is None:
                raise ExternalShutdownException()
            held.enter_context(context)
            if self._set is None:
                self._set = _rclpy.WaitSet(len(self._subs), len(self._guards),
                                           len(self._timers), len(self._clients),
                                           len(self._services), len(self._matched), context)
            wait_set = self._set
            wait_set.clear_entities()
            for sub in self._subs:
                wait_set.add_subscription(sub.handle)
            for service in self._services:
                wait_set.add_service(service.handle)
            for client in self._clients:
                wait_set.add_client(client.handle)
            for timer in self._timers:
                wait_set.add_timer(timer.handle)
            for guard in self._guards:
                wait_set.add_guard_condition(guard.handle)
            for handler in self._matched:
                handler.add_to_wait_set(wait_set)
            wait_set.wait(max(0, round(timeout_s * 1e9)))
            ready = set(wait_set.get_ready_entities("subscription"))
            subs = [s for s in self._subs if s.handle.pointer in ready] if ready else []
            fired = set(wait_set.get_ready_entities("guard_condition"))
            guards = [g for g in self._guards if g.handle.pointer in fired] if fired else []
            other = bool(wait_set.get_ready_entities("service")
                         or wait_set.get_ready_entities("client")
                         or wait_set.get_ready_entities("timer"))
            matched = [h for h in self._matched if h.is_ready(wait_set)]
        events = [(h, data) for h in matched if (data := h.take_data()) is not None]
        return DdsReady(subs, guards, other, events)

    def close(self) -> None:
        with contextlib.suppress(InvalidHandle, ValueError):
            self._sigint.destroy()
        self._set = None


class PolledWait:
    """What :class:`NodesWait` leaves out, polled on a wait set of its own kept across
    polls: the nodes' parameter services (:data:`POLLED_SERVICES`) and their entities' QoS
    event handlers but the publishers' "matched" ones (NodesWait takes those).

    rclpy's executor polled them (with everything else) by building a wait set over every
    entity of every node in Python, and matching each ready event handler against its list
    of them: 5.9 ms of CPU a poll in a robot's container, four polls a second, 3.7 % of a
    core. :meth:`poll` runs what is ready itself: a service's request is answered through
    its callback, an event handler's data given to its ``execute``, as rclpy's executor
    does. It serves event handlers only: a node with another kind of waitable (an action
    server) makes :meth:`poll` return None, and the caller polls through rclpy instead.
    """

    def __init__(self, executor: Any) -> None:
        self._executor = executor
        self._context: Context = executor.context
        self._key: tuple[tuple[int, ...], ...] | None = None
        self._set: Any = None
        self._services: list[Any] = []
        self._handlers: list[Any] = []
        self._foreign = False

    def _refresh(self) -> None:
        from rclpy.event_handler import EventHandler

        nodes = self._executor.get_nodes()
        key = tuple((id(n), len(n._services), len(n._publishers), len(n._subscriptions),
                     len(list(n.waitables))) for n in nodes)
        if key == self._key:
            return
        self._key, self._set = key, None
        self._services = [e for n in nodes for e in n._services if polled(e)]
        waitables = [w for n in nodes for w in n.waitables]
        self._foreign = any(not isinstance(w, EventHandler) for w in waitables)
        self._handlers = [w for w in waitables if w.event_type != _PUBLISHER_MATCHED]

    def poll(self) -> int | None:
        """Run every polled service request and QoS event ready now; how many (None: a
        waitable this does not serve exists, poll through rclpy)."""
        if not self._context.ok():
            raise ExternalShutdownException()
        self._refresh()
        if self._foreign:
            return None
        with contextlib.ExitStack() as held:
            try:
                for service in self._services:
                    held.enter_context(service.handle)
                for handler in self._handlers:
                    held.enter_context(handler)
            except InvalidHandle:  # destroyed meanwhile: look again next time
                self._key = None
                return 0
            context = self._context.handle
            if context is None:
                raise ExternalShutdownException()
            held.enter_context(context)
            if self._set is None:
                events = sum(h.get_num_entities().num_events for h in self._handlers)
                self._set = _rclpy.WaitSet(0, 0, 0, 0, len(self._services), events, context)
            wait_set = self._set
            wait_set.clear_entities()
            for service in self._services:
                wait_set.add_service(service.handle)
            for handler in self._handlers:
                handler.add_to_wait_set(wait_set)
            wait_set.wait(0)
            ready = set(wait_set.get_ready_entities("service"))
            services = [s for s in self._services if s.handle.pointer in ready] if ready else []
            handlers = [h for h in self._handlers if h.is_ready(wait_set)]
        ran = 0
        for service in services:
            ran += _answer(service)
        for handler in handlers:
            data = handler.take_data()
            if data is not None:
                _finish(handler.execute(data))
                ran += 1
        return ran


def _answer(service: Any) -> int:
    """Take ``service``'s request and send its callback's response (rclpy's executor does
    the same, awaiting a callback that is a coroutine)."""
    try:
        with service.handle:
            request, header = service.handle.service_take_request(service.srv_type.Request)
    except InvalidHandle:
        return 0
    if header is None:
        return 0
    response = service.callback(request, service.srv_type.Response())
    if hasattr(response, "send"):  # a coroutine callback
        response = _finish(response)
    service.send_response(response, header)
    return 1


def _finish(coroutine: Any) -> Any:
    """Run ``coroutine`` to its end here: an event handler's ``execute`` (or a service's
    coroutine callback) that awaits nothing another thread must do, as rclpy's own are.
    One that still waits after :data:`_MAX_SENDS` resumptions is closed (None)."""
    try:
        for _ in range(_MAX_SENDS):
            coroutine.send(None)
    except StopIteration as done:
        return done.value
    coroutine.close()
    return None


_MAX_SENDS = 100
