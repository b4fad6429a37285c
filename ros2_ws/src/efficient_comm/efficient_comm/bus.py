"""In-process topics: publishers hand the very message object to each subscriber.

A :class:`Bus` belongs to one container. It only keeps the wiring (who publishes and who
subscribes on which topic, with which QoS); *when* a callback runs is the executor's
business (:mod:`efficient_comm.executor`). Endpoints talking to other processes are added
on top by :mod:`efficient_comm.container`.

Delivery follows what ROS users expect from DDS:

* a subscriber only hears publishers with compatible QoS (reliability, durability), and
  both sides are warned once through their component's logger when they do not match, as
  DDS warns of an incompatible remote endpoint;
* a queued subscriber keeps at most ``depth`` messages (KEEP_LAST); older ones are dropped
  and counted;
* a TRANSIENT_LOCAL publisher keeps its last ``depth`` messages and replays them to a
  TRANSIENT_LOCAL subscriber that joins later.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from rclpy.duration import Duration
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from ._qos import compatible, incompatible_policy, is_transient_local, queue_limit
from .errors import ComponentError, TopicTypeError
from .typenames import type_name

if TYPE_CHECKING:
    from .executor import ConsecutiveExecutor
    from .handle import Logger
    from .stats import CallbackStats

#: What an observer subscribes with: matches every publisher, keeps whatever it is handed.
OBSERVER_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_ALL,
    reliability=ReliabilityPolicy.BEST_EFFORT,
    durability=DurabilityPolicy.VOLATILE,
)


#: rclpy's default wait: no limit.
_NO_LIMIT = Duration(seconds=-1)

class LocalSubscription:
    """A callback on a topic, with its queue for deferred (breadth-first) delivery."""

    __slots__ = (
        "active",
        "callback",
        "dds",
        "logger",
        "observer",
        "qos",
        "queue",
        "shm",
        "stats",
        "topic",
    )

    def __init__(
        self,
        topic: Topic,
        callback: Callable[[Any], None],
        qos: QoSProfile,
        stats: CallbackStats,
        logger: Logger,
    ) -> None:
        self.topic = topic
        self.callback = callback
        self.qos = qos
        self.stats = stats
        self.logger = logger
        self.queue: deque[tuple[Any, bytes | None, str]] = deque(maxlen=queue_limit(qos))
        self.active = True
        self.dds: Any = None  # the reader for remote publishers, if the container has DDS
        self.shm: Any = None  # its shared-memory side (efficient_comm.shm), if any
        # Test taps: they record what is published but are nobody's demand.
        self.observer = False

    @property
    def topic_name(self) -> str:
        return self.topic.name

    def run_one(self, executor: ConsecutiveExecutor) -> None:
        """Deliver the oldest queued message (the executor's ready queue calls this)."""
        if self.queue and self.active:
            msg, fp, origin = self.queue.popleft()
            executor.deliver(self, msg, fp, origin)


class LocalPublisher:
    """Publishes on a topic; ``dds`` is the writer for peers in other processes, if any.

    The container keeps ``dds_matched`` up to date from DDS matched events, so the common
    case (nobody outside listens) costs one attribute test per publish.
    """

    __slots__ = (
        "_executor",
        "_history",
        "_msg_type",
        "_subs",
        "closed",
        "dds",
        "dds_always",
        "dds_matched",
        "logger",
        "name",
        "qos",
        "shm",
        "topic",
    )

    def __init__(
        self,
        topic: Topic,
        qos: QoSProfile,
        executor: ConsecutiveExecutor,
        name: str,
        logger: Logger | None = None,
    ) -> None:
        self.topic = topic
        self.qos = qos
        self.name = name
        self.logger = logger
        self._executor = executor
        self._msg_type = topic.msg_type
        self._subs: tuple[LocalSubscription, ...] = ()
        self._history: deque[Any] | None = (
            deque(maxlen=queue_limit(qos)) if is_transient_local(qos) else None
        )
        # Set by the container when this publisher also has a DDS writer.
        self.dds: Any = None
        self.dds_always = False
        self.dds_matched = 0
        # Set by the container when large messages also go through shared memory: it
        # writes DDS too (efficient_comm.shm).
        self.shm: Any = None
        self.closed = False

    @property
    def topic_name(self) -> str:
        return self.topic.name

    def get_subscription_count(self) -> int:
        """Subscribers this publisher reaches: in this process, plus matched DDS readers."""
        return sum(not s.observer for s in self._subs) + self.dds_matched

    def shm_subscription_count(self) -> int:
        """Subscribers in other processes this publisher reaches through shared memory,
        connected now (0 without the transport, :mod:`efficient_comm.shm`); each is also
        among :meth:`get_subscription_count`'s matched DDS readers once DDS discovered it."""
        return int(self.shm.remote_readers) if self.shm is not None else 0

    def wait_for_all_acked(self, timeout: Duration = _NO_LIMIT) -> bool:
        """Whether DDS readers acknowledged everything (in-process ones need not)."""
        return self.dds is None or bool(self.dds.wait_for_all_acked(timeout))

    def publish(self, msg: Any, /) -> None:
        if self.closed:
            raise ComponentError(f"publisher on {self.topic.name} was destroyed")
        if type(msg) is not self._msg_type:
            raise TypeError(
                f"{self.topic.name} carries {self._msg_type.__name__}, "
                f"not {type(msg).__name__}"
            )
        if self.shm is not None:
            self.shm.publish(msg)
        elif self.dds is not None and (self.dds_matched or self.dds_always):
            self.dds.publish(msg)
        if self._history is not None:
            self._history.append(msg)
        if self._subs:
            self._executor.dispatch(self._subs, msg, self.name)

    def history(self) -> list[Any]:
        return list(self._history or ())


class Topic:
    __slots__ = ("_warned", "msg_type", "name", "publishers", "subscriptions")

    def __init__(self, name: str, msg_type: type) -> None:
        self.name = name
        self.msg_type = msg_type
        self.publishers: list[LocalPublisher] = []
        self.subscriptions: list[LocalSubscription] = []
        # Incompatible (publisher, subscriber) pairs already warned of: once per pair.
        self._warned: set[tuple[int, int]] = set()

    def rewire(self) -> None:
        """Recompute, per publisher, the subscribers it may reach (done on (un)subscribe)."""
        for pub in self.publishers:
            reached = []
            for sub in self.subscriptions:
                if not sub.active:
                    continue
                policy = incompatible_policy(pub.qos, sub.qos)
                if policy is None:
                    reached.append(sub)
                elif (id(pub), id(sub)) not in self._warned:
                    self._warned.add((id(pub), id(sub)))
                    self._warn(pub, sub, policy)
            pub._subs = tuple(reached)

    def _warn(self, pub: LocalPublisher, sub: LocalSubscription, policy: str) -> None:
        """What DDS says of an incompatible remote endpoint, for an in-process pair."""
        sub.logger.warning(
            f"publisher {pub.name} on topic '{self.name}' offers incompatible QoS: no "
            f"messages will be received from it (incompatible policy: {policy}; offered "
            f"{_describe(pub.qos)}, requested {_describe(sub.qos)})"
        )
        if pub.logger is not None:
            pub.logger.warning(
                f"a subscriber of {sub.stats.node} on topic '{self.name}' requests "
                f"incompatible QoS: no messages will be sent to it (incompatible policy: "
                f"{policy}; offered {_describe(pub.qos)}, requested {_describe(sub.qos)})"
            )

    def forget(self, pub: LocalPublisher | None = None,
               sub: LocalSubscription | None = None) -> None:
        """Drop warned pairs of a removed endpoint (ids may be reused by new ones)."""
        self._warned = {
            (p, s) for p, s in self._warned
            if (pub is None or p != id(pub)) and (sub is None or s != id(sub))
        }


class Bus:
    """All in-process topics of one container."""

    def __init__(self, executor: ConsecutiveExecutor) -> None:
        self._executor = executor
        self._topics: dict[str, Topic] = {}

    def topic(self, name: str, msg_type: type) -> Topic:
        topic = self._topics.get(name)
        if topic is None:
            topic = self._topics[name] = Topic(name, msg_type)
        elif topic.msg_type is not msg_type:
            raise TopicTypeError(
                f"topic {name} already carries {type_name(topic.msg_type)} in this process, "
                f"cannot use it with {type_name(msg_type)}"
            )
        return topic

    def topics(self) -> dict[str, type]:
        return {name: t.msg_type for name, t in self._topics.items()}

    def dds_readers(self) -> list[Any]:
        """The DDS reader (rclpy subscription) of every subscription that has one, by topic
        name: what a lockstep intake takes from (:mod:`efficient_comm.simtime`)."""
        return [sub.dds for name in sorted(self._topics)
                for sub in self._topics[name].subscriptions if sub.dds is not None]

    def publisher_qos(self, name: str) -> list[QoSProfile]:
        """The QoS profiles of this process's publishers on topic ``name`` (none: ``[]``).

        A subscriber created later uses it to match what is offered, e.g. to subscribe best
        effort when a publisher is best effort (a reliable subscription would get nothing).
        """
        return [pub.qos for pub in self.publishers(name)]

    def publishers(self, name: str) -> list[LocalPublisher]:
        """This process's publishers on topic ``name``."""
        topic = self._topics.get(name)
        return list(topic.publishers) if topic is not None else []

    def add_publisher(
        self, name: str, msg_type: type, qos: QoSProfile, *, owner: str,
        logger: Logger | None = None,
    ) -> LocalPublisher:
        topic = self.topic(name, msg_type)
        pub = LocalPublisher(topic, qos, self._executor, owner, logger)
        topic.publishers.append(pub)
        topic.rewire()
        return pub

    def add_subscription(
        self,
        name: str,
        msg_type: type,
        callback: Callable[[Any], None],
        qos: QoSProfile,
        *,
        stats: CallbackStats,
        logger: Logger,
    ) -> LocalSubscription:
        topic = self.topic(name, msg_type)
        sub = LocalSubscription(topic, callback, qos, stats, logger)
        topic.subscriptions.append(sub)
        topic.rewire()
        if is_transient_local(qos):
            for pub in topic.publishers:
                if compatible(pub.qos, qos):
                    for msg in pub.history():
                        self._executor.enqueue(sub, msg, None)
        return sub

    def add_observer(
        self,
        name: str,
        msg_type: type,
        callback: Callable[[Any], None],
        *,
        stats: CallbackStats,
        logger: Logger,
    ) -> LocalSubscription:
        """A subscription that hears every in-process publisher of ``name`` (best effort
        and volatile match them all) without counting as a subscriber: a publisher asks
        ``get_subscription_count()`` whether anybody wants its work, and an observer
        (a test's record of what was published, the recorder learning whose clock sync is
        local) must not make it compute what nobody else wants."""
        sub = self.add_subscription(name, msg_type, callback, OBSERVER_QOS,
                                    stats=stats, logger=logger)
        sub.observer = True
        return sub

    def remove_publisher(self, pub: LocalPublisher) -> None:
        pub.closed = True
        pub._subs = ()
        pub.dds = None
        if pub.shm is not None:
            pub.shm.close()
            pub.shm = None
        topic = pub.topic
        if pub in topic.publishers:
            topic.publishers.remove(pub)
        topic.forget(pub=pub)
        self._drop_if_unused(topic)

    def remove_subscription(self, sub: LocalSubscription) -> None:
        sub.active = False
        topic = sub.topic
        if sub in topic.subscriptions:
            topic.subscriptions.remove(sub)
            topic.rewire()
        topic.forget(sub=sub)
        self._drop_if_unused(topic)

    def _drop_if_unused(self, topic: Topic) -> None:
        if not topic.publishers and not topic.subscriptions:
            self._topics.pop(topic.name, None)


def _describe(qos: QoSProfile) -> str:
    return f"{qos.reliability.name.lower()}, {qos.durability.name.lower()}"
