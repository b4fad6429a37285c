"""Reading bags back: every message of a bag directory, also from files cut short.

A recorder killed with SIGKILL (or a machine losing power) leaves its last MCAP file without
summary and footer, and ``metadata.yaml`` without that file. :func:`read_messages` reads such
files sequentially up to the last complete chunk instead of refusing them, and
:func:`recover` writes a complete bag from what is readable.
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path

import yaml
from mcap.records import Channel, Message, Metadata, Schema
from mcap.stream_reader import StreamReader

from .errors import PlaybackError
from .storage import BagWriter

__all__ = ["BagMessage", "mcap_files", "read_messages", "read_metadata_records", "recover"]


@dataclass(frozen=True, slots=True)
class BagMessage:
    topic: str
    type: str
    data: bytes
    log_time_ns: int


def mcap_files(bag: str | Path) -> list[Path]:
    """The MCAP files of a bag directory in recording order (or ``[bag]`` for one file)."""
    path = Path(bag)
    if path.is_file():
        return [path]
    if not path.is_dir():
        raise PlaybackError(f"no bag at {path}")
    listed: list[Path] = []
    meta = path / "metadata.yaml"
    if meta.is_file():
        try:
            info = yaml.safe_load(meta.read_text())["rosbag2_bagfile_information"]
            listed = [path / Path(p).name for p in info.get("relative_file_paths", [])]
        except (yaml.YAMLError, KeyError, TypeError) as exc:
            raise PlaybackError(f"{meta} is not rosbag2 metadata: {exc}") from exc
    found = sorted(path.glob("*.mcap"), key=_index)
    files = [p for p in listed if p.exists()] + [p for p in found if p not in listed]
    if not files:
        raise PlaybackError(f"{path} holds no .mcap file")
    return files


def _index(path: Path) -> tuple[int, str]:
    match = re.search(r"_(\d+)\.mcap$", path.name)
    return (int(match.group(1)) if match else 0, path.name)


def _records(path: Path, problems: list[str] | None) -> Iterator[object]:
    """Records of one file in order, ending where a crash cut the file (noted in problems)."""
    with open(path, "rb") as stream:
        reader = StreamReader(stream, record_size_limit=1 << 31)
        try:
            yield from reader.records
        except Exception as exc:  # EndOfFile, a half-written chunk, bad compression ...
            if problems is None:
                return
            problems.append(f"{path}: readable up to byte {stream.tell()}, then {exc!r}")


def read_messages(
    bag: str | Path,
    *,
    topics: Iterable[str] | None = None,
    problems: list[str] | None = None,
) -> Iterator[BagMessage]:
    """Every readable message, file by file, in the order written.

    A file that ends early (killed recorder) yields what its complete chunks hold; pass a
    list as ``problems`` to learn which files ended early and where.
    """
    wanted = set(topics) if topics is not None else None
    for path in mcap_files(bag):
        schemas: dict[int, Schema] = {}
        channels: dict[int, Channel] = {}
        for record in _records(path, problems):
            if isinstance(record, Schema):
                schemas[record.id] = record
            elif isinstance(record, Channel):
                channels[record.id] = record
            elif isinstance(record, Message):
                channel = channels.get(record.channel_id)
                if channel is None or (wanted is not None and channel.topic not in wanted):
                    continue
                schema = schemas.get(channel.schema_id)
                yield BagMessage(channel.topic, schema.name if schema else "", record.data,
                                 record.log_time)


def read_metadata_records(bag: str | Path) -> dict[str, dict[str, str]]:
    """MCAP metadata records by name (later files win), e.g. ``"team_clock"``."""
    out: dict[str, dict[str, str]] = {}
    for path in mcap_files(bag):
        for record in _records(path, None):
            if isinstance(record, Metadata):
                out[record.name] = dict(record.metadata)
    return out


def recover(bag: str | Path, out: str | Path) -> int:
    """Write every readable message of ``bag`` as a complete bag ``out``; returns the count."""
    writer = BagWriter(out, min_free_bytes=0)
    count = 0
    try:
        for msg in read_messages(bag):
            writer.write(msg.topic, msg.type, msg.data, msg.log_time_ns)
            count += 1
    finally:
        writer.close()
    return count
