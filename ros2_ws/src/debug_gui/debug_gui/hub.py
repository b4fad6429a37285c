"""The data side: connections to robots in several DDS domains, feeds, service calls.

One rclpy Context, node and executor thread per DDS domain (a participant can join only
one domain). Robots are discovered by their ``<namespace>/efficient_comm/stats`` topic and
appear and disappear live; with ``plain_robots`` every top-level namespace with running
nodes is a robot too (plain rclpy or rclcpp robots publish no statistics). Feeds go
through throttle_publisher whenever the publisher understands it, so the robot sends (and
computes) only the rate a view displays; for other publishers the Hub drops what the view
would not show, which saves the GUI but not the link.

Nothing here imports a UI toolkit: the Hub is tested without a browser, and the foxglove
endpoint serves the same Hub.

Thread rule: feed callbacks and ``on_robots_changed`` callbacks run on a domain's executor
thread; every public method may be called from any other thread. :meth:`Hub.call` blocks,
so a UI calls it off its event loop. Subscriptions and publishers are destroyed on the
domain's executor thread, between its waits: rclpy's executor reads the handles of the
node's entities after each wait, and an entity another thread destroys meanwhile makes it
raise ``InvalidHandle`` (what closing browser tabs did).
"""

from __future__ import annotations

import contextlib
import logging
import threading
import time
from collections import deque
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import rclpy
from rclpy.context import Context
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile
from rclpy.serialization import deserialize_message

from efficient_comm.handle import MessageCallback, NodeHandle, Publisher, QoSLike, Subscription
from efficient_comm.standalone import StandaloneHandle
from throttle_publisher import ThrottledSubscription, ThrottleOptions

from .errors import CallFailed, InvalidInput, RobotUnavailable
from .robots import STATS_SUFFIX, RobotId, Via, check_domain
from .security import check_name, check_rate

if TYPE_CHECKING:
    from .source import Source

_log = logging.getLogger(__name__)

#: How often each domain's graph is scanned for robots coming and going.
DISCOVERY_PERIOD_S = 0.5
#: A robot is gone once its statistics topic has had no publisher this long (a single scan
#: can miss a publisher while DDS rediscovers a busy participant).
GONE_AFTER_S = 1.5
#: Longest wait of the executor, so close() and new entities are noticed soon.
SPIN_TIMEOUT_S = 0.05
_THROTTLE_REQUEST = "_throttle"
#: A feed dropping locally passes a message this fraction of its period after the last.
MIN_INTERVAL = 0.9
#: Nodes named so are debug_gui instances (this one's or another's), never a robot's.
_OWN_NODE_PREFIX = "debug_gui"


def hidden(name: str) -> bool:
    """True for a name ROS 2 hides (``ros2 topic list`` does): a token starting with ``_``."""
    return any(token.startswith("_") for token in name.split("/"))


@dataclass(slots=True)
class TopicCounter:
    """What crossed the link for one (robot, topic): the benchmark's figure."""

    messages: int = 0
    bytes: int = 0


class _CountingHandle:
    """The domain's handle, but subscriptions arrive serialized and are counted.

    ThrottledSubscription creates its reply subscription through this, so bytes are
    counted for throttled feeds as for plain ones; deserializing here costs what rclpy
    would spend doing it itself.
    """

    def __init__(self, domain: _Domain, counter: TopicCounter) -> None:
        self._domain = domain
        self._counter = counter

    def create_publisher(self, msg_type: type, topic: str, *, qos: QoSLike = 10) -> Publisher:
        return self._domain.handle.create_publisher(msg_type, topic, qos=qos)

    def create_subscription(
        self, msg_type: type, topic: str, callback: MessageCallback, *, qos: QoSLike = 10
    ) -> Subscription:
        counter = self._counter

        def on_raw(data: bytes) -> None:
            counter.messages += 1
            counter.bytes += len(data)
            callback(deserialize_message(data, msg_type))

        profile = qos if isinstance(qos, QoSProfile) else QoSProfile(depth=int(qos))
        return self._domain.node.create_subscription(
            msg_type, topic, on_raw, profile, raw=True
        )

    def destroy_subscription(self, subscription: Subscription) -> None:
        self._domain.node.destroy_subscription(subscription)  # type: ignore[arg-type]

    def destroy_publisher(self, publisher: Publisher) -> None:
        self._domain.node.destroy_publisher(publisher)  # type: ignore[arg-type]


