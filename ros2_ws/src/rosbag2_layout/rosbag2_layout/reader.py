"""Reading bags: every message of a bag directory or ``.mcap`` file, also of files cut short.

A bag is one ``.mcap`` file or a bag directory: ``metadata.yaml`` and the files it lists,
then any further ``.mcap`` file in the directory (the file a killed recorder was writing is
not listed yet), or without ``metadata.yaml`` every ``.mcap`` file in recording order. A
file listed in ``metadata.yaml`` but missing is refused (:class:`BagNotFoundError`): a bag
with a hole must not pass for a complete one.

A file with a summary is read in log-time order, one chunk in memory at a time. A file
without one (its writer was killed, or the disk filled) is read sequentially up to its last
complete record and noted in :attr:`BagReader.truncated` and :attr:`BagReader.problems`.
A file that is not MCAP at all raises :class:`BagFormatError`.

A time window (``start_ns``, ``end_ns``: log times, start inclusive, end exclusive) seeks as
mcap's and rosbags' readers do: only the chunks whose time range meets the window are read
and decompressed, so a minute out of an hour's log costs a minute's reading.
"""

from __future__ import annotations

import heapq
import re
import struct
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO

from mcap.data_stream import ReadDataStream
from mcap.exceptions import McapError
from mcap.opcode import Opcode
from mcap.reader import SeekingReader
from mcap.records import Channel, Chunk, Message, Metadata, Schema
from mcap.stream_reader import StreamReader, get_chunk_data_stream
from mcap.summary import Summary
from zstandard import ZstdError

from .errors import BagFormatError, BagNotFoundError
from .metadata import QosDict, parse_qos, read_metadata
from .sqlite import SUFFIX as SQLITE_SUFFIX
from .sqlite import sqlite_records, sqlite_topics

__all__ = ["BagMessage", "BagReader", "TopicRecord", "mcap_files"]

#: What the mcap readers raise on damaged or cut-off input (they use struct and asserts too;
#: the decompressors raise their own errors, lz4 a RuntimeError).
_DAMAGED = (McapError, ValueError, EOFError, AssertionError, struct.error, ZstdError,
            RuntimeError, KeyError)
_MAGIC = b"\x89MCAP0\r\n"

Record = tuple[Schema | None, Channel, Message]


@dataclass(frozen=True, slots=True)
class BagMessage:
    """One recorded message: topic, ``pkg/msg/Type``, CDR bytes and times (ns)."""

    topic: str
    type: str
    data: bytes
    log_time_ns: int
    publish_time_ns: int = 0
    sequence: int = 0


@dataclass(frozen=True)
class TopicRecord:
    """A topic as the bag stores it (first file that holds it)."""

    name: str
    type: str
    qos_profiles: list[QosDict]
    schema: Schema | None
    channel: Channel


def mcap_files(bag: str | Path) -> list[Path]:
    """The files of a bag in recording order (``[bag]`` for one file): MCAP files, or
    rosbag2's sqlite3 files (``.db3``, read only)."""
    path = Path(bag)
    if path.is_file():
        return [path]
    if not path.is_dir():
        raise BagNotFoundError(f"no bag at {path} (an .mcap file or a rosbag2 directory)")
    listed: list[Path] = []
    if (path / "metadata.yaml").is_file():
        info = read_metadata(path)
        listed = [path / Path(p).name for p in info["relative_file_paths"]]
        if missing := [str(p) for p in listed if not p.exists()]:
            raise BagNotFoundError(f"{path}: files listed in metadata.yaml are missing: "
                                   f"{missing}")
        if compressed := [str(p) for p in listed if p.suffix not in (".mcap", SQLITE_SUFFIX)]:
            raise BagFormatError(f"{path}: file-compressed bags are not supported: "
                                 f"{compressed}")
    suffix = listed[0].suffix if listed else ".mcap"
    found = sorted(path.glob(f"*{suffix}"), key=_index)
    if not listed and not found:
        found = sorted(path.glob(f"*{SQLITE_SUFFIX}"), key=_index)
    files = listed + [p for p in found if p not in listed]
    if not files:
        raise BagFormatError(f"{path} holds no .mcap (or .db3) file")
    return files


