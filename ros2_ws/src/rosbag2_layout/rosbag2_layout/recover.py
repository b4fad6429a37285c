"""Recovering a bag cut short: every readable message written again as a complete bag, or
the bag made whole where it is (:func:`reindex`).

A recorder killed with SIGKILL (or a machine losing power, or a full disk) leaves its last
MCAP file without summary and footer. :func:`recover` reads such files up to their last
complete chunk and writes a complete bag with the same topics, schemas, offered QoS
profiles and MCAP metadata records (team_clock's clock estimates live there).
"""

from __future__ import annotations

import contextlib
from pathlib import Path

from .errors import BagFormatError
from .metadata import bag_metadata, metadata_text
from .reader import BagReader
from .writer import BagWriter, FileSystem

__all__ = ["recover", "reindex"]


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


def reindex(bag: str | Path) -> int:
    """Make bag directory ``bag`` whole where it is, as ``ros2 bag reindex`` does: every
    file without a summary is rewritten with one (under its own name, replaced only once the
    new one is written), then ``metadata.yaml`` is written from what the files hold.
    File names never change. Returns the message count.
    """
    path = Path(bag)
    if not path.is_dir():
        raise BagFormatError(f"{path} is not a bag directory")
    reader = BagReader(path)
    scratch = path.parent / f".{path.name}.reindex"  # beside, so replace() is a rename
    for file in reader.unfinished():
        fresh = scratch / file.name
        with contextlib.suppress(FileNotFoundError):
            fresh.unlink()
        try:
            recover(file, fresh)
            fresh.replace(file)
        finally:
            with contextlib.suppress(OSError):
                fresh.unlink()
            with contextlib.suppress(OSError):
                scratch.rmdir()
    reader = BagReader(path)
    files = [(file.name, *reader.file_stats(file)) for file in reader.files]
    counts: dict[str, int] = {}
    for message in reader.messages():
        counts[message.topic] = counts.get(message.topic, 0) + 1
    topics = [(t.name, t.type, t.qos_profiles, counts.get(t.name, 0))
              for t in reader.topic_records().values()]
    metadata = bag_metadata(files=files, topics=topics, custom_data={"reindexed_by":
                                                                     "rosbag2_layout"})
    FileSystem().write_text(path / "metadata.yaml", metadata_text(metadata))
    return sum(f[3] for f in files)
