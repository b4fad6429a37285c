"""The Foxglove WebSocket endpoint: the Hub's robots for Foxglove, Lichtblick and PlotJuggler.

The GUI is one viewer; the ecosystem's viewers speak the Foxglove WebSocket protocol. This
endpoint offers them what the Hub sees, the way foxglove_bridge offers one ROS graph: every
robot's topics as channels (``cdr`` messages with ``ros2msg`` schemas, the complete
definition text rosbag2_layout builds), every node's parameters as ``/node.param`` (get,
set, and updates made elsewhere through ``/parameter_events``) and every service (called
through the Hub). It is built on foxglove-sdk's server; the gate in front of it
(``_foxglove_gate``) adds the older protocol name and the token.

Unlike foxglove_bridge it does not subscribe to everything: a robot's topic is subscribed
(through the Hub, so a ThrottledPublisher sees the demand) only while at least one viewer
subscribes to its channel, and released when the last one leaves. A robot nobody looks at
through Foxglove costs nothing.

Names: with one DDS domain, channels, parameters and services carry their ROS names. With
several, two robots may share a namespace, so every name is prefixed with ``/domain<N>``.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import Any

import foxglove
from foxglove.websocket import (
    Capability,
    ChannelView,
    Client,
    MessageSchema,
    Parameter,
    ParameterType,
    ServerListener,
    Service,
    ServiceRequest,
    ServiceSchema,
    StatusLevel,
    WebSocketServer,
)
from rcl_interfaces.msg import ParameterEvent, ParameterValue
from rcl_interfaces.msg import ParameterType as RosType
from rclpy.serialization import deserialize_message, serialize_message

from efficient_comm import matching_qos
from rosbag2_layout import (
    Rosbag2Error,
    full_definition,
    import_service,
    import_type,
    service_definitions,
)

from . import params
from ._foxglove_gate import Gate
from .errors import AccessDenied, DebugGuiError, InvalidInput, RobotUnavailable
from .hub import Feed, Hub
from .robots import RobotId
from .security import AccessPolicy, check_port
from .source import Stream

__all__ = ["DEFAULT_PORT", "FoxgloveEndpoint", "serve_foxglove", "start"]

_log = logging.getLogger(__name__)
DEFAULT_PORT = 8765  # the port Foxglove's "open connection" dialog proposes
_CDR = "cdr"
_ROS2MSG = "ros2msg"
_PARAM_SEP = "."
#: A topic missing from a robot's graph for less than this keeps its channel. A DDS graph
#: can miss an endpoint for a moment on a loaded machine; a channel withdrawn and advertised
#: again gets a new id, and a viewer's subscription made with the old one fails ("unknown
#: channel"). A robot that is gone (the Hub's own grace period passed) loses its channels
#: at once.
WITHDRAW_AFTER_S = 1.5


@dataclass
class _Channel:
    """One robot's topic as a Foxglove channel, and the viewers subscribed to it."""

    robot: RobotId
    topic: str
    msg_type: type
    channel: foxglove.Channel
    clients: set[int] = field(default_factory=set)
    feed: Feed | None = None


@dataclass(frozen=True)
class _Target:
    """What a public (Foxglove-side) name stands for on a robot."""

    robot: RobotId
    name: str  # absolute ROS name


class _Naming:
    """Public names of ROS names: prefixed by the domain when the Hub serves several."""

    def __init__(self, domains: Iterable[int]) -> None:
        self.prefixed = len(set(domains)) > 1

    def public(self, robot: RobotId, name: str) -> str:
        return f"/domain{robot.domain}{name}" if self.prefixed else name


def _to_foxglove(name: str, value: ParameterValue) -> Parameter:
    """A ROS parameter value as the protocol carries it (type hints where JSON is ambiguous)."""
    kind, plain = value.type, params.python_value(value)
    if kind == RosType.PARAMETER_DOUBLE:
        return Parameter(name, value=plain, type=ParameterType.Float64)
    if kind == RosType.PARAMETER_BYTE_ARRAY:
        return Parameter(name, value=plain, type=ParameterType.ByteArray)
    if kind == RosType.PARAMETER_DOUBLE_ARRAY:
        return Parameter(name, value=plain, type=ParameterType.Float64Array)
    if plain is None:
        return Parameter(name)
    return Parameter(name, value=plain)


def _to_ros(value: object, hint: ParameterType | None, current: int) -> ParameterValue:
    """A viewer's value as a ROS ParameterValue of the parameter's current type (the
    protocol's Float64 hints say a whole number is meant as a double)."""
    return params.to_ros(value, current=current,
                         doubles=hint in (ParameterType.Float64, ParameterType.Float64Array))