def _index(path: Path) -> tuple[str, int, str]:
    """Sort key: ``bag_2.mcap`` before ``bag_10.mcap``."""
    match = re.search(r"^(.*)_(\d+)\.(mcap|db3)$", path.name)
    return (match.group(1), int(match.group(2)), path.name) if match else (path.stem, 0, "")


@dataclass
class BagReader:
    """The messages, topics and metadata records of one bag.

    ``truncated`` names the files that ended before their last record was complete, and
    ``problems`` says where each ended. Such a file has no index to order by, so its
    messages come in the order they were written (a recorder's are close to time order).
    """

    path: Path
    files: list[Path] = field(init=False)
    truncated: list[Path] = field(default_factory=list, init=False)
    problems: list[str] = field(default_factory=list, init=False)

    def __post_init__(self) -> None:
        self.path = Path(self.path)
        self.files = mcap_files(self.path)

    def records(self, *, topics: list[str] | None = None, start_ns: int | None = None,
                end_ns: int | None = None) -> Iterator[Record]:
        """``(schema, channel, message)`` of every readable message, file by file; only
        those logged in ``[start_ns, end_ns)`` when given."""
        window = _Window(start_ns, end_ns)
        for file in self.files:
            with open(file, "rb") as stream:
                yield from self._file_records(file, stream, topics, window)

    def messages(self, *, topics: list[str] | None = None, start_ns: int | None = None,
                 end_ns: int | None = None) -> Iterator[BagMessage]:
        """Every readable message (in ``[start_ns, end_ns)`` when given) as a
        :class:`BagMessage`."""
        for schema, channel, message in self.records(topics=topics, start_ns=start_ns,
                                                     end_ns=end_ns):
            yield BagMessage(channel.topic, schema.name if schema else "", message.data,
                             message.log_time, message.publish_time, message.sequence)

    def topic_records(self) -> dict[str, TopicRecord]:
        """Every topic of the bag with its type, offered QoS profiles and schema."""
        found: dict[str, TopicRecord] = {}

        def add(schema: Schema | None, channel: Channel) -> None:
            if channel.topic not in found:
                found[channel.topic] = TopicRecord(
                    channel.topic, schema.name if schema else "",
                    parse_qos(channel.metadata.get("offered_qos_profiles", "")),
                    schema, channel)

        for file in self.files:
            if file.suffix == SQLITE_SUFFIX:
                for schema, channel in sqlite_topics(file).values():
                    add(schema, channel)
                continue
            summary = _summary(file)
            if summary is not None:
                for channel in summary.channels.values():
                    add(summary.schemas.get(channel.schema_id), channel)
                continue
            schemas: dict[int, Schema] = {}
            for record in _scan(file, None):
                if isinstance(record, Schema):
                    schemas[record.id] = record
                elif isinstance(record, Channel):
                    add(schemas.get(record.schema_id), record)
        return found

    def unfinished(self) -> list[Path]:
        """The files without a summary: their writer did not close them (killed, or still
        writing). They are read in full, but metadata.yaml may not count all they hold."""
        return [file for file in self.files
                if file.suffix != SQLITE_SUFFIX and _summary(file) is None]

    def file_stats(self, file: Path) -> tuple[int, int, int]:
        """``(start_ns, end_ns, messages)`` of one of the bag's files: from its summary's
        statistics where it has them, else read from its records."""
        summary = None if file.suffix == SQLITE_SUFFIX else _summary(file)
        if summary is not None and summary.statistics is not None:
            stats = summary.statistics
            if not stats.message_count:
                return 0, 0, 0
            return stats.message_start_time, stats.message_end_time, stats.message_count
        start, end, count = 0, 0, 0
        with open(file, "rb") as stream:
            for _, _, message in self._file_records(file, stream, None):
                stamp = message.log_time
                start = stamp if not count else min(start, stamp)
                end = max(end, stamp)
                count += 1
        return start, end, count

    def topics(self) -> set[str]:
        """Every topic name of the bag."""
        return set(self.topic_records())

    def metadata(self) -> Iterator[tuple[str, dict[str, str]]]:
        """Every MCAP metadata record ``(name, key/values)`` of the bag's files, in order."""
        for file in self.files:
            if file.suffix == SQLITE_SUFFIX:
                continue  # sqlite3 bags hold no MCAP metadata records
            with open(file, "rb") as stream:
                _check_magic(file, stream)
                try:
                    reader = SeekingReader(stream, validate_crcs=True)
                    if reader.get_summary() is not None:
                        for record in reader.iter_metadata():
                            yield record.name, dict(record.metadata)
                        continue
                except _DAMAGED:
                    pass
            for scanned in _scan(file, None):
                if isinstance(scanned, Metadata):
                    yield scanned.name, dict(scanned.metadata)

    def metadata_records(self) -> dict[str, dict[str, str]]:
        """MCAP metadata records by name (later files win), e.g. ``"team_clock"``."""
        return dict(self.metadata())

    def _file_records(self, file: Path, stream: IO[bytes], topics: list[str] | None,
                      window: _Window | None = None) -> Iterator[Record]:
        window = window or _Window()
        if file.suffix == SQLITE_SUFFIX:
            yield from (item for item in sqlite_records(file, topics)
                        if window.holds(item[2].log_time))
            return
        _check_magic(file, stream)
        try:
            reader = SeekingReader(stream, validate_crcs=True)
            header = reader.get_header()
        except _DAMAGED as exc:
            raise BagFormatError(f"{file} is not an MCAP file: {exc}") from exc
        if header.profile not in ("ros2", ""):
            raise BagFormatError(f"{file} has MCAP profile {header.profile!r}, not 'ros2'")
        try:
            summary = reader.get_summary()
        except _DAMAGED:
            summary = None
        if summary is not None:
            try:
                if summary.chunk_indexes:
                    yield from _in_time_order(stream, summary, topics, window)
                else:
                    yield from (item for item in reader.iter_messages(
                        topics=topics, log_time_order=True, start_time=window.start_ns)
                        if window.holds(item[2].log_time))
            except _DAMAGED as exc:
                raise BagFormatError(f"{file} is damaged: {exc}") from exc
            return
        # No summary: the writer did not finish (killed, disk full). Read what is complete.
        wanted = None if topics is None else set(topics)
        schemas: dict[int, Schema] = {}
        channels: dict[int, Channel] = {}
        for record in _scan(file, self):
            if isinstance(record, Schema):
                schemas[record.id] = record
            elif isinstance(record, Channel):
                channels[record.id] = record
            elif isinstance(record, Message):
                channel = channels.get(record.channel_id)
                if channel is None or (wanted is not None and channel.topic not in wanted) \
                        or not window.holds(record.log_time):
                    continue
                yield schemas.get(channel.schema_id), channel, record