class _SharedStream:
    """The one subscription to a (robot, topic, type, QoS) that all its feeds share.

    Two views of one robot topic must not make the robot encode and send it twice: the
    robot sends one stream at the highest rate any feed wants (every message if one wants
    them all), through throttle_publisher when the publisher understands it, and each feed
    drops locally what its own rate does not show. Created by the Hub's ``subscribe``,
    closed with its last feed.

    A latched topic (transient local durability) gives a new subscription its last
    messages; a feed joining a stream that already runs gets them from the stream instead
    (it keeps the last ``depth``), on the domain's thread, before anything newer.
    """

    def __init__(self, hub: Hub, robot: RobotId, topic: str, msg_type: type, *,
                 qos: QoSLike) -> None:
        self.robot = robot
        self.topic = topic
        self._hub = hub
        self._lock = threading.Lock()
        self._feeds: list[Feed] = []
        self._rate_hz: float | None = None
        self.closed = False
        domain = hub._domain(robot)
        self._domain = domain
        self._msg_type = msg_type
        self._qos = qos
        self._handle = _CountingHandle(domain, hub._counter(robot, topic))
        self._throttled: ThrottledSubscription | None = None
        self._plain: Subscription | None = None
        latched = isinstance(qos, QoSProfile) and \
            qos.durability == DurabilityPolicy.TRANSIENT_LOCAL
        self._latched: deque[Any] | None = deque(maxlen=max(1, qos.depth)) \
            if latched and isinstance(qos, QoSProfile) else None

    def open(self, first: Feed) -> None:
        """Subscribe for ``first`` (before anyone else can join: the Hub's lock is held)."""
        self._feeds.append(first)
        self._rate_hz = first.rate_hz
        if not self.upgrade():
            self._plain = self._handle.create_subscription(
                self._msg_type, self.topic, self._deliver, qos=self._qos)

    @property
    def throttled(self) -> bool:
        return self._throttled is not None

    @property
    def rate_hz(self) -> float | None:
        """The rate asked of the robot: the highest of the feeds' (None: every message)."""
        return self._rate_hz

    def upgrade(self) -> bool:
        """Go through throttle_publisher if the topic now has a throttle-aware publisher
        (see :meth:`Feed.upgrade`); True if throttled (now or already)."""
        with self._lock:
            if self._throttled is not None or self.closed:
                return self._throttled is not None
            if self._domain.node.count_subscribers(f"{self.topic}/{_THROTTLE_REQUEST}") == 0:
                return False
            self._throttled = ThrottledSubscription(
                self._handle, self._msg_type, self.topic,  # type: ignore[arg-type]
                self._deliver, options=_options(self._rate_hz), qos=self._qos,
            )
            plain, self._plain = self._plain, None
        if plain is not None:
            self._domain.on_thread(lambda: self._handle.destroy_subscription(plain))
        return True

    def join(self, feed: Feed) -> None:
        with self._lock:
            self._feeds.append(feed)
            feed._awaiting_replay = self._latched is not None
        self.recompute()
        if self._latched is None:
            return

        def replay() -> None:
            # On the domain's thread, as deliveries are (which skip the feed until now, and
            # keep what they bring): nothing newer reaches the feed before the kept ones.
            with self._lock:
                kept = list(self._latched or ())
            now = time.monotonic_ns()
            for msg in kept:
                feed._offer(msg, now, whole=True)
            feed._awaiting_replay = False

        self._domain.on_thread(replay)

    def recompute(self) -> None:
        """Ask the robot for the highest rate any feed wants now (after a join, a leave or
        a feed's new rate); a throttle-aware publisher hears of a change only."""
        with self._lock:
            if self.closed:
                return
            rates = [f.rate_hz for f in self._feeds]
            wanted = None if not rates or None in rates else max(
                r for r in rates if r is not None)
            if wanted == self._rate_hz:
                return
            self._rate_hz = wanted
            if self._throttled is not None:
                self._throttled.update(_options(wanted))

    def leave(self, feed: Feed) -> None:
        """``feed`` closed: with it the last, the subscription goes (on the domain's thread,
        within a spin, about 50 ms) and a throttle-aware publisher stops sending then."""
        with self._hub._lock, self._lock:
            if feed in self._feeds:
                self._feeds.remove(feed)
            last = not self._feeds and not self.closed
            if last:
                self.closed = True
                self._hub._forget_stream(self)
            throttled, plain = self._throttled, self._plain
        if not last:
            self.recompute()
        elif throttled is not None:
            self._domain.on_thread(throttled.close)
        elif plain is not None:
            self._domain.on_thread(lambda: self._handle.destroy_subscription(plain))

    def _deliver(self, msg: Any) -> None:
        with self._lock:
            if self._latched is not None:
                self._latched.append(msg)
            feeds = list(self._feeds)
            robot_limits = self._throttled is not None
            sent_rate = self._rate_hz
        now = time.monotonic_ns()
        for feed in feeds:
            if feed._awaiting_replay:
                continue
            # What the robot already limits to a feed's rate passes whole; the rest is
            # dropped per feed, by each one's own rate.
            feed._offer(msg, now, whole=robot_limits and feed.rate_hz == sent_rate)