class _Bridge(ServerListener):
    """The Hub on one side, the SDK server on the other; the SDK calls its on_* methods."""

    def __init__(self, hub: Hub, context: foxglove.Context, naming: _Naming) -> None:
        self._hub = hub
        self._context = context
        self._naming = naming
        self._lock = threading.RLock()
        self._channels: dict[int, _Channel] = {}
        self._by_topic: dict[tuple[RobotId, str, str], _Channel] = {}
        self._missing_since: dict[tuple[RobotId, str, str], float] = {}
        self._services: dict[str, tuple[RobotId, str]] = {}
        self._watched_params: set[str] = set()
        # SDK client id -> may it write; only the gate's connections are here (see the gate).
        self._writers: dict[int, bool] = {}
        self._introduced: dict[str, bool] = {}
        self._param_feeds: dict[RobotId, Stream] = {}
        self.server: WebSocketServer | None = None

    # -- what exists: topics and services, kept in step with the Hub ----------------------

    def sync(self) -> None:
        """Advertise new topics and services, withdraw vanished ones."""
        topics: dict[tuple[RobotId, str, str], None] = {}
        services: dict[str, tuple[RobotId, str, str]] = {}
        robots = self._hub.robots()
        for robot in robots:
            try:
                for topic, types in self._hub.topics(robot).items():
                    if types:
                        topics[(robot, robot.resolve(topic), types[0])] = None
                for service, types in self._hub.services(robot).items():
                    if types:
                        name = robot.resolve(service)
                        services[self._naming.public(robot, name)] = (robot, name, types[0])
            except RobotUnavailable:
                continue
        with self._lock:
            now = time.monotonic()
            gone = []
            for key in self._by_topic:
                if key in topics:
                    self._missing_since.pop(key, None)
                    continue
                since = self._missing_since.setdefault(key, now)
                if key[0] not in robots or now - since >= WITHDRAW_AFTER_S:
                    gone.append(key)
            new = [key for key in topics if key not in self._by_topic]
            closing = [self._forget(key) for key in gone]
            for key in new:
                self._advertise(*key)
            old_services = set(self._services) - set(services)
            new_services = {name: target for name, target in services.items()
                            if name not in self._services}
        for channel in closing:
            channel.channel.close()  # may call on_unsubscribe: outside the lock's body
            if channel.feed is not None:
                channel.feed.close()
        self._update_services(old_services, new_services)

    def _advertise(self, robot: RobotId, topic: str, type_name: str) -> None:
        try:
            msg_type = import_type(type_name)
            schema = foxglove.Schema(name=type_name, encoding=_ROS2MSG,
                                     data=full_definition(type_name).encode())
        except Rosbag2Error:
            return  # a type this machine does not have cannot be decoded here either
        channel = foxglove.Channel(
            self._naming.public(robot, topic), message_encoding=_CDR, schema=schema,
            context=self._context,
            metadata={"robot": robot.label, "domain": str(robot.domain),
                      "namespace": robot.namespace, "ros_topic": topic})
        entry = _Channel(robot, topic, msg_type, channel)
        self._channels[channel.id()] = entry
        self._by_topic[(robot, topic, type_name)] = entry

    def _forget(self, key: tuple[RobotId, str, str]) -> _Channel:
        entry = self._by_topic.pop(key)
        self._missing_since.pop(key, None)
        self._channels.pop(entry.channel.id(), None)
        return entry

    def _update_services(self, old: set[str],
                         new: dict[str, tuple[RobotId, str, str]]) -> None:
        server = self.server
        if server is None:
            return
        if old:
            server.remove_services(sorted(old))
            with self._lock:
                for name in old:
                    self._services.pop(name, None)
        added = []
        for public, (robot, name, type_name) in new.items():
            try:
                request_def, response_def = service_definitions(type_name)
                import_service(type_name)
            except Rosbag2Error:
                continue
            schema = ServiceSchema(type_name, request=MessageSchema(
                encoding=_CDR, schema=foxglove.Schema(
                    name=f"{type_name}_Request", encoding=_ROS2MSG, data=request_def.encode())),
                response=MessageSchema(encoding=_CDR, schema=foxglove.Schema(
                    name=f"{type_name}_Response", encoding=_ROS2MSG,
                    data=response_def.encode())))
            added.append(Service(public, schema=schema, handler=self._call_service))
            with self._lock:
                self._services[public] = (robot, name)
        if added:
            server.add_services(added)

    # -- topics: subscribe on the robot only while a viewer subscribes --------------------

    def on_subscribe(self, client: Client, channel: ChannelView) -> None:
        with self._lock:
            entry = self._channels.get(channel.id)
            if entry is None:
                return
            entry.clients.add(client.id)
            if entry.feed is not None:
                return
            log = entry.channel.log
            # What the publishers offer: best effort reaches a best-effort camera, transient
            # local gives a latched topic's last message, as foxglove_bridge does.
            try:
                offered = self._hub.handle(entry.robot).graph.publishers_qos(entry.topic)
                entry.feed = self._hub.subscribe(
                    entry.robot, entry.topic, entry.msg_type,
                    lambda msg: log(serialize_message(msg), log_time=time.time_ns()),
                    qos=matching_qos(offered))
            except DebugGuiError as exc:  # the robot went away: its channel goes at the next sync
                self._status(f"{channel.topic}: {exc}", StatusLevel.Warning)

    def on_unsubscribe(self, client: Client, channel: ChannelView) -> None:
        with self._lock:
            entry = self._channels.get(channel.id)
            if entry is None:
                return
            entry.clients.discard(client.id)
            feed = entry.feed if not entry.clients else None
            if feed is not None:
                entry.feed = None
        if feed is not None:
            feed.close()

    def subscribed_topics(self) -> list[tuple[RobotId, str]]:
        """Robot topics subscribed for viewers right now (what the robot sees asked of it)."""
        with self._lock:
            return [(e.robot, e.topic) for e in self._channels.values() if e.feed is not None]

    # -- services -------------------------------------------------------------------------

    def _call_service(self, request: ServiceRequest) -> bytes:
        """Forward one viewer's call; raising sends the viewer a serviceCallFailure."""
        if not self._may_write(request.client_id):  # only a gate connection with the token
            raise AccessDenied("calling services needs the token")
        with self._lock:
            target = self._services.get(request.service_name)
        if target is None:
            raise InvalidInput(f"no service {request.service_name!r}")
        robot, name = target
        if request.encoding != _CDR:
            raise InvalidInput(f"service requests must be cdr, not {request.encoding!r}")
        type_name = self._service_type(robot, name)
        srv_type: Any = import_service(type_name)
        try:
            ros_request = deserialize_message(request.payload, srv_type.Request)
        except Exception as exc:  # rclpy raises bare RuntimeError/TypeError on bad CDR
            raise InvalidInput(f"the request is not a CDR {type_name} request: {exc}") from exc
        response = self._hub.call(robot, name, srv_type, ros_request)
        return bytes(serialize_message(response))

    def _service_type(self, robot: RobotId, name: str) -> str:
        types = self._hub.services(robot).get(name) or []
        if not types:
            raise RobotUnavailable(f"{robot.label} no longer offers {name}")
        return types[0]

    # -- parameters: the rcl_interfaces services of every node, through the Hub -----------

    def _split(self, public: str) -> tuple[RobotId, str, str]:
        """``[/domainN]/node.param`` -> (robot, node, param)."""
        node, sep, param = public.partition(_PARAM_SEP)
        if not sep or not param:
            raise InvalidInput(f"parameter names are /node.param, not {public!r}")
        for robot in self._hub.robots():
            for fq_node in self._hub.nodes(robot):
                if self._naming.public(robot, fq_node) == node:
                    return robot, fq_node, param
        raise RobotUnavailable(f"no node {node!r} on any robot")

    def _get(self, robot: RobotId, node: str, names: list[str] | None) -> list[Parameter]:
        """Named parameters of ``node``, or all of them (``names=None``, sooner given up)."""
        return self._published(robot, node, params.get(self._hub, robot, node, names=names))

    def _published(self, robot: RobotId, node: str,
                   values: dict[str, ParameterValue]) -> list[Parameter]:
        prefix = self._naming.public(robot, node) + _PARAM_SEP
        return [_to_foxglove(prefix + name, value) for name, value in values.items()]

    def _get_all(self) -> list[Parameter]:
        """Every node's parameters, the nodes asked in parallel."""
        nodes = [(robot, node) for robot in self._hub.robots()
                 for node in self._hub.nodes(robot)]
        return [p for robot, node, values in params.get_many(self._hub, nodes)
                for p in self._published(robot, node, values)]

    def introduce(self, nonce: str, may_write: bool) -> None:
        """The gate's next connection will ask for parameters with this request id."""
        with self._lock:
            self._introduced[nonce] = may_write

    def _may_write(self, client_id: int) -> bool:
        with self._lock:
            return self._writers.get(client_id, False)

    def on_get_parameters(self, client: Client, param_names: list[str],
                          request_id: str | None = None) -> list[Parameter]:
        with self._lock:
            introduced = self._introduced.pop(request_id, None) if request_id else None
            if introduced is not None:
                self._writers[client.id] = introduced
                return []
        out: list[Parameter] = []
        if not param_names:
            return self._get_all()
        wanted: dict[tuple[RobotId, str], list[str]] = {}
        for public in param_names:
            try:
                robot, node, param = self._split(public)
            except DebugGuiError as exc:
                self._status(f"get {public}: {exc}", StatusLevel.Warning)
                continue
            wanted.setdefault((robot, node), []).append(param)
        for (robot, node), names in wanted.items():
            try:
                out.extend(self._get(robot, node, names))
            except DebugGuiError as exc:
                self._status(f"get parameters of {node}: {exc}", StatusLevel.Warning)
        return out

    def on_set_parameters(self, client: Client, parameters: list[Parameter],
                          request_id: str | None = None) -> list[Parameter]:
        if not self._may_write(client.id):  # only a gate connection with the token
            self._status("setting parameters needs the token", StatusLevel.Error)
            return []
        grouped: dict[tuple[RobotId, str], list[tuple[str, Parameter]]] = {}
        for parameter in parameters:
            try:
                robot, node, param = self._split(parameter.name)
            except DebugGuiError as exc:
                self._status(f"set {parameter.name}: {exc}", StatusLevel.Error)
                continue
            grouped.setdefault((robot, node), []).append((param, parameter))
        out: list[Parameter] = []
        for (robot, node), items in grouped.items():
            try:
                out.extend(self._set(robot, node, items))
            except DebugGuiError as exc:
                self._status(f"set parameters of {node}: {exc}", StatusLevel.Error)
        return out

    def _set(self, robot: RobotId, node: str,
             items: list[tuple[str, Parameter]]) -> list[Parameter]:
        names = [name for name, _ in items]
        current = params.get_values(self._hub, robot, node, names)
        values: dict[str, ParameterValue] = {}
        for name, parameter in items:
            now = current.get(name)
            try:
                values[name] = _to_ros(parameter.get_value(), parameter.type,
                                       now.type if now is not None else RosType.PARAMETER_NOT_SET)
            except InvalidInput as exc:
                self._status(f"{parameter.name}: {exc}", StatusLevel.Error)
        for outcome in params.set_values(self._hub, robot, node, values):
            if not outcome.successful:  # a veto: say why, the value stays as it was
                self._status(f"{self._naming.public(robot, node)}{_PARAM_SEP}{outcome.name} "
                             f"refused: {outcome.reason}", StatusLevel.Error)
        return self._get(robot, node, names)

    def on_parameters_subscribe(self, param_names: list[str]) -> None:
        robots = set()
        with self._lock:
            self._watched_params.update(param_names)
        for public in param_names:
            try:
                robots.add(self._split(public)[0])
            except DebugGuiError:
                continue
        with self._lock:
            for robot in robots - set(self._param_feeds):
                self._param_feeds[robot] = params.watch(self._hub, robot,
                                                        self._events_of(robot))

    def on_parameters_unsubscribe(self, param_names: list[str]) -> None:
        with self._lock:
            self._watched_params.difference_update(param_names)
            if self._watched_params:
                return
            feeds, self._param_feeds = list(self._param_feeds.values()), {}
        for feed in feeds:
            feed.close()

    def _events_of(self, robot: RobotId) -> Callable[[ParameterEvent], None]:
        def on_event(event: ParameterEvent) -> None:
            prefix = self._naming.public(robot, event.node) + _PARAM_SEP
            with self._lock:
                changed = [_to_foxglove(prefix + p.name, p.value)
                           for p in [*event.new_parameters, *event.changed_parameters]
                           if prefix + p.name in self._watched_params]
            if changed and self.server is not None:
                self.server.publish_parameter_values(changed)
        return on_event

    def _status(self, message: str, level: StatusLevel) -> None:
        if self.server is not None:
            self.server.publish_status(message, level)

    def close(self) -> None:
        with self._lock:
            feeds: list[Stream] = [e.feed for e in self._channels.values() if e.feed is not None]
            feeds.extend(self._param_feeds.values())
            for entry in self._channels.values():
                entry.feed = None
            self._param_feeds = {}
        for feed in feeds:
            feed.close()


