"""``metadata.yaml`` of a rosbag2 bag directory (format version 9, as Jazzy writes it), and
the offered QoS profiles it and the MCAP channels hold.

The schema is spelled out as typed dicts so that writer and reader agree on every key.
Offered QoS profiles appear twice in a bag, as rosbag2 (Jazzy) writes them: in
``metadata.yaml`` as a YAML *list* of profiles per topic, and in each MCAP channel's
metadata under ``offered_qos_profiles`` as the same list dumped to a YAML *string* (the
MCAP ros2 profile requires a string there). Policies are lower-case names (``keep_last``,
``reliable``, ``transient_local``, ``automatic``), durations ``{sec, nsec}``. Older bags
(version 8 and before) hold the list as a string with integer policies; both are read.
"""

from __future__ import annotations

import datetime
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any, TypedDict, cast

import yaml

from .errors import BagFormatError
from .msgdefs import type_hash

__all__ = [
    "METADATA_VERSION",
    "BagMetadata",
    "FileInformation",
    "QosDict",
    "TopicMetadata",
    "bag_metadata",
    "dump_qos",
    "parse_qos",
    "qos_dict",
    "qos_profile",
    "read_metadata",
]

METADATA_VERSION = 9
#: libyaml's C emitter and parser where PyYAML was built with them (the wheels are): a
#: recorder rewrites ``metadata.yaml`` at every flush so that a killed bag still lists what
#: it holds, and PyYAML's pure-Python emitter took 36 ms for a robot's 50 topics, 7x libyaml.
_DUMPER: Any = getattr(yaml, "CSafeDumper", yaml.SafeDumper)
_LOADER: Any = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
#: rosbag2's "infinite" duration (RMW_DURATION_INFINITE) as ``{sec, nsec}``.
_INFINITE_NS = 0x7FFF_FFFF_FFFF_FFFF


class QosTime(TypedDict):
    sec: int
    nsec: int


class QosDict(TypedDict):
    """One offered QoS profile, as rosbag2 (version 9) writes it."""

    history: str
    depth: int
    reliability: str
    durability: str
    deadline: QosTime
    lifespan: QosTime
    liveliness: str
    liveliness_lease_duration: QosTime
    avoid_ros_namespace_conventions: bool


class TopicMetadata(TypedDict):
    name: str
    type: str
    serialization_format: str
    offered_qos_profiles: list[QosDict]
    type_description_hash: str


class TopicWithMessageCount(TypedDict):
    topic_metadata: TopicMetadata
    message_count: int


class Nanoseconds(TypedDict):
    nanoseconds: int


class StartingTime(TypedDict):
    nanoseconds_since_epoch: int


class FileInformation(TypedDict):
    path: str
    starting_time: StartingTime
    duration: Nanoseconds
    message_count: int


class BagMetadata(TypedDict):
    """The ``rosbag2_bagfile_information`` mapping of ``metadata.yaml``."""

    version: int
    storage_identifier: str
    duration: Nanoseconds
    starting_time: StartingTime
    message_count: int
    topics_with_message_count: list[TopicWithMessageCount]
    compression_format: str
    compression_mode: str
    relative_file_paths: list[str]
    files: list[FileInformation]
    custom_data: dict[str, str] | None
    ros_distro: str


# -- QoS ------------------------------------------------------------------------------------

_HISTORY = {0: "system_default", 1: "keep_last", 2: "keep_all", 3: "unknown"}
_RELIABILITY = {0: "system_default", 1: "reliable", 2: "best_effort", 3: "unknown",
                4: "best_available"}
_DURABILITY = {0: "system_default", 1: "transient_local", 2: "volatile", 3: "unknown",
               4: "best_available"}
_LIVELINESS = {0: "system_default", 1: "automatic", 3: "manual_by_topic", 4: "unknown",
               5: "best_available"}


