"""The bridge file: which topics go where, how, and how foreign types map.

::

    ros1:                              # optional: a ROS 1 system
      master_uri: http://127.0.0.1:11311/   # default: $ROS_MASTER_URI
      node_name: /rf_bridge
      bind: 127.0.0.1                  # listeners (XML-RPC, TCPROS); 0.0.0.0 to open up
      max_message_bytes: 67108864      # larger frames drop that connection
      queue_size: 100                  # per ROS 1 subscriber; older messages dropped beyond
    team:                              # optional: robot-to-robot link (Zenoh)
      robot_id: robot1
      listen: [tcp/127.0.0.1:7447]
      connect: []
      compression: zlib                # or none
      max_message_bytes: 67108864      # larger samples (after decompression) are dropped
      budget_bytes_per_s: 2048         # what this robot may send, all topics (default: no limit)
      budget_burst_bytes: 2048         # at most this much at once (default: 1 s of budget)
    stats_period_s: 10                 # log statistics every 10 s (default 0: never)
    usage_period_s: 1                  # the links' usage on /diagnostics (default 1; 0: never)
    topics:
      - ros2: /chatter                 # ROS 2 topic
        type: std_msgs/msg/String      # ROS 2 type (or given by peer_type and a rule)
        peer: ros1                     # ros1 | team
        peer_topic: /chatter           # default: the ROS 2 name
        peer_type: std_msgs/String     # default: derived from the ROS 2 type
        direction: to_peer             # to_peer | from_peer | both
        qos: {depth: 10, reliability: reliable, durability: volatile}
        throttle: {max_rate_hz: 5.0, every_nth: 1, mode: local}   # mode: local | publisher
    types:                             # rules where names do not match; a rule applies to
                                       # the topics whose peer_type is its ros1 type
      - ros1: lab_msgs/Sighting
        ros2: geometry_msgs/msg/Vector3
        fields: {x: distance, y: bearing}   # ROS 2 field: ROS 1 field
        ros1_definition: "float64 distance\\nfloat64 bearing"   # only to publish it

Every error names the file and the entry; a topic whose entry is wrong is reported and the
others still load (``BridgeConfig.errors``).
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import yaml
from rclpy.qos import QoSProfile

from throttle_publisher import ThrottleOptions
from throttle_publisher.errors import ThrottleError

from .core.qos import profile_from_config
from .errors import ConfigError
from .translate import TypeRule

Direction = Literal["to_peer", "from_peer", "both"]
PEERS = ("ros1", "team")


@dataclass(frozen=True, kw_only=True)
class Ros1Options:
    master_uri: str
    node_name: str = "/rf_bridge"
    bind: str = "127.0.0.1"
    advertise_host: str | None = None  # what peers are told to connect to; default: bind
    max_message_bytes: int = 64 << 20
    queue_size: int = 100
    master_check_s: float = 0.5


@dataclass(frozen=True, kw_only=True)
class TeamOptions:
    robot_id: str
    listen: tuple[str, ...] = ()
    connect: tuple[str, ...] = ()
    compression: Literal["zlib", "none"] = "zlib"
    prefix: str = "rf_team"
    multicast_scouting: bool = False
    lease_s: float = 3.0
    max_message_bytes: int = 64 << 20
    #: Bytes per second this robot may send over all team topics (0: no budget) and at
    #: most at once (0: one second's worth); see core/budget.py.
    budget_bytes_per_s: float = 0.0
    budget_burst_bytes: int = 0


@dataclass(frozen=True, kw_only=True)
class TopicSpec:
    ros2_topic: str
    ros2_type: str | None
    peer: str
    peer_topic: str
    peer_type: str | None
    direction: Direction
    qos: QoSProfile
    throttle: ThrottleOptions | None = None
    throttle_mode: Literal["local", "publisher"] = "local"

    @property
    def outbound(self) -> bool:
        return self.direction in ("to_peer", "both")

    @property
    def inbound(self) -> bool:
        return self.direction in ("from_peer", "both")


@dataclass(frozen=True, kw_only=True)
class BridgeConfig:
    topics: tuple[TopicSpec, ...] = ()
    rules: tuple[TypeRule, ...] = ()
    ros1: Ros1Options | None = None
    team: TeamOptions | None = None
    stats_period_s: float = 0.0  # log every topic's statistics this often (0: never)
    usage_period_s: float = 1.0  # publish the links' usage on /diagnostics (0: never)
    errors: tuple[str, ...] = field(default=())


def load_config(path: str | os.PathLike[str]) -> BridgeConfig:
    """Read a bridge file; raises ConfigError if it cannot be used at all."""
    try:
        data = yaml.safe_load(Path(path).read_text())
    except OSError as exc:
        raise ConfigError(f"{path}: cannot read: {exc}") from None
    except yaml.YAMLError as exc:
        raise ConfigError(f"{path}: invalid YAML: {exc}") from None
    return parse_config(data if data is not None else {}, source=str(path))


def parse_config(data: Any, *, source: str = "<config>") -> BridgeConfig:
    if not isinstance(data, Mapping):
        raise ConfigError(f"{source}: the top level must be a mapping")
    unknown = set(data) - {"ros1", "team", "topics", "types", "stats_period_s",
                           "usage_period_s"}
    if unknown:
        raise ConfigError(f"{source}: unknown sections {sorted(unknown)}")
    ros1 = _ros1(data.get("ros1"), f"{source}: ros1") if "ros1" in data else None
    team = _team(data.get("team"), f"{source}: team") if "team" in data else None
    rules = tuple(_rule(r, f"{source}: types[{i}]") for i, r in enumerate(data.get("types") or []))
    topics: list[TopicSpec] = []
    errors: list[str] = []
    for i, entry in enumerate(data.get("topics") or []):
        where = f"{source}: topics[{i}]"
        try:
            spec = _topic(entry, where)
            if spec.peer == "ros1" and ros1 is None:
                raise ConfigError(f"{where}: peer ros1 needs a 'ros1' section")
            if spec.peer == "team" and team is None:
                raise ConfigError(f"{where}: peer team needs a 'team' section")
            topics.append(spec)
        except ConfigError as exc:
            errors.append(str(exc))
    period = _typed(data.get("stats_period_s", 0.0), (int, float), f"{source}: stats_period_s")
    if period < 0:
        raise ConfigError(f"{source}: stats_period_s must be >= 0, not {period!r}")
    usage = _typed(data.get("usage_period_s", 1.0), (int, float), f"{source}: usage_period_s")
    if usage < 0:
        raise ConfigError(f"{source}: usage_period_s must be >= 0, not {usage!r}")
    return BridgeConfig(
        topics=tuple(topics), rules=rules, ros1=ros1, team=team, errors=tuple(errors),
        stats_period_s=float(period), usage_period_s=float(usage),
    )


def _mapping(value: Any, where: str, allowed: set[str]) -> Mapping[str, Any]:
    if value is None:
        value = {}
    if not isinstance(value, Mapping):
        raise ConfigError(f"{where}: must be a mapping, not {value!r}")
    unknown = set(value) - allowed
    if unknown:
        raise ConfigError(f"{where}: unknown keys {sorted(unknown)}")
    return value


def _keys(options: type) -> set[str]:
    """The keys a section accepts are its options' fields: one list to keep up to date."""
    return {f.name for f in dataclasses.fields(options)}


