"""The node handle: the one interface a component talks to (the dissertation's gateway).

A component is a plain class whose constructor takes a :class:`NodeHandle`. It never
subclasses or imports ``rclpy.node.Node``, so the same class runs on every backend:

* :mod:`efficient_comm.standalone` wraps a real rclpy node (one component, one process);
* :mod:`efficient_comm.container` composes many components in one process and passes
  messages between them by reference;
* :mod:`efficient_comm.testing` needs no DDS at all and runs on a manual clock.

Only the protocols below are the contract; each backend returns its own implementations.
Besides communication, the handle offers a few capabilities that components adapting to
their deployment need (the recorder, the simulator): name resolution, the ROS graph
(:class:`Graph`), the clock's kind and, where the executor can tell, its timer schedule.
Every backend implements them and the conformance suite covers them, so no component
needs to know which backend it runs on.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any, Literal, Protocol, TypeAlias, TypeVar, runtime_checkable

from rclpy.duration import Duration
from rclpy.qos import QoSProfile

from ._future import Future

__all__ = [
    "Client",
    "Clock",
    "ClockKind",
    "Component",
    "Future",
    "Graph",
    "Logger",
    "MessageCallback",
    "NodeHandle",
    "ParameterCallback",
    "ParameterRange",
    "ParameterValue",
    "Publisher",
    "QoSLike",
    "Service",
    "Subscription",
    "Timer",
    "TimerSchedule",
]

#: A depth (KEEP_LAST, reliable, volatile, as in rclpy) or a full profile.
QoSLike: TypeAlias = QoSProfile | int
#: Values a ROS 2 parameter can hold.
ParameterValue: TypeAlias = (
    bool | int | float | str | list[bool] | list[int] | list[float] | list[str]
)
#: rclpy's default wait: no limit.
_NO_LIMIT = Duration(seconds=-1)

#: The values a numeric parameter may take: ``(low, high)`` or ``(low, high, step)``, both
#: ends included; ints for an int parameter, numbers for a float one (step 0: any value).
ParameterRange: TypeAlias = tuple[float, float] | tuple[float, float, float]

#: A parameter's declared type: ``declare_parameter`` returns the type of its default.
P = TypeVar("P", bound=ParameterValue)
MessageCallback: TypeAlias = Callable[[Any], None]
#: Called with the parameters about to change; raise ``ValueError`` (or
#: :class:`~efficient_comm.errors.ParameterError`) to reject the whole change.
ParameterCallback: TypeAlias = Callable[[Mapping[str, ParameterValue]], None]


class Publisher(Protocol):
    """Sends messages on one topic."""

    @property
    def topic_name(self) -> str:
        """The fully resolved topic name (after namespace and remapping)."""
        ...

    def get_subscription_count(self) -> int:
        """How many subscribers are reached: ask before computing an expensive output."""
        ...

    def wait_for_all_acked(self, timeout: Duration = _NO_LIMIT) -> bool:
        """Whether every reliable reader in another process has acknowledged what was
        published, waiting at most ``timeout`` (negative: no limit; rclpy's signature).

        A program that ends right after its last publish calls it first: a message still
        on its way (or waiting for a reader that has only just matched) is lost when the
        writer goes. In-process subscribers have their messages already: ``True``.
        """
        ...

    def publish(self, msg: Any, /) -> None:
        """Publish ``msg``.

        On the composed and test backends in-process subscribers receive this very object:
        do not modify it after publishing, and receivers must not modify it either.
        """
        ...


class Subscription(Protocol):
    @property
    def topic_name(self) -> str: ...


class Timer(Protocol):
    @property
    def timer_period_ns(self) -> int: ...

    def cancel(self) -> None: ...

    def reset(self) -> None: ...

    def is_canceled(self) -> bool: ...


class Service(Protocol):
    @property
    def service_name(self) -> str: ...


class Client(Protocol):
    @property
    def srv_name(self) -> str: ...

    def call_async(self, request: Any, /) -> Future:
        """Send ``request``; the future completes in the executor's thread.

        Components run inside a single-threaded executor, so they must never block on the
        future: add a done-callback instead.
        """
        ...

    def service_is_ready(self) -> bool: ...


class Logger(Protocol):
    def debug(self, message: str, /) -> Any: ...

    def info(self, message: str, /) -> Any: ...

    def warning(self, message: str, /) -> Any: ...

    def error(self, message: str, /) -> Any: ...


class Clock(Protocol):
    """Time as integer nanoseconds: ROS time for real backends, manual time in tests."""

    def now_ns(self) -> int: ...


#: How a node's time advances: by itself ("system": ROS time from the system clock, maybe
#: skewed as on a computer of its own), only when the executor is advanced in this process
#: ("manual": tests and in-process lockstep simulation), or when another process says so
#: ("sim": ``/clock`` from a simulator, as ``use_sim_time`` in ROS; in lockstep or not).
#: Under "manual" and "sim" no wall-time deadline means anything to a component.
ClockKind: TypeAlias = Literal["system", "manual", "sim"]


class Graph(Protocol):
    """The ROS graph as one node sees it: the topics of its own process and, where the
    backend talks DDS, what DDS discovered (other processes). Without DDS (tests), only
    the process's own topics."""

    def topic_names_and_types(self) -> dict[str, list[str]]:
        """Every known topic's resolved name and its types (``pkg/msg/Type``)."""
        ...

    def publishers_qos(self, topic: str) -> list[QoSProfile]:
        """The QoS every known publisher on ``topic`` (a resolved name) offers.

        A subscriber matches what is offered with it: best effort when a publisher is best
        effort (a reliable reader would get nothing), transient local when all are.
        """
        ...


class TimerSchedule(Protocol):
    """When the executor running a component next has a timer due.

    A hint a component's own background thread may read (without the executor's
    cooperation, so possibly stale) to keep off the GIL around the deadlines of the
    executor's timers; the recorder's writer does.
    """

    @property
    def clock(self) -> Clock: ...

    def next_timer_due_ns(self) -> int | None:
        """The earliest timer deadline on :attr:`clock` (ns), or None with no timers."""
        ...


@runtime_checkable
class NodeHandle(Protocol):
    """What a component may ask of the middleware. Injected into the constructor."""

    @property
    def name(self) -> str: ...

    @property
    def namespace(self) -> str: ...

    @property
    def fully_qualified_name(self) -> str: ...

    @property
    def logger(self) -> Logger: ...

    @property
    def clock(self) -> Clock: ...

    # -- capabilities (every backend has them) ---------------------------------------------

    @property
    def clock_kind(self) -> ClockKind:
        """Whether :attr:`clock` runs by itself or only when the executor is advanced."""
        ...

    @property
    def graph(self) -> Graph: ...

    @property
    def timer_schedule(self) -> TimerSchedule | None:
        """The executor's timer deadlines, where the backend can tell (composed: the
        container's executor); None where it cannot (standalone: rclpy's executor)."""
        ...

    def resolve_topic_name(self, topic: str) -> str:
        """The full name ``topic`` has for this node (namespace and remapping applied)."""
        ...

    def observe_in_process(
        self, msg_type: type, topic: str, callback: MessageCallback
    ) -> Subscription | None:
        """Hear what the components of this process publish on ``topic``, and only that.

        On a DDS domain shared by a team every robot's messages reach every process; a
        component that must tell its own robot's from the others' (the recorder learning
        whose clock sync shares its container) observes the in-process bus instead. An
        observer has no DDS reader and does not count as a subscriber, so no publisher
        computes anything for it. None where the backend hosts no other components
        (standalone: one component a process). Remove it with :meth:`destroy_subscription`.
        """
        ...

    # -- communication -----------------------------------------------------------------------

    def create_publisher(self, msg_type: type, topic: str, *, qos: QoSLike = 10) -> Publisher: ...

    def create_subscription(
        self, msg_type: type, topic: str, callback: MessageCallback, *, qos: QoSLike = 10,
        on_lost: Callable[[int], None] | None = None,
    ) -> Subscription:
        """``on_lost(n)``: DDS reports ``n`` more messages of a remote publisher that will
        never arrive (a reliable KEEP_LAST writer dropped them unacknowledged, or the
        transport did); called on the executor's thread. In-process delivery loses none."""
        ...

    def create_timer(self, period_s: float, callback: Callable[[], None]) -> Timer: ...

    def create_service(
        self, srv_type: type, name: str, callback: Callable[[Any, Any], Any]
    ) -> Service:
        """``callback(request, response)`` fills and returns ``response``, as in rclpy."""
        ...

    def create_client(self, srv_type: type, name: str) -> Client: ...

    def destroy_publisher(self, publisher: Publisher) -> None: ...

    def destroy_subscription(self, subscription: Subscription) -> None: ...

    def destroy_timer(self, timer: Timer) -> None: ...

    def declare_parameter(
        self,
        name: str,
        default: P,
        *,
        description: str = "",
        read_only: bool = False,
        range: ParameterRange | None = None,
    ) -> P:
        """Declare ``name`` with the type of ``default``; return the effective value.

        The effective value is the override given at deployment (params file, container
        entry, test fixture) when there is one, else ``default``. ``range`` is
        ``(low, high)`` or ``(low, high, step)`` for an int or float parameter: values
        outside it (or off the step grid from ``low``) are refused on every backend, and
        tools see it in the descriptor (``ros2 param describe``, the GUI's pre-check).
        """
        ...

    def get_parameter(self, name: str) -> ParameterValue: ...

    def set_parameter(self, name: str, value: ParameterValue) -> None:
        """Set a declared parameter; raises ParameterError if rejected or of another type."""
        ...

    def add_on_parameter_change(self, callback: ParameterCallback) -> None: ...


class Component(Protocol):
    """Anything constructed from a handle. ``close()`` is optional and called on unload."""

    def __init__(self, node: NodeHandle) -> None: ...