def _allowed(check: Callable[[str | None], None]) -> Callable[[str | None], bool]:
    def allowed(token: str | None) -> bool:
        try:
            check(token)
        except AccessDenied:
            return False
        return True
    return allowed


class FoxgloveEndpoint:
    """A running endpoint; ``close()`` (or leaving the ``with`` block) stops it.

    ``port`` is where viewers connect (``url``); ``subscribed_topics()`` tells which robot
    topics are subscribed for viewers right now.
    """

    def __init__(self, hub: Hub, *, policy: AccessPolicy, port: int, refresh_s: float) -> None:
        self._policy = policy
        self._context = foxglove.Context()
        self._bridge = _Bridge(hub, self._context, _Naming(hub.domains))
        self._stop = threading.Event()
        self._wake = threading.Event()
        self._refresh_s = refresh_s
        self._server = foxglove.start_server(
            name="debug_gui", host="127.0.0.1", port=0, context=self._context,
            capabilities=[Capability.Parameters, Capability.Services],
            server_listener=self._bridge, supported_encodings=[_CDR])
        self._bridge.server = self._server
        self._gate = Gate(host=policy.host, port=port, backend_port=self._server.port,
                          may_connect=_allowed(policy.check_read),
                          may_write=_allowed(policy.check_write),
                          introduce=self._bridge.introduce)
        try:
            self._gate.start()
        except DebugGuiError:
            self._server.stop()
            raise
        self.port = self._gate.port
        self._unsubscribe_robots = hub.on_robots_changed(lambda *_: self._wake.set())
        self._bridge.sync()
        self._thread = threading.Thread(target=self._refresh, name="foxglove-sync",
                                        daemon=True)
        self._thread.start()

    @property
    def url(self) -> str:
        """Where a viewer connects to look (beyond loopback it needs :attr:`write_url`)."""
        host = self._policy.host
        return f"ws://{f'[{host}]' if ':' in host else host}:{self.port}/"

    @property
    def write_url(self) -> str:
        """The URL with the token: what a viewer that sets parameters or calls services opens."""
        return f"{self.url}?token={self._policy.token}"

    def subscribed_topics(self) -> list[tuple[RobotId, str]]:
        return self._bridge.subscribed_topics()

    @property
    def sdk_port(self) -> int:
        """The SDK server's own loopback port behind the gate (writes there are refused)."""
        return self._server.port

    def _refresh(self) -> None:
        while not self._stop.is_set():
            self._wake.wait(self._refresh_s)
            self._wake.clear()
            if self._stop.is_set():
                return
            try:
                self._bridge.sync()
            except DebugGuiError:
                continue  # a robot vanished mid-sync: the next round sees the new state
            except Exception:  # keep serving: one bad round must not end discovery
                _log.exception("Foxglove endpoint: updating channels and services failed")

    def close(self) -> None:
        """Stop serving and release every subscription on the robots; idempotent."""
        if self._stop.is_set():
            return
        self._stop.set()
        self._wake.set()
        self._unsubscribe_robots()
        self._thread.join(timeout=5.0)
        self._gate.close()
        self._server.stop()
        self._bridge.close()

    def __enter__(self) -> FoxgloveEndpoint:
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()