@dataclass(frozen=True, slots=True)
class _Window:
    """Log times ``[start_ns, end_ns)``; ``None`` leaves that side open."""

    start_ns: int | None = None
    end_ns: int | None = None

    def holds(self, log_time: int) -> bool:
        return ((self.start_ns is None or log_time >= self.start_ns)
                and (self.end_ns is None or log_time < self.end_ns))

    def meets(self, first: int, last: int) -> bool:
        """Whether times ``first`` to ``last`` (inclusive) meet the window."""
        return ((self.start_ns is None or last >= self.start_ns)
                and (self.end_ns is None or first < self.end_ns))


def _check_magic(file: Path, stream: IO[bytes]) -> None:
    start = stream.read(len(_MAGIC))
    stream.seek(0)
    if start != _MAGIC:
        raise BagFormatError(f"{file} is not an MCAP file (it does not start with MCAP's "
                             "magic bytes)")


def _summary(file: Path) -> Summary | None:
    with open(file, "rb") as stream:
        _check_magic(file, stream)
        try:
            return SeekingReader(stream, validate_crcs=True).get_summary()
        except _DAMAGED:
            return None


def _scan(file: Path, reader: BagReader | None) -> Iterator[object]:
    """Records of one file in order, ending where a crash cut it (noted on ``reader``)."""
    with open(file, "rb") as stream:
        _check_magic(file, stream)
        try:
            yield from StreamReader(stream, record_size_limit=1 << 31).records
        except _DAMAGED as exc:  # EndOfFile, a half-written chunk, bad compression ...
            if reader is not None:
                reader.truncated.append(file)
                reason = (" ".join(str(exc).split())[:200]  # a bytes dump can be huge
                          or "the file ends in the middle of a record (cut while written)")
                reader.problems.append(f"{file}: readable up to byte {stream.tell()}, then "
                                       f"{type(exc).__name__}: {reason}")


