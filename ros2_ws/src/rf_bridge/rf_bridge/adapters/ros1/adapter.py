"""The ROS 1 channel adapter: a ROS 1 node of its own, without rospy.

It registers the bridge's publications and subscriptions with the master, serves TCPROS to
ROS 1 subscribers and connects to ROS 1 publishers. A watchdog asks the master every
``master_check_s`` whether it still knows the bridge; after a master restart it registers
everything again, so ROS 1 nodes started later find the bridged topics without a restart.
rospy and roscpp nodes never register again after a restart, so the new master does not
name the publishers that were already running: the bridge keeps its links to them (they
still serve their topics) until one of them is gone, instead of dropping what the new
master does not list.

Every thread it starts ends when it is closed: :meth:`Ros1Adapter.close` unregisters, stops
the links, shuts the listener (closing alone does not wake a thread blocked in ``accept``)
and joins what it started, so a closed bridge leaves no socket listening behind it.
"""

from __future__ import annotations

import contextlib
import socket
import threading
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

from ..._log import Logger, RateLimitedLog
from ...config import Ros1Options
from ...core.adapter import Deliver, Route
from ...core.qos import ros1_latch
from ...errors import (
    LinkError,
    OutOfRangeError,
    ProtocolError,
    RfBridgeError,
    TranslationError,
)
from ...translate import Translator, TranslatorSet
from ._deadline import deadline
from .tcpros import InboundLink, OutboundConnection, encode_header, frame, read_header
from .xmlrpc import MasterRefusedError, SlaveServer, call

#: TCPROS handshakes in progress at once; a peer opening connections without sending a
#: header (or trickling it) holds one for at most the handshake timeout in all, further
#: connections are refused.
MAX_HANDSHAKES = 32
HANDSHAKE_TIMEOUT_S = 5.0
#: Publishers of one topic the bridge connects to; a publisherUpdate naming more (a real
#: system has a handful) is cut to this many, with a log line, instead of a thread each.
MAX_PUBLISHERS_PER_TOPIC = 64
#: How long :meth:`Ros1Adapter.close` waits for its threads altogether.
CLOSE_TIMEOUT_S = 5.0


@dataclass(eq=False)
class _Publication:
    route: Route
    ros1_type: str
    md5sum: str
    definition: str
    translator: Translator
    latch: bool
    connections: list[OutboundConnection] = field(default_factory=list)
    last: bytes | None = None


@dataclass(eq=False)
class _Subscription:
    route: Route
    ros1_type: str  # "*" when the type is learned from the publisher
    links: dict[str, InboundLink] = field(default_factory=dict)
    #: Publishers linked before a master restart that the new master does not list (they
    #: never register again): kept until their link fails, whatever the master says.
    unlisted: set[str] = field(default_factory=set)