class Feed:
    """One subscription of a view to a robot's topic, at the rate the view displays.

    Feeds of one robot topic (same type and QoS) share one stream from the robot: it sends
    at the highest rate any of them asks for, and each feed drops locally what its own rate
    does not show. ``throttled`` says whether the robot itself limits what it sends
    (throttle-aware publisher) or the Hub drops the surplus locally. ``received`` counts
    the messages handed to the callback.
    """

    def __init__(
        self,
        hub: Hub,
        robot: RobotId,
        topic: str,
        callback: Callable[[Any], None],
        *,
        rate_hz: float | None,
    ) -> None:
        self.robot = robot
        self.topic = topic
        self.received = 0
        self._callback = callback
        self._hub = hub
        self._rate_hz = rate_hz
        self._last_ns = 0
        self._closed = False
        self._stream: _SharedStream | None = None
        #: Joined a latched stream: its kept messages come first (see _SharedStream.join).
        self._awaiting_replay = False

    def upgrade(self) -> bool:
        """Go through throttle_publisher if the topic now has a throttle-aware publisher.

        Called at creation and by the Hub's discovery, so a feed made before the robot's
        publisher was discovered moves to the robot-side rate as soon as it is. True if
        the feed is throttled (now or already).
        """
        stream = self._stream
        return stream is not None and not self._closed and stream.upgrade()

    @property
    def throttled(self) -> bool:
        stream = self._stream
        return stream is not None and stream.throttled

    @property
    def rate_hz(self) -> float | None:
        return self._rate_hz

    def _offer(self, msg: Any, now_ns: int, *, whole: bool) -> None:
        """Hand ``msg`` to the callback unless this feed's rate drops it: one at least
        :data:`MIN_INTERVAL` of a period after the last (a tenth of a period of jitter
        tolerated, so a feed at half a stream's rate gets every other message, not every
        third, and never more than a tenth above its rate)."""
        if self._closed:
            return
        rate = self._rate_hz
        if rate is not None and not whole:
            if now_ns - self._last_ns < int(MIN_INTERVAL * 1e9 / rate):
                return
            self._last_ns = now_ns
        self.received += 1
        try:
            self._callback(msg)
        except Exception:
            _log.exception("feed %s of %s: callback raised", self.topic, self.robot.label)

    def set_rate(self, rate_hz: float | None) -> None:
        """Display another rate from now on (None: every message)."""
        self._rate_hz = check_rate(rate_hz)
        stream = self._stream
        if stream is not None and not self._closed:
            stream.recompute()

    def close(self) -> None:
        """Stop receiving at once; the shared stream's subscription goes with its last feed
        (see :meth:`_SharedStream.leave`)."""
        if self._closed:
            return
        self._closed = True
        stream = self._stream
        if stream is not None:
            stream.leave(self)
        self._hub._forget(self)