#: A message record's fields before its data: channel id, sequence, log and publish time.
_MESSAGE_HEAD = struct.Struct("<HIQQ")
_RECORD_HEAD = struct.Struct("<BQ")


def _chunk_messages(chunk: Chunk, ids: set[int] | None, window: _Window) -> Iterator[Message]:
    """The messages of one chunk on channels ``ids`` (all when ``None``) in ``window``.

    Records are parsed with one ``struct`` call each and only wanted messages become
    objects (mcap's ``breakup_chunk`` builds every record through a stream wrapper, about
    three quarters of the time of reading a few topics out of a full log).
    """
    stream, size = get_chunk_data_stream(chunk, validate_crc=True)
    data = stream.read(size) if size else b""
    view = memoryview(data)
    pos, message_op = 0, Opcode.MESSAGE
    while pos < size:
        opcode, length = _RECORD_HEAD.unpack_from(data, pos)
        body = pos + _RECORD_HEAD.size
        pos = body + length
        if pos > size:
            raise BagFormatError(f"a record of {length} bytes overruns its chunk ({size} bytes)")
        if opcode != message_op:
            continue  # channels and schemas: the summary has them
        channel_id, sequence, log_time, publish_time = _MESSAGE_HEAD.unpack_from(data, body)
        if (ids is None or channel_id in ids) and window.holds(log_time):
            yield Message(channel_id=channel_id, sequence=sequence, log_time=log_time,
                          publish_time=publish_time,
                          data=bytes(view[body + _MESSAGE_HEAD.size:pos]))


def _in_time_order(stream: IO[bytes], summary: Summary, topics: list[str] | None,
                   window: _Window) -> Iterator[Record]:
    """Messages in log-time order, one chunk in memory at a time.

    Chunks are read by their start time; a message is released once no later chunk can
    hold an earlier one (its time is below the next chunk's start). The mcap reader's own
    time ordering does the same with a Python-level comparison per heap step, which makes
    it the slowest part of a merge; plain tuples compare in C.
    """
    wanted = None if topics is None else set(topics)
    chunks = summary.chunk_indexes
    ids = None
    if wanted is not None:  # skip chunks without the wanted channels (their index says)
        ids = {cid for cid, ch in summary.channels.items() if ch.topic in wanted}
        chunks = [c for c in chunks if not c.message_index_offsets
                  or ids.intersection(c.message_index_offsets)]
    chunks = sorted((c for c in chunks if window.meets(c.message_start_time, c.message_end_time)),
                    key=lambda c: (c.message_start_time, c.chunk_start_offset))
    heap: list[tuple[int, int, Schema | None, Channel, Message]] = []
    order = 0
    for i, index in enumerate(chunks):
        stream.seek(index.chunk_start_offset + 1 + 8)  # opcode, record length
        chunk = Chunk.read(ReadDataStream(stream))
        for record in _chunk_messages(chunk, ids, window):
            channel = summary.channels[record.channel_id]
            order += 1
            heapq.heappush(heap, (record.log_time, order, summary.schemas.get(channel.schema_id),
                                  channel, record))
        horizon = chunks[i + 1].message_start_time if i + 1 < len(chunks) else None
        while heap and (horizon is None or heap[0][0] < horizon):
            _, _, schema, channel, message = heapq.heappop(heap)
            yield schema, channel, message