class Ros1Adapter:
    name = "ros1"

    def __init__(self, options: Ros1Options, translators: TranslatorSet, logger: Logger) -> None:
        self.options = options
        self._translators = translators
        self._log = RateLimitedLog(logger)
        self._caller_id = options.node_name
        self._master = options.master_uri
        self._pubs: dict[str, _Publication] = {}
        self._subs: dict[str, _Subscription] = {}
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._deliver: Deliver | None = None
        self._listener: socket.socket | None = None
        self._slave: SlaveServer | None = None
        self._registered = threading.Event()
        self._threads: list[threading.Thread] = []
        self._handshakes = threading.BoundedSemaphore(MAX_HANDSHAKES)
        self.registrations = 0  # how many times everything was registered (restarts + 1)

    # --- lifecycle ---------------------------------------------------------------------

    def start(self, routes: Sequence[Route], deliver: Deliver) -> Sequence[Route]:
        self._deliver = deliver
        host = self.options.bind
        advertise = self.options.advertise_host or (host if host != "0.0.0.0" else "127.0.0.1")
        self._advertise = advertise
        self._listener = socket.create_server((host, 0))
        self._tcp_port = self._listener.getsockname()[1]
        self._slave = SlaveServer(
            host=host,
            advertise_host=advertise,
            master_uri=self._master,
            on_publishers=self._on_publishers,
            on_request=self._on_request,
            publications=lambda: [[t, p.ros1_type] for t, p in self._pubs.items()],
            subscriptions=lambda: [[t, s.ros1_type] for t, s in self._subs.items()],
            log=self._log,
        )
        served: list[Route] = []
        for route in routes:
            try:
                if (route.spec.outbound and route.peer_topic in self._pubs) or (
                    route.spec.inbound and route.peer_topic in self._subs
                ):
                    raise RfBridgeError("another entry bridges it the same way")
                publication = self._publication(route) if route.spec.outbound else None
                if route.spec.inbound:
                    self._add_subscription(route)
                if publication is not None:
                    self._pubs[route.peer_topic] = publication
            except RfBridgeError as exc:
                self._log.error(
                    f"topic {route.spec.ros2_topic} not bridged: ROS 1 {route.peer_topic}: {exc}"
                )
                continue
            served.append(route)
        for target, name in ((self._accept, "tcpros-accept"), (self._watch_master, "ros1-master")):
            thread = threading.Thread(target=target, name=name, daemon=True)
            thread.start()
            self._threads.append(thread)
        return served

    @property
    def uri(self) -> str:
        assert self._slave is not None
        return self._slave.uri

    def wait_registered(self, timeout_s: float) -> bool:
        return self._registered.wait(timeout_s)

    def close(self) -> None:
        if self._stop.is_set():
            return
        self._stop.set()
        if self._listener is not None:
            with contextlib.suppress(OSError):
                self._listener.shutdown(socket.SHUT_RDWR)  # wakes the accept thread
            self._listener.close()
        threads = list(self._threads)
        for topic, pub in list(self._pubs.items()):
            self._quietly("unregisterPublisher", topic)
            with self._lock:
                conns = list(pub.connections)
            for conn in conns:
                conn.close()
                threads.append(conn.thread)
        for topic, sub in list(self._subs.items()):
            self._quietly("unregisterSubscriber", topic)
            with self._lock:
                links = list(sub.links.values())
            for link in links:
                link.stop()
                threads.append(link.thread)
        if self._slave is not None:
            self._slave.close()
        deadline = time.monotonic() + CLOSE_TIMEOUT_S
        for thread in threads:
            thread.join(max(0.0, deadline - time.monotonic()))
        left = [t.name for t in threads if t.is_alive()]
        if left:
            self._log.warning(f"ROS 1 adapter closed; threads still ending: {', '.join(left)}")

    def _quietly(self, method: str, topic: str) -> None:
        with contextlib.suppress(LinkError):
            call(self._master, method, self._caller_id, topic, self.uri, timeout_s=0.5)

    # --- master --------------------------------------------------------------------------

    def _publication(self, route: Route) -> _Publication:
        ros1_type = self._translators.ros1_type_for(route.ros2_cls, route.spec.peer_type)
        registry = self._translators.registry
        return _Publication(
            route=route,
            ros1_type=ros1_type,
            md5sum=registry.md5sum(ros1_type),
            definition=registry.full_definition(ros1_type),
            translator=self._translators.translator(ros1_type, route.ros2_cls),
            latch=ros1_latch(route.spec.qos),
        )

    def _add_subscription(self, route: Route) -> None:
        ros1_type = route.spec.peer_type
        if ros1_type is None:
            ros1_type = self._translators.ros1_type_for(route.ros2_cls)
        self._subs[route.peer_topic] = _Subscription(route=route, ros1_type=ros1_type)

    def _register_all(self) -> None:
        for topic, pub in self._pubs.items():
            call(self._master, "registerPublisher", self._caller_id, topic, pub.ros1_type, self.uri)
        restarted = self.registrations > 0
        for topic, sub in self._subs.items():
            uris = call(
                self._master, "registerSubscriber", self._caller_id, topic, sub.ros1_type, self.uri
            )
            if restarted:
                with self._lock:
                    sub.unlisted |= set(sub.links) - set(uris)
            self._on_publishers(topic, list(uris))
        self.registrations += 1
        self._registered.set()

    def _watch_master(self) -> None:
        reachable = True
        while not self._stop.is_set():
            try:
                try:
                    known = call(self._master, "lookupNode", self._caller_id, self._caller_id)
                except MasterRefusedError:
                    known = None
                if known != self.uri:
                    if self.registrations:
                        self._log.warning(
                            f"ROS 1 master {self._master} does not know this bridge (restarted?): "
                            f"registering {len(self._pubs)} publication(s) and "
                            f"{len(self._subs)} subscription(s) again"
                        )
                    self._register_all()
                elif not reachable:
                    self._log.info(f"ROS 1 master {self._master} reachable again")
                reachable = True
            except LinkError as exc:
                if reachable:
                    self._log.warning(f"ROS 1 master unreachable: {exc}; retrying")
                reachable = False
            self._stop.wait(self.options.master_check_s)

    # --- ROS 2 -> ROS 1 --------------------------------------------------------------------

    def send(self, route: Route, msg: Any, received_ns: int) -> None:
        pub = self._pubs.get(route.peer_topic)
        if pub is None:
            route.stats_out.dropped("not_bridged")
            return
        conns = pub.connections
        if not conns and not pub.latch:
            route.stats_out.dropped("no_subscriber")
            return
        try:
            payload = self._translators.codec.encode(pub.ros1_type, pub.translator.to_ros1(msg))
        except OutOfRangeError as exc:
            route.stats_out.dropped("out_of_range")
            self._log.warning(f"not sent to ROS 1 {route.peer_topic}: {exc}")
            return
        except (TranslationError, ProtocolError, TypeError, ValueError, KeyError) as exc:
            route.stats_out.dropped("untranslatable")
            self._log.error(f"cannot translate a message for ROS 1 {route.peer_topic}: {exc}")
            return
        if len(payload) > self.options.max_message_bytes:
            route.stats_out.dropped("oversize")
            self._log.error(
                f"not sending a {len(payload)}-byte message on ROS 1 {route.peer_topic}: over "
                f"max_message_bytes ({self.options.max_message_bytes})"
            )
            return
        data = frame(payload)
        if pub.latch:
            pub.last = data
        if not conns:
            route.stats_out.dropped("no_subscriber")
            return
        for conn in conns:
            conn.send(data)
        route.stats_out.delivered(len(payload), time.perf_counter_ns() - received_ns)

    def _accept(self) -> None:
        assert self._listener is not None
        while not self._stop.is_set():
            try:
                sock, addr = self._listener.accept()
            except OSError:
                return
            if self._stop.is_set():
                sock.close()
                return
            if not self._handshakes.acquire(blocking=False):
                self._log.warning(
                    f"rejecting TCPROS connection from {addr[0]}:{addr[1]}: "
                    f"{MAX_HANDSHAKES} handshakes already in progress"
                )
                sock.close()
                continue
            threading.Thread(
                target=self._handshake, args=(sock, addr), name="tcpros-handshake", daemon=True
            ).start()

    def _handshake(self, sock: socket.socket, addr: Any) -> None:
        sock.settimeout(HANDSHAKE_TIMEOUT_S)
        try:
            with deadline(sock, HANDSHAKE_TIMEOUT_S) as expired:
                header = read_header(sock)
        except (OSError, LinkError, ProtocolError) as exc:
            reason = f"no header within {HANDSHAKE_TIMEOUT_S:g} s" if expired.is_set() else exc
            self._log.warning(f"rejecting TCPROS connection from {addr[0]}:{addr[1]}: {reason}")
            sock.close()
            return
        finally:
            self._handshakes.release()
        topic = header.get("topic", "")
        peer = header.get("callerid", f"{addr[0]}:{addr[1]}")
        pub = self._pubs.get(topic)
        error = None
        if pub is None:
            error = f"the bridge does not publish {topic!r}"
        elif header.get("md5sum", "*") not in ("*", pub.md5sum) and not self._learn(pub, header):
            error = (
                f"md5sum mismatch for {topic}: {pub.ros1_type} is {pub.md5sum}, "
                f"subscriber wants {header.get('md5sum')} ({header.get('type')})"
            )
        if error is not None or pub is None:
            self._log.warning(f"rejecting TCPROS subscriber {peer}: {error}")
            with contextlib.suppress(OSError):
                sock.sendall(encode_header({"error": str(error)}))
            sock.close()
            return
        reply = {
            "callerid": self._caller_id,
            "topic": topic,
            "type": pub.ros1_type,
            "md5sum": pub.md5sum,
            "message_definition": pub.definition,
            "latching": "1" if pub.latch else "0",
        }
        try:
            sock.sendall(encode_header(reply))
        except OSError as exc:
            self._log.warning(f"TCPROS subscriber {peer} on {topic} left during handshake: {exc}")
            sock.close()
            return
        if header.get("probe") == "1":
            sock.close()
            return
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        stats = pub.route.stats_out
        conn = OutboundConnection(
            sock,
            peer=peer,
            topic=topic,
            queue_size=self.options.queue_size,
            on_undelivered=stats.dropped,
            on_closed=lambda c: self._remove(pub, c),
            log=self._log,
        )
        with self._lock:
            if self._stop.is_set():  # closed during the handshake: close() did not see it
                conn.close()
                return
            if pub.latch and pub.last is not None:
                conn.send(pub.last)
            pub.connections = [*pub.connections, conn]  # copy on write: send() iterates freely
        self._log.info(f"ROS 1 subscriber {peer} connected to {topic}")

    def _learn(self, pub: _Publication, header: dict[str, str]) -> bool:
        """Adopt a subscriber's own definition of the published type when ours (derived
        from ROS 2) differs: ROS 1 defines the type, and rospy and roscpp send it."""
        definition = header.get("message_definition")
        if header.get("type") != pub.ros1_type or not definition:
            return False
        learned = TranslatorSet(self._translators.rules.values())
        try:
            learned.registry.add_full_definition(pub.ros1_type, definition)
            if learned.registry.md5sum(pub.ros1_type) != header.get("md5sum"):
                return False
            for dep in [pub.ros1_type, *learned.registry.dependencies(pub.ros1_type)]:
                self._translators.registry.add(learned.registry.get(dep))
                self._translators.forget(dep)
            translator = self._translators.translator(pub.ros1_type, pub.route.ros2_cls)
        except TranslationError as exc:
            self._log.warning(f"{pub.ros1_type} from a subscriber cannot be used: {exc}")
            return False
        with self._lock:
            pub.translator = translator
            pub.md5sum = self._translators.registry.md5sum(pub.ros1_type)
            pub.definition = self._translators.registry.full_definition(pub.ros1_type)
            pub.last = None
        self._log.info(
            f"learned {pub.ros1_type} ({pub.md5sum}) from a subscriber of {pub.route.peer_topic}; "
            f"not translated: {', '.join(translator.unmatched) or 'nothing'}"
        )
        return True

    def _remove(self, pub: _Publication, conn: OutboundConnection) -> None:
        with self._lock:
            pub.connections = [c for c in pub.connections if c is not conn]

    def _on_request(self, topic: str, protocols: list[list[Any]]) -> list[Any]:
        if topic not in self._pubs:
            raise LookupError(f"the bridge does not publish {topic!r}")
        if not any(isinstance(p, list) and p and p[0] == "TCPROS" for p in protocols):
            raise LookupError("only TCPROS is supported")
        return ["TCPROS", self._advertise, self._tcp_port]

    # --- ROS 1 -> ROS 2 --------------------------------------------------------------------

    def _on_publishers(self, topic: str, uris: list[str]) -> None:
        sub = self._subs.get(topic)
        if sub is None:
            return
        wanted = {u for u in uris if u != self.uri}  # never subscribe to ourselves
        with self._lock:
            if self._stop.is_set():  # checked under the lock close() takes the links with
                return
            sub.unlisted -= wanted  # the master knows it (again)
            wanted |= sub.unlisted & set(sub.links)
            if len(wanted) > MAX_PUBLISHERS_PER_TOPIC:
                self._log.warning(
                    f"{topic}: {len(wanted)} publishers named; connected to "
                    f"{MAX_PUBLISHERS_PER_TOPIC} of them (those already connected first)"
                )
                ranked = sorted(wanted, key=lambda u: (u not in sub.links, u))
                wanted = set(ranked[:MAX_PUBLISHERS_PER_TOPIC])
            for uri in list(sub.links):
                if uri not in wanted:
                    sub.links.pop(uri).stop()
            for uri in wanted - set(sub.links):
                sub.links[uri] = self._link(sub, uri)

    def _forget_unlisted(self, sub: _Subscription, uri: str) -> None:
        """A publisher the master does not list cannot be reached: it is gone, and no
        ``publisherUpdate`` will say so, so its link ends here."""
        with self._lock:
            if uri not in sub.unlisted:
                return
            sub.unlisted.discard(uri)
            link = sub.links.pop(uri, None)
        if link is not None:
            link.stop()
            self._log.info(
                f"{sub.route.peer_topic}: publisher {uri}, unknown to the restarted master, "
                "is gone; link closed"
            )

    def _link(self, sub: _Subscription, uri: str) -> InboundLink:
        route = sub.route
        state: dict[str, Any] = {}

        def request() -> tuple[str, int]:
            try:
                value = call(uri, "requestTopic", self._caller_id, route.peer_topic, [["TCPROS"]])
            except LinkError:
                self._forget_unlisted(sub, uri)
                raise
            if not isinstance(value, list) or len(value) != 3 or value[0] != "TCPROS":
                raise ProtocolError(f"publisher {uri} offered {value!r}, not TCPROS")
            return str(value[1]), int(value[2])

        def on_header(reply: dict[str, str]) -> None:
            ros1_type = reply.get("type", "")
            definition = reply.get("message_definition")
            registry = self._translators.registry
            try:
                if definition:
                    before = registry.md5sum(ros1_type) if ros1_type in registry else None
                    registry.add_full_definition(ros1_type, definition)
                    if before is not None and before != registry.md5sum(ros1_type):
                        self._translators.forget(ros1_type)
                if ros1_type not in registry:
                    raise TranslationError(f"unknown type {ros1_type!r} and no message_definition")
                if reply.get("md5sum") not in (None, "*", registry.md5sum(ros1_type)):
                    self._log.warning(
                        f"{route.peer_topic}: md5sum of {ros1_type} from {uri} differs from the "
                        "one computed from its definition; translating by field names"
                    )
                state["type"] = ros1_type
                state["translator"] = self._translators.translator(ros1_type, route.ros2_cls)
            except TranslationError as exc:
                route.stats_in.dropped("unknown_type")
                raise ProtocolError(f"cannot bridge {ros1_type!r} to ROS 2: {exc}") from None

        deliver = self._deliver
        assert deliver is not None
        codec = self._translators.codec

        def on_frame(payload: bytes) -> None:
            """One message: a malformed frame drops the connection (the stream may be out
            of step); a message that does not translate is dropped and counted, and the
            connection carries on with the next one."""
            received = time.perf_counter_ns()
            try:
                msg = state["translator"].to_ros2(codec.decode(state["type"], payload))
            except ProtocolError:
                route.stats_in.dropped("malformed")
                raise
            except OutOfRangeError as exc:
                route.stats_in.dropped("out_of_range")
                self._log.warning(f"not delivered from ROS 1 {route.peer_topic}: {exc}")
                return
            except TranslationError as exc:
                route.stats_in.dropped("untranslatable")
                self._log.error(f"cannot translate a message from ROS 1 {route.peer_topic}: {exc}")
                return
            deliver(route, msg, received, len(payload))

        def on_oversize() -> None:
            route.stats_in.dropped("oversize")

        return InboundLink(
            publisher_uri=uri,
            topic=route.peer_topic,
            request=request,
            header={
                "callerid": self._caller_id,
                "topic": route.peer_topic,
                "md5sum": "*",
                "type": sub.ros1_type,
                "tcp_nodelay": "1",
            },
            max_bytes=self.options.max_message_bytes,
            on_header=on_header,
            on_frame=on_frame,
            on_oversize=on_oversize,
            log=self._log,
        )