def _typed(value: Any, kind: type | tuple[type, ...], where: str) -> Any:
    if (isinstance(value, bool) and kind is not bool) or not isinstance(value, kind):
        raise ConfigError(f"{where}: expected {kind}, not {value!r}")
    return value


def _positive(m: Mapping[str, Any], key: str, default: float, kind: type, where: str) -> Any:
    """An option that must be a number above zero (a zero timeout or limit would stall or
    refuse everything without saying why)."""
    value = _typed(m.get(key, default), kind if kind is int else (int, float), f"{where}.{key}")
    if value <= 0:
        raise ConfigError(f"{where}.{key}: must be > 0, not {value!r}")
    return value if kind is int else float(value)


def _ros1(value: Any, where: str) -> Ros1Options:
    m = _mapping(value, where, _keys(Ros1Options))
    master = m.get("master_uri") or os.environ.get("ROS_MASTER_URI")
    if not master:
        raise ConfigError(f"{where}: no master_uri and no ROS_MASTER_URI in the environment")
    node_name = _typed(m.get("node_name", "/rf_bridge"), str, f"{where}.node_name")
    if not node_name.startswith("/"):
        node_name = "/" + node_name
    advertise = m.get("advertise_host")
    if advertise is not None:
        advertise = _typed(advertise, str, f"{where}.advertise_host")
    return Ros1Options(
        master_uri=_typed(master, str, f"{where}.master_uri"),
        node_name=node_name,
        bind=_typed(m.get("bind", "127.0.0.1"), str, f"{where}.bind"),
        advertise_host=advertise,
        max_message_bytes=_positive(m, "max_message_bytes", 64 << 20, int, where),
        queue_size=_positive(m, "queue_size", 100, int, where),
        master_check_s=_positive(m, "master_check_s", 0.5, float, where),
    )


