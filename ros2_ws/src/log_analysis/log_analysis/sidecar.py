"""Events in a sidecar MCAP beside the log, as Foxglove's ``foxglove.Event`` messages.

Foxglove's Event schema has three fields: ``start_time``, ``end_time`` (``{sec, nsec}``) and
``metadata`` (key-value pairs of strings). Written as JSON on the topic ``/events`` with
the schema name ``foxglove.Event``, any MCAP reader can list them, and tools that know
Foxglove's schemas show them as events. What our :class:`~.events.Event` has beyond the
schema (name, robot, description, generator) goes into ``metadata`` under those keys.

The sidecar is a plain MCAP file, not a rosbag2 bag: it holds no ROS messages, and a log's
folder stays what the recorder made (``<log>.events.mcap`` sits beside it).
"""

from __future__ import annotations

import json
import os
from collections.abc import Iterable
from pathlib import Path

from mcap.exceptions import McapError
from mcap.reader import make_reader
from mcap.writer import Writer

from .errors import LogSourceError
from .events import Event

__all__ = ["EVENTS_TOPIC", "SCHEMA_NAME", "read_events", "sidecar_path", "write_events"]

EVENTS_TOPIC = "/events"
SCHEMA_NAME = "foxglove.Event"
#: The event's own fields that travel in ``metadata``.
_OWN = ("name", "robot", "description", "generator")
_TIME = {"type": "object", "properties": {"sec": {"type": "integer", "minimum": 0},
                                          "nsec": {"type": "integer", "minimum": 0}}}
_SCHEMA = {
    "title": SCHEMA_NAME,
    "description": "A discrete event that occurred over a time range",
    "type": "object",
    "properties": {
        "start_time": _TIME,
        "end_time": _TIME,
        "metadata": {"type": "array", "items": {
            "type": "object",
            "properties": {"key": {"type": "string"}, "value": {"type": "string"}}}},
    },
}


def sidecar_path(log: str | os.PathLike[str], *, partial: bool = False) -> Path:
    """Where a log's events go by default: ``<log>.events.mcap`` beside it; those of a
    ``partial`` run (some generators, one robot, a window) ``<log>.partial.events.mcap``,
    so that they never replace the full set that other tools read."""
    path = Path(log)
    kind = ".partial" if partial else ""
    return path.with_name(f"{path.name.removesuffix('.mcap')}{kind}.events.mcap")


def _time(ns: int) -> dict[str, int]:
    return {"sec": ns // 1_000_000_000, "nsec": ns % 1_000_000_000}


def write_events(path: str | os.PathLike[str], events: Iterable[Event]) -> Path:
    """Write ``events`` to a new MCAP file at ``path`` (an existing file is replaced: the
    sidecar is derived data, made again by running the generators again)."""
    target = Path(path)
    partial = target.with_name(target.name + ".partial")
    with open(partial, "wb") as stream:
        writer = Writer(stream)
        writer.start(profile="", library="log_analysis")
        schema = writer.register_schema(SCHEMA_NAME, "jsonschema",
                                        json.dumps(_SCHEMA).encode())
        channel = writer.register_channel(EVENTS_TOPIC, "json", schema)
        for i, event in enumerate(sorted(events, key=lambda e: (e.start_ns, e.end_ns))):
            own = {key: getattr(event, key) for key in _OWN}
            metadata = [{"key": k, "value": str(v)} for k, v in own.items()]
            metadata += [{"key": str(k), "value": str(v)} for k, v in event.metadata.items()
                         if k not in own]
            data = {"start_time": _time(event.start_ns), "end_time": _time(event.end_ns),
                    "metadata": metadata}
            writer.add_message(channel, log_time=event.start_ns, publish_time=event.start_ns,
                               data=json.dumps(data).encode(), sequence=i)
        writer.finish()  # type: ignore[no-untyped-call]
    partial.replace(target)
    return target


def read_events(path: str | os.PathLike[str]) -> list[Event]:
    """The events of a sidecar (ours, or any MCAP with ``foxglove.Event`` JSON messages)."""
    events = []
    try:
        with open(path, "rb") as stream:
            for schema, _, message in make_reader(stream).iter_messages():
                if schema is None or schema.name != SCHEMA_NAME:
                    continue
                data = json.loads(message.data)
                meta = {kv["key"]: kv["value"] for kv in data.get("metadata", [])}
                own = {key: meta.pop(key, "") for key in _OWN}
                start, end = (t["sec"] * 1_000_000_000 + t["nsec"]
                              for t in (data["start_time"], data["end_time"]))
                events.append(Event(own["name"], start, end, own["robot"], own["description"],
                                    meta, own["generator"]))
    except (OSError, McapError, ValueError, KeyError, TypeError) as exc:
        raise LogSourceError(f"cannot read events from {path}: {exc}") from exc
    return events