def _time(ns: int) -> QosTime:
    ns = min(max(ns, 0), _INFINITE_NS)
    return {"sec": ns // 1_000_000_000, "nsec": ns % 1_000_000_000}


def _ns(value: Any) -> int:
    if isinstance(value, Mapping):
        return int(value.get("sec", 0)) * 1_000_000_000 + int(value.get("nsec", 0))
    return 0


def _policy(value: Any, names: Mapping[int, str]) -> str:
    """A policy as its lower-case name (older bags hold the integer)."""
    if isinstance(value, bool):
        return "unknown"
    if isinstance(value, int):
        return names.get(value, "unknown")
    return str(value).lower()


def qos_dict(profile: Any) -> QosDict:
    """An rclpy ``QoSProfile`` (as ``get_publishers_info_by_topic`` reports it) as a dict."""
    return {
        "history": _HISTORY.get(int(profile.history), "unknown"),
        "depth": int(profile.depth),
        "reliability": _RELIABILITY.get(int(profile.reliability), "unknown"),
        "durability": _DURABILITY.get(int(profile.durability), "unknown"),
        "deadline": _time(profile.deadline.nanoseconds),
        "lifespan": _time(profile.lifespan.nanoseconds),
        "liveliness": _LIVELINESS.get(int(profile.liveliness), "unknown"),
        "liveliness_lease_duration": _time(profile.liveliness_lease_duration.nanoseconds),
        "avoid_ros_namespace_conventions": bool(profile.avoid_ros_namespace_conventions),
    }


def qos_profile(qos: QosDict) -> Any:
    """The rclpy ``QoSProfile`` a recorded profile describes (what a player offers)."""
    from rclpy.duration import Duration
    from rclpy.qos import (
        DurabilityPolicy,
        HistoryPolicy,
        LivelinessPolicy,
        QoSProfile,
        ReliabilityPolicy,
    )

    def pick(enum: Any, name: str, default: Any) -> Any:
        return getattr(enum, name.upper(), default)

    def duration(t: QosTime) -> Duration:
        ns = _ns(t)
        return Duration(nanoseconds=0 if ns >= _INFINITE_NS else ns)

    history = pick(HistoryPolicy, qos["history"], HistoryPolicy.KEEP_LAST)
    if history not in (HistoryPolicy.KEEP_LAST, HistoryPolicy.KEEP_ALL):
        history = HistoryPolicy.KEEP_LAST
    return QoSProfile(
        history=history,
        depth=max(1, int(qos["depth"])),
        reliability=pick(ReliabilityPolicy, qos["reliability"], ReliabilityPolicy.RELIABLE),
        durability=pick(DurabilityPolicy, qos["durability"], DurabilityPolicy.VOLATILE),
        deadline=duration(qos["deadline"]),
        lifespan=duration(qos["lifespan"]),
        liveliness=pick(LivelinessPolicy, qos["liveliness"], LivelinessPolicy.AUTOMATIC),
        liveliness_lease_duration=duration(qos["liveliness_lease_duration"]),
        avoid_ros_namespace_conventions=bool(qos["avoid_ros_namespace_conventions"]),
    )


def parse_qos(value: str | Sequence[Any] | None) -> list[QosDict]:
    """Offered profiles from ``metadata.yaml`` (a list) or channel metadata (YAML text)."""
    if isinstance(value, str):
        if not value.strip():
            return []
        try:
            value = yaml.load(value, Loader=_LOADER)
        except yaml.YAMLError as exc:
            raise BagFormatError(f"offered_qos_profiles is not YAML: {exc}") from exc
    if not value:
        return []
    if not isinstance(value, list):
        raise BagFormatError(f"offered_qos_profiles must be a list, not {value!r}")
    out: list[QosDict] = []
    for item in value:
        if not isinstance(item, Mapping):
            raise BagFormatError(f"an offered QoS profile must be a mapping, not {item!r}")
        out.append({
            "history": _policy(item.get("history", 1), _HISTORY),
            "depth": int(item.get("depth", 0)),
            "reliability": _policy(item.get("reliability", 1), _RELIABILITY),
            "durability": _policy(item.get("durability", 2), _DURABILITY),
            "deadline": _time(_ns(item.get("deadline"))),
            "lifespan": _time(_ns(item.get("lifespan"))),
            "liveliness": _policy(item.get("liveliness", 1), _LIVELINESS),
            "liveliness_lease_duration": _time(_ns(item.get("liveliness_lease_duration"))),
            "avoid_ros_namespace_conventions":
                bool(item.get("avoid_ros_namespace_conventions", False)),
        })
    return out


def dump_qos(profiles: Iterable[QosDict]) -> str:
    """The channel-metadata form: the list as YAML text (empty text for no profiles)."""
    items = list(profiles)
    return yaml.dump(items, Dumper=_DUMPER, sort_keys=False).strip() if items else ""


# -- metadata.yaml --------------------------------------------------------------------------


def bag_metadata(
    *,
    files: Sequence[tuple[str, int, int, int]],
    topics: Sequence[tuple[str, str, list[QosDict], int]],
    custom_data: Mapping[str, str] | None = None,
) -> BagMetadata:
    """``metadata.yaml`` content for ``files`` ``(name, start_ns, end_ns, messages)`` and
    ``topics`` ``(name, type, offered profiles, messages)``."""
    counted = [f for f in files if f[3]]
    start = min((f[1] for f in counted), default=0)
    end = max((f[2] for f in counted), default=0)
    custom = dict(custom_data or {})
    custom.setdefault("written", datetime.datetime.now(datetime.UTC).isoformat())
    return {
        "version": METADATA_VERSION,
        "storage_identifier": "mcap",
        "duration": {"nanoseconds": end - start},
        "starting_time": {"nanoseconds_since_epoch": start},
        "message_count": sum(f[3] for f in files),
        "topics_with_message_count": [
            {
                "topic_metadata": {
                    "name": name,
                    "type": type_name,
                    "serialization_format": "cdr",
                    "offered_qos_profiles": list(qos),
                    "type_description_hash": type_hash(type_name) if "/" in type_name
                    else "",
                },
                "message_count": count,
            }
            for name, type_name, qos, count in topics
        ],
        "compression_format": "",
        "compression_mode": "",
        "relative_file_paths": [f[0] for f in files],
        "files": [
            {
                "path": name,
                "starting_time": {"nanoseconds_since_epoch": f_start},
                "duration": {"nanoseconds": f_end - f_start},
                "message_count": count,
            }
            for name, f_start, f_end, count in files
        ],
        "custom_data": custom,
        "ros_distro": "jazzy",
    }


def metadata_text(metadata: BagMetadata) -> str:
    return yaml.dump({"rosbag2_bagfile_information": metadata}, Dumper=_DUMPER,
                     sort_keys=False)


def read_metadata(bag: str | Path) -> BagMetadata:
    """The ``metadata.yaml`` of bag directory ``bag`` (checked for what readers rely on)."""
    path = Path(bag) / "metadata.yaml"
    try:
        info = yaml.load(path.read_text(encoding="utf-8"),
                         Loader=_LOADER)["rosbag2_bagfile_information"]
        if not isinstance(info, dict) or not isinstance(info["relative_file_paths"], list):
            raise TypeError("relative_file_paths is not a list")
        for topic in info.get("topics_with_message_count") or []:
            meta = topic["topic_metadata"]
            meta["offered_qos_profiles"] = parse_qos(meta.get("offered_qos_profiles"))
    except OSError as exc:
        raise BagFormatError(f"cannot read {path}: {exc}") from exc
    except (yaml.YAMLError, KeyError, TypeError, UnicodeDecodeError) as exc:
        reason = " ".join(str(exc).split())  # YAML errors span lines; one line for a CLI
        raise BagFormatError(f"{path} is not rosbag2 metadata: {reason}") from exc
    storage = info.get("storage_identifier", "mcap")
    if storage not in ("mcap", "sqlite3"):
        raise BagFormatError(f"{bag} uses storage {storage!r}; mcap and sqlite3 are read")
    return cast(BagMetadata, info)