def _options(rate_hz: float | None) -> ThrottleOptions:
    return ThrottleOptions(max_rate_hz=rate_hz or 0.0)


def _qos_key(qos: QoSLike) -> object:
    """What makes two QoS settings one subscription's (a QoSProfile is not hashable)."""
    if isinstance(qos, QoSProfile):
        return (qos.history, qos.depth, qos.reliability, qos.durability, qos.liveliness,
                qos.deadline.nanoseconds, qos.lifespan.nanoseconds,
                qos.liveliness_lease_duration.nanoseconds)
    return int(qos)


class _Domain:
    """One DDS domain: context, node, handle and the thread that spins them."""

    def __init__(self, domain: int, *, node_name: str, via: Via) -> None:
        self.domain = domain
        self.via = via
        self.node_name = node_name
        self.context = Context()
        rclpy.init(context=self.context, domain_id=domain)
        try:
            # No rosout: one node a domain in one process would share the logger's rosout
            # publisher (rcl warns), and the GUI's own log is no robot's business.
            self.node = Node(node_name, context=self.context, enable_rosout=False)
            self.handle = StandaloneHandle(self.node)
            self.executor = SingleThreadedExecutor(context=self.context)
            self.executor.add_node(self.node)
        except BaseException:
            self.context.try_shutdown()
            raise
        self.thread: threading.Thread | None = None
        self._pending: list[Callable[[], None]] = []
        self._pending_lock = threading.Lock()
        # Triggered by on_thread: wakes the executor, whose thread then runs the pending work.
        self._wake = self.node.create_guard_condition(self.run_pending)
        self.robots: set[RobotId] = set()
        self.last_seen: dict[RobotId, float] = {}
        self.clients: dict[tuple[str, type], Any] = {}
        self.clients_lock = threading.Lock()

    def on_thread(self, work: Callable[[], None]) -> None:
        """Run ``work`` (destroying an entity) on the executor thread between its waits, or
        now if this is that thread or it does not run (any more)."""
        thread = self.thread
        if thread is None or thread is threading.current_thread() or not thread.is_alive():
            self._run(work)
            return
        with self._pending_lock:
            self._pending.append(work)
        with contextlib.suppress(Exception):  # shut down meanwhile: close() runs it
            self._wake.trigger()

    def run_pending(self) -> None:
        with self._pending_lock:
            pending, self._pending = self._pending, []
        for work in pending:
            self._run(work)

    def _run(self, work: Callable[[], None]) -> None:
        try:
            work()
        except Exception:  # the context may be shut down under us: the node goes anyway
            if self.context.ok():
                _log.exception("domain %d: destroying an entity failed", self.domain)

    def close(self) -> None:
        self.context.try_shutdown()
        if self.thread is not None and self.thread is not threading.current_thread():
            self.thread.join(timeout=5.0)
        self.run_pending()  # what was queued while the thread stopped
        self.executor.shutdown()
        with contextlib.suppress(Exception):
            self.node.destroy_node()


