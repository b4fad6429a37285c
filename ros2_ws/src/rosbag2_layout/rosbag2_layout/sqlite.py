"""Reading rosbag2's sqlite3 storage (``.db3`` files), the default before Iron.

Such bags are read, never written: the records come out as MCAP's (schema, channel,
message) so the reader serves both storages alike. A ``.db3`` file holds a ``topics`` table
(name, type, serialization format, offered QoS profiles as YAML text, in later versions the
type description hash) and a ``messages`` table (topic id, receive time, CDR bytes); the
message definitions are the installed ones (``message_definitions`` is recent and often
empty), so a type that is not installed gets an empty schema, as rosbag2 writes one.
"""

from __future__ import annotations

import sqlite3
from collections.abc import Iterator
from contextlib import closing
from pathlib import Path

from mcap.records import Channel, Message, Schema

from .errors import BagFormatError, UnknownTypeError
from .msgdefs import full_definition

__all__ = ["SUFFIX", "sqlite_records", "sqlite_topics"]

SUFFIX = ".db3"
_MAGIC = b"SQLite format 3\x00"

Record = tuple[Schema | None, Channel, Message]


def _connect(file: Path) -> sqlite3.Connection:
    with open(file, "rb") as stream:
        if stream.read(len(_MAGIC)) != _MAGIC:
            raise BagFormatError(f"{file} is not an SQLite database (rosbag2's sqlite3 storage)")
    try:
        return sqlite3.connect(f"file:{file}?mode=ro", uri=True)
    except sqlite3.Error as exc:
        raise BagFormatError(f"{file}: cannot open: {exc}") from exc


def sqlite_topics(file: Path) -> dict[int, tuple[Schema | None, Channel]]:
    """The topics of one ``.db3`` file by their id, as MCAP schema and channel."""
    with closing(_connect(file)) as db:
        try:
            cursor = db.execute("SELECT * FROM topics")
            columns = [d[0] for d in cursor.description]
            rows = [dict(zip(columns, row, strict=True)) for row in cursor]
        except sqlite3.Error as exc:
            raise BagFormatError(f"{file} is not a rosbag2 sqlite3 bag: {exc}") from exc
    topics: dict[int, tuple[Schema | None, Channel]] = {}
    for row in rows:
        type_name = str(row.get("type", ""))
        try:
            definition = full_definition(type_name).encode()
        except UnknownTypeError:
            definition = b""
        topic_id = int(row["id"])
        schema = Schema(id=topic_id, name=type_name, encoding="ros2msg", data=definition)
        channel = Channel(id=topic_id, topic=str(row["name"]),
                          message_encoding=str(row.get("serialization_format") or "cdr"),
                          schema_id=topic_id,
                          metadata={"offered_qos_profiles":
                                    str(row.get("offered_qos_profiles") or "")})
        topics[topic_id] = (schema, channel)
    return topics


def sqlite_records(file: Path, topics: list[str] | None) -> Iterator[Record]:
    """Every message of one ``.db3`` file in receive-time order."""
    known = sqlite_topics(file)
    wanted = None if topics is None else set(topics)
    ids = [i for i, (_, ch) in known.items() if wanted is None or ch.topic in wanted]
    if not ids:
        return
    with closing(_connect(file)) as db:
        marks = ",".join("?" * len(ids))
        try:
            cursor = db.execute(
                f"SELECT topic_id, timestamp, data FROM messages WHERE topic_id IN ({marks}) "
                "ORDER BY timestamp, id", ids)
            for sequence, (topic_id, stamp, data) in enumerate(cursor):
                schema, channel = known[topic_id]
                yield schema, channel, Message(channel_id=topic_id, sequence=sequence,
                                               log_time=stamp, publish_time=stamp,
                                               data=bytes(data))
        except sqlite3.Error as exc:
            raise BagFormatError(f"{file} is damaged: {exc}") from exc