def _team(value: Any, where: str) -> TeamOptions:
    m = _mapping(value, where, _keys(TeamOptions))
    robot_id = _typed(m.get("robot_id"), str, f"{where}.robot_id")
    compression = m.get("compression", "zlib")
    if compression not in ("zlib", "none"):
        raise ConfigError(f"{where}.compression: zlib or none, not {compression!r}")
    listen = tuple(_typed(x, str, f"{where}.listen") for x in m.get("listen") or [])
    connect = tuple(_typed(x, str, f"{where}.connect") for x in m.get("connect") or [])
    return TeamOptions(
        robot_id=robot_id,
        listen=listen,
        connect=connect,
        compression=compression,
        prefix=_typed(m.get("prefix", "rf_team"), str, f"{where}.prefix"),
        multicast_scouting=_typed(
            m.get("multicast_scouting", False), bool, f"{where}.multicast_scouting"
        ),
        lease_s=_positive(m, "lease_s", 3.0, float, where),
        max_message_bytes=_positive(m, "max_message_bytes", 64 << 20, int, where),
        budget_bytes_per_s=float(_non_negative(m, "budget_bytes_per_s", (int, float), where)),
        budget_burst_bytes=int(_non_negative(m, "budget_burst_bytes", int, where)),
    )


def _non_negative(m: Mapping[str, Any], key: str, kind: type | tuple[type, ...],
                  where: str) -> Any:
    """An option where 0 means "off" (no budget) and negative is a mistake."""
    value = _typed(m.get(key, 0), kind, f"{where}.{key}")
    if value < 0:
        raise ConfigError(f"{where}.{key}: must be >= 0 (0: no limit), not {value!r}")
    return value


def _rule(value: Any, where: str) -> TypeRule:
    m = _mapping(value, where, {"ros1", "ros2", "fields", "ros1_definition"})
    fields = _mapping(m.get("fields"), f"{where}.fields", set(m.get("fields") or {}))
    return TypeRule(
        ros1=_typed(m.get("ros1"), str, f"{where}.ros1"),
        ros2=_typed(m.get("ros2"), str, f"{where}.ros2"),
        fields={str(k): _typed(v, str, f"{where}.fields.{k}") for k, v in fields.items()},
        ros1_definition=m.get("ros1_definition"),
    )


def _topic(value: Any, where: str) -> TopicSpec:
    m = _mapping(
        value,
        where,
        {"ros2", "type", "peer", "peer_topic", "peer_type", "direction", "qos", "throttle"},
    )
    ros2 = _typed(m.get("ros2"), str, f"{where}.ros2")
    peer = m.get("peer", "ros1")
    if peer not in PEERS:
        raise ConfigError(f"{where}.peer: one of {PEERS}, not {peer!r}")
    direction = m.get("direction", "to_peer")
    if direction not in ("to_peer", "from_peer", "both"):
        raise ConfigError(f"{where}.direction: to_peer, from_peer or both, not {direction!r}")
    ros2_type = m.get("type")
    peer_type = m.get("peer_type")
    if ros2_type is None and peer_type is None:
        raise ConfigError(f"{where}: give 'type' (ROS 2) or 'peer_type'")
    throttle = None
    mode: Literal["local", "publisher"] = "local"
    if m.get("throttle") is not None:
        t = dict(
            _mapping(
                m["throttle"], f"{where}.throttle", {"max_rate_hz", "every_nth", "paused", "mode"}
            )
        )
        mode_value = t.pop("mode", "local")
        if mode_value not in ("local", "publisher"):
            raise ConfigError(f"{where}.throttle.mode: local or publisher, not {mode_value!r}")
        mode = "publisher" if mode_value == "publisher" else "local"
        try:
            throttle = ThrottleOptions(**t)
        except ThrottleError as exc:
            raise ConfigError(f"{where}.throttle: {exc}") from None
    return TopicSpec(
        ros2_topic=ros2,
        ros2_type=ros2_type,
        peer=peer,
        peer_topic=_typed(m.get("peer_topic", ros2), str, f"{where}.peer_topic"),
        peer_type=peer_type,
        direction=direction,
        qos=profile_from_config(m.get("qos"), where=f"{where}.qos"),
        throttle=throttle,
        throttle_mode=mode,
    )
