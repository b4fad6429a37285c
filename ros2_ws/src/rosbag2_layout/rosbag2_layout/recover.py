"""Recovering a bag cut short: every readable message written again as a complete bag.

A recorder killed with SIGKILL (or a machine losing power, or a full disk) leaves its last
MCAP file without summary and footer. :func:`recover` reads such files up to their last
complete chunk and writes a complete bag with the same topics, schemas, offered QoS
profiles and MCAP metadata records (team_clock's clock estimates live there).
"""

from __future__ import annotations

from pathlib import Path

from .reader import BagReader
from .writer import BagWriter

__all__ = ["recover"]


def recover(bag: str | Path, out: str | Path) -> int:
    """Write every readable message of ``bag`` as a complete bag ``out``; returns the count.

    The input is checked before ``out`` is created, and ``out`` is removed again if anything
    fails, so a missing or garbage input (:class:`BagNotFoundError`,
    :class:`BagFormatError`) leaves nothing behind.
    """
    reader = BagReader(Path(bag))
    topics = reader.topic_records()  # reads every file's start: garbage raises here
    records = list(reader.metadata())
    count = 0
    with BagWriter(out, min_free_bytes=0) as writer:
        for record in topics.values():
            schema = record.schema
            writer.add_topic(record.name, record.type, qos_profiles=record.qos_profiles,
                             definition=schema.data if schema is not None else None,
                             schema_encoding=schema.encoding if schema else "ros2msg")
        for name, values in records:
            writer.add_metadata(name, values)
        for msg in reader.messages():
            writer.write(msg.topic, msg.type, msg.data, msg.log_time_ns,
                         publish_time_ns=msg.publish_time_ns, sequence=msg.sequence)
            count += 1
    return count