def serve_foxglove(hub: Hub, *, policy: AccessPolicy, port: int = DEFAULT_PORT,
                   refresh_s: float = 1.0) -> FoxgloveEndpoint:
    """Serve the Hub's robots to Foxglove viewers on ``ws://policy.host:port/``.

    The GUI's rules, from the same :class:`AccessPolicy`: beyond loopback a viewer must
    present the token to connect at all; writes (parameters, service calls) always need it
    (``ws://host:port/?token=TOKEN``, :attr:`FoxgloveEndpoint.write_url`); without it a
    viewer looks but cannot change anything. ``port=0`` picks a free port.
    """
    check_port(port)
    return FoxgloveEndpoint(hub, policy=policy, port=port, refresh_s=refresh_s)


def start(hub: Hub, *, host: str, port: int, policy: AccessPolicy) -> FoxgloveEndpoint:
    """What ``debug_gui --foxglove-port P`` runs: serve, and print where viewers connect.

    ``host`` must be the policy's (the one address both the GUI and the endpoint bind).
    """
    if host != policy.host:
        raise InvalidInput(f"the Foxglove endpoint binds the GUI's host {policy.host}, "
                           f"not {host}")
    endpoint = serve_foxglove(hub, policy=policy, port=port)
    print(f"debug_gui: Foxglove viewers connect to {endpoint.url} "
          f"(to set parameters and call services: {endpoint.write_url})", flush=True)
    return endpoint