class Hub:
    """Connections to the robots of one or more DDS domains (a context manager).

    ``team_link_domains`` are domains whose robots are reached through rf_bridge's team
    link (a bridge republishes them locally); their robots say so in ``RobotId.via``. A
    domain given in both is refused: it would be one participant with two meanings.

    ``plain_robots``: also count every top-level namespace that has running nodes as a
    robot (the root namespace is the robot ``/`` of its domain), so plain ROS 2 robots,
    which publish no efficient_comm statistics, can be reached too. Off by default, since
    any helper node in a root namespace (a tool, a test's peer) would then be a robot.
    Debug_gui's own nodes (named ``debug_gui...``) and hidden nodes (``_...``) never are.
    """

    def __init__(
        self,
        *,
        domains: Iterable[int] = (0,),
        team_link_domains: Iterable[int] = (),
        node_name: str = "debug_gui",
        plain_robots: bool = False,
    ) -> None:
        check_name(node_name, what="node name")
        self._team = {check_domain(d) for d in team_link_domains}
        self._domain_ids = [check_domain(d) for d in domains]
        both = sorted(self._team & set(self._domain_ids))
        if both:
            raise InvalidInput(
                f"domain {', '.join(map(str, both))} given both as a domain and as a "
                "team-link domain: name each domain once"
            )
        self._domain_ids.extend(sorted(self._team))
        self._plain_robots = bool(plain_robots)
        if not self._domain_ids:
            raise InvalidInput("the Hub needs at least one domain")
        self._node_name = node_name
        self._domains: dict[int, _Domain] = {}
        self._lock = threading.RLock()
        self._listeners: list[Callable[[], None]] = []
        self._feeds: set[Feed] = set()
        #: The streams the feeds share, by (robot, absolute topic, type, QoS).
        self._streams: dict[tuple[RobotId, str, type, object], _SharedStream] = {}
        self._counters: dict[tuple[RobotId, str], TopicCounter] = {}
        self._stop = threading.Event()
        self._started = False

    # -- life cycle --------------------------------------------------------------------

    def start(self) -> Hub:
        """Join every domain and start discovering robots (idempotent)."""
        with self._lock:
            if self._started:
                return self
            self._started = True
            try:
                for d in self._domain_ids:
                    via: Via = "team link" if d in self._team else "dds"
                    dom = _Domain(d, node_name=self._node_name, via=via)
                    self._domains[d] = dom
                    dom.thread = threading.Thread(
                        target=self._spin, args=(dom,), name=f"debug_gui domain {d}",
                        daemon=True,
                    )
                    dom.thread.start()
            except BaseException:
                self.close()
                raise
        return self

    def close(self) -> None:
        """Close every feed and leave every domain."""
        for feed in list(self._feeds):
            feed.close()
        self._stop.set()
        with self._lock:
            domains = list(self._domains.values())
            self._domains.clear()
        for dom in domains:
            dom.close()

    def __enter__(self) -> Hub:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.close()

    @property
    def domains(self) -> list[int]:
        return list(self._domain_ids)

    def _spin(self, dom: _Domain) -> None:
        next_scan = 0.0
        while dom.context.ok() and not self._stop.is_set():
            try:
                now = time.monotonic()
                if now >= next_scan:
                    next_scan = now + DISCOVERY_PERIOD_S
                    self._discover(dom)
                dom.executor.spin_once(timeout_sec=SPIN_TIMEOUT_S)
            except ExternalShutdownException:
                break
            except Exception:
                if not dom.context.ok() or self._stop.is_set():
                    break  # closing under us: rclpy raises on a context shut down mid-wait
                _log.exception("domain %d: executor or discovery failed", dom.domain)
        dom.run_pending()

    def _discover(self, dom: _Domain) -> None:
        now = time.monotonic()
        for topic, _types in dom.node.get_topic_names_and_types():
            robot = RobotId.from_stats_topic(dom.domain, topic, via=dom.via)
            if robot is not None and dom.node.count_publishers(topic) > 0:
                dom.last_seen[robot] = now
        if self._plain_robots:
            for robot in self._plain_robots_of(dom):
                dom.last_seen[robot] = now
        for robot, seen in list(dom.last_seen.items()):
            if now - seen > GONE_AFTER_S:
                del dom.last_seen[robot]
        found = set(dom.last_seen)
        if found != dom.robots:
            dom.robots = found
            self._notify()
        with self._lock:
            plain = [s for s in self._streams.values()
                     if not s.throttled and s.robot.domain == dom.domain]
        for stream in plain:
            stream.upgrade()

    def _plain_robots_of(self, dom: _Domain) -> set[RobotId]:
        """One robot per top-level namespace with nodes other than debug_gui's or hidden ones."""
        out = set()
        for name, namespace in dom.node.get_node_names_and_namespaces():
            if name.startswith(("_", _OWN_NODE_PREFIX)) or name == dom.node_name:
                continue
            top = namespace.strip("/").split("/", 1)[0]
            if top.startswith("_"):
                continue
            with contextlib.suppress(InvalidInput):
                out.add(RobotId(dom.domain, f"/{top}" if top else "/", via=dom.via))
        return out

    def _notify(self) -> None:
        with self._lock:
            listeners = list(self._listeners)
        for cb in listeners:
            try:
                cb()
            except Exception:
                _log.exception("on_robots_changed callback raised")

    # -- the Source protocol's clock -------------------------------------------------

    @property
    def live(self) -> bool:
        """Always True: robots running now (see debug_gui.source)."""
        return True

    def now(self) -> float:
        """Monotonic seconds: live, a message is as old as it is now."""
        return time.monotonic()

    def on_reset(self, callback: Callable[[], None]) -> Callable[[], None]:
        """A live source never resets (nothing delivered stops holding); the unsubscribe
        function returned does nothing."""
        return lambda: None

    # -- robots ------------------------------------------------------------------------

    def robots(self) -> list[RobotId]:
        """The robots seen now, sorted by domain and namespace."""
        with self._lock:
            domains = list(self._domains.values())
        return sorted(r for dom in domains for r in dom.robots)

    def wait_for_robots(self, count: int, *, timeout_s: float = 30.0) -> list[RobotId]:
        """Block until at least ``count`` robots are seen (or the timeout); returns them."""
        event = threading.Event()
        unsubscribe = self.on_robots_changed(event.set)
        try:
            end = time.monotonic() + timeout_s
            while len(robots := self.robots()) < count and time.monotonic() < end:
                event.wait(min(0.2, max(0.0, end - time.monotonic())))
                event.clear()
            return robots
        finally:
            unsubscribe()

    def on_robots_changed(self, callback: Callable[[], None]) -> Callable[[], None]:
        """Call ``callback()`` (no arguments; read :meth:`robots`) when robots come or go.

        Runs on a domain's executor thread. Returns a function that unsubscribes.
        """
        with self._lock:
            self._listeners.append(callback)

        def unsubscribe() -> None:
            with self._lock, contextlib.suppress(ValueError):
                self._listeners.remove(callback)

        return unsubscribe

    def _domain(self, robot: RobotId) -> _Domain:
        if not isinstance(robot, RobotId):
            raise InvalidInput(f"not a robot: {robot!r}")
        with self._lock:
            dom = self._domains.get(robot.domain)
        if dom is None or not dom.context.ok():
            raise RobotUnavailable(
                f"{robot.label}: domain {robot.domain} is not one this GUI joined "
                f"({', '.join(map(str, self._domain_ids))}) or the GUI is closing"
            )
        return dom

    def handle(self, robot: RobotId) -> NodeHandle:
        """The efficient_comm node handle of the robot's domain, for what the Hub lacks.

        Names are not put under the robot's namespace: use ``robot.resolve(name)``.
        Destroy what you create when your view deactivates.
        """
        return self._domain(robot).handle

    def topics(self, robot: RobotId) -> dict[str, list[str]]:
        """Topic names and types under the robot's namespace that someone publishes.

        As ``ros2 topic list`` shows them: hidden ``_`` topics are left out, and so are
        topics only the GUI itself takes part in (a view's subscription to a topic the
        robot does not publish makes it appear in the graph, but it is no robot's topic).
        """
        dom = self._domain(robot)
        own = (dom.node.get_name(), dom.node.get_namespace())
        out = {}
        for name, types in sorted(dom.node.get_topic_names_and_types()):
            if not robot.contains(name) or hidden(name):
                continue
            publishers = dom.node.get_publishers_info_by_topic(name)
            if any((p.node_name, p.node_namespace) != own for p in publishers):
                out[name] = list(types)
        return out

    def publishes_statistics(self, robot: RobotId) -> bool:
        """True if the robot publishes efficient_comm statistics now (a plain ROS 2 robot,
        found with ``plain_robots``, does not)."""
        return self.publishes(robot, robot.stats_topic)

    def publishes(self, robot: RobotId, topic: str) -> bool:
        """True if someone publishes ``topic`` (relative to the robot's namespace) now."""
        return self._domain(robot).node.count_publishers(robot.resolve(topic)) > 0

    def nodes(self, robot: RobotId) -> list[str]:
        """Fully qualified names of the nodes under the robot's namespace (not the GUI's)."""
        dom = self._domain(robot)
        own = dom.node.get_fully_qualified_name()
        out = set()
        for name, namespace in dom.node.get_node_names_and_namespaces():
            full = f"{namespace.rstrip('/')}/{name}"
            if full != own and robot.contains(full):
                out.add(full)
        return sorted(out)

    def services(self, robot: RobotId) -> dict[str, list[str]]:
        """Service names and types under the robot's namespace (hidden ``_`` ones left out)."""
        dom = self._domain(robot)
        return {
            name: list(types)
            for name, types in sorted(dom.node.get_service_names_and_types())
            if robot.contains(name) and not hidden(name)
        }

    # -- data --------------------------------------------------------------------------

    def subscribe(
        self,
        robot: RobotId,
        topic: str,
        msg_type: type,
        callback: Callable[[Any], None],
        *,
        rate_hz: float | None = None,
        qos: QoSLike = 10,
    ) -> Feed:
        """Receive ``topic`` (relative to the robot's namespace, or absolute) at ``rate_hz``.

        Through throttle_publisher when the topic has a throttle-aware publisher (the robot
        then sends only this rate), else plainly with the surplus dropped here. Feeds of
        one topic (same type and QoS) share one stream from the robot, at the highest rate
        any of them wants (see :class:`_SharedStream`). ``callback`` runs on the domain's
        executor thread.
        """
        check_name(topic, what="topic name")
        rate_hz = check_rate(rate_hz)
        full = robot.resolve(topic)
        feed = Feed(self, robot, full, callback, rate_hz=rate_hz)
        key = (robot, full, msg_type, _qos_key(qos))
        # Under the Hub's lock: a stream's last feed closing meanwhile (which takes it
        # first) must not leave this one joined to a closed stream.
        with self._lock:
            stream = self._streams.get(key)
            feed._stream = stream
            if stream is None:
                feed._stream = stream = _SharedStream(self, robot, full, msg_type, qos=qos)
                stream.open(feed)
                self._streams[key] = stream
            else:
                stream.join(feed)
            self._feeds.add(feed)
        return feed

    def _forget(self, feed: Feed) -> None:
        with self._lock:
            self._feeds.discard(feed)

    def _forget_stream(self, stream: _SharedStream) -> None:
        with self._lock:
            for key, known in list(self._streams.items()):
                if known is stream:
                    del self._streams[key]

    def _counter(self, robot: RobotId, topic: str) -> TopicCounter:
        with self._lock:
            return self._counters.setdefault((robot, topic), TopicCounter())

    def counters(self) -> dict[tuple[RobotId, str], TopicCounter]:
        """Messages and bytes received per (robot, absolute topic) since the start."""
        with self._lock:
            return {k: TopicCounter(v.messages, v.bytes) for k, v in self._counters.items()}

    def call(
        self,
        robot: RobotId,
        service: str,
        srv_type: type,
        request: Any,
        *,
        timeout_s: float = 5.0,
    ) -> Any:
        """Call a service of the robot and wait for the response (blocking).

        Never on a UI event loop, never from a feed callback (it would wait for itself).
        Raises RobotUnavailable when the service is not there, CallFailed on timeout.
        """
        check_name(service, what="service name")
        dom = self._domain(robot)
        if threading.current_thread() is dom.thread:
            raise InvalidInput("Hub.call from a feed callback would wait for itself")
        full = robot.resolve(service)
        with dom.clients_lock:
            client = dom.clients.get((full, srv_type))
            if client is None:
                client = dom.node.create_client(srv_type, full)
                dom.clients[(full, srv_type)] = client
        if not client.wait_for_service(timeout_sec=timeout_s):
            raise RobotUnavailable(f"{robot.label}: no service {full}")
        done = threading.Event()
        future = client.call_async(request)
        future.add_done_callback(lambda _f: done.set())
        if not done.wait(timeout_s):
            future.cancel()
            raise CallFailed(f"{robot.label}: {full} did not answer within {timeout_s:g} s")
        exc = future.exception()
        if exc is not None:
            raise CallFailed(f"{robot.label}: {full} failed: {exc}") from exc
        return future.result()


__all__ = ["STATS_SUFFIX", "Feed", "Hub", "TopicCounter", "hidden"]

if TYPE_CHECKING:
    _LIVE_IS_A_SOURCE: type[Source] = Hub
