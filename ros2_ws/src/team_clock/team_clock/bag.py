"""MCAP in the rosbag2 layout: reading robots' logs and writing merged ones.

What rosbag2 (and the tools that read its bags: ``rosbags``, Foxglove, ``ros2 bag``) expect:
the MCAP ``ros2`` profile, schemas named ``pkg/msg/Type`` with encoding ``ros2msg`` holding
the message definition (dependencies appended after ``====`` separator lines), channels
with ``cdr`` message encoding and the offered QoS in their metadata, and for a bag directory
a ``metadata.yaml`` (version 9) listing the files, topics and counts.

A log is either one ``.mcap`` file or a bag directory (``metadata.yaml`` plus the files it
lists, or, without it, the ``.mcap`` files in name order). Logs cut short (a recorder killed
mid-chunk) are read up to their last complete record and reported as truncated.
"""

from __future__ import annotations

import contextlib
import heapq
import os
import struct
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

import yaml
from mcap.data_stream import ReadDataStream
from mcap.exceptions import McapError
from mcap.reader import NonSeekingReader, SeekingReader
from mcap.records import Channel, Chunk, Message, Schema
from mcap.stream_reader import breakup_chunk
from mcap.summary import Summary
from mcap.writer import CompressionType, Writer
from zstandard import ZstdError

from .errors import LogFormatError, MergeError

__all__ = ["BagWriter", "LogReader", "message_definition"]

_SEPARATOR = "=" * 80
#: What the mcap readers raise on damaged or cut-off input (they use struct and asserts too;
#: the decompressors raise their own errors, lz4 a RuntimeError).
_DAMAGED = (McapError, ValueError, EOFError, AssertionError, struct.error, ZstdError,
            RuntimeError)


def message_definition(type_name: str) -> str:
    """The rosbag2 ``ros2msg`` definition of ``type_name`` (``pkg/msg/Type``), with deps.

    Read from the installed ``.msg`` files (``share/<pkg>/msg``), as rosbag2 does.
    """
    from ament_index_python.packages import PackageNotFoundError, get_package_share_directory

    def text_of(name: str) -> str:
        pkg, _, base = name.partition("/msg/")
        try:
            share = get_package_share_directory(pkg)
        except PackageNotFoundError as exc:
            raise LogFormatError(f"no installed package {pkg!r} defines {name}") from exc
        path = Path(share) / "msg" / f"{base}.msg"
        if not path.exists():
            raise LogFormatError(f"{path} missing: cannot write the definition of {name}")
        return path.read_text()

    builtin = {"bool", "byte", "char", "float32", "float64", "int8", "uint8", "int16", "uint16",
               "int32", "uint32", "int64", "uint64", "string", "wstring"}
    main = text_of(type_name)
    seen: list[str] = []
    pending = [(type_name.partition("/msg/")[0], main)]
    texts: dict[str, str] = {}
    while pending:
        pkg, text = pending.pop(0)
        for line in text.splitlines():
            line = line.split("#", 1)[0].strip()
            if not line or "=" in line.split()[0]:
                continue
            parts = line.split()
            if len(parts) < 2 or "=" in parts[1]:
                continue
            field_type = parts[0].split("[", 1)[0].split("<=", 1)[0]
            if field_type in builtin:
                continue
            if field_type == "Header":
                dep = "std_msgs/msg/Header"
            elif "/" in field_type:
                dep_pkg, dep_name = field_type.split("/", 1)
                dep = f"{dep_pkg}/msg/{dep_name.removeprefix('msg/')}"
            else:
                dep = f"{pkg}/msg/{field_type}"
            if dep not in texts:
                texts[dep] = text_of(dep)
                seen.append(dep)
                pending.append((dep.partition("/msg/")[0], texts[dep]))
    parts = [main.rstrip("\n")]
    for dep in seen:
        body = texts[dep].rstrip("\n")
        parts.append(f"{_SEPARATOR}\nMSG: {dep.replace('/msg/', '/')}\n{body}")
    return "\n".join(parts) + "\n"


@dataclass
class LogReader:
    """Iterates a log's messages in log-time order, file after file.

    ``truncated`` names the files that ended before their last record was complete. Such a
    file has no index to order by, so its messages come in the order they were written
    (a recorder's are close to time order; the merged output is then only as ordered).
    """

    path: Path
    files: list[Path] = field(init=False)
    truncated: list[Path] = field(default_factory=list, init=False)

    def __post_init__(self) -> None:
        self.path = Path(self.path)
        self.files = log_files(self.path)

    def messages(
        self, *, topics: list[str] | None = None
    ) -> Iterator[tuple[Schema | None, Channel, Message]]:
        for file in self.files:
            with open(file, "rb") as stream:
                yield from self._file_messages(file, stream, topics)

    def topics(self) -> set[str]:
        """Every topic of the log (from the files' summaries, else by reading them)."""
        found: set[str] = set()
        for file in self.files:
            with open(file, "rb") as stream:
                try:
                    summary = SeekingReader(stream, validate_crcs=True).get_summary()
                except _DAMAGED:
                    summary = None
                if summary is not None:
                    found.update(ch.topic for ch in summary.channels.values())
                    continue
            found.update(channel.topic for _, channel, _ in self._file_messages_of(file))
        return found

    def _file_messages_of(self, file: Path) -> Iterator[tuple[Schema | None, Channel, Message]]:
        with open(file, "rb") as stream:
            yield from self._file_messages(file, stream, None)

    def metadata(self) -> Iterator[tuple[str, dict[str, str]]]:
        """Every MCAP metadata record ``(name, key/values)`` of the log's files."""
        for file in self.files:
            with open(file, "rb") as stream:
                reader = SeekingReader(stream, validate_crcs=True)
                try:
                    if reader.get_summary() is not None:
                        for record in reader.iter_metadata():
                            yield record.name, dict(record.metadata)
                        continue
                except _DAMAGED:
                    pass
                yield from _scan_metadata(file)

    def _file_messages(
        self, file: Path, stream: IO[bytes], topics: list[str] | None
    ) -> Iterator[tuple[Schema | None, Channel, Message]]:
        try:
            reader = SeekingReader(stream, validate_crcs=True)
            header = reader.get_header()
        except _DAMAGED as exc:
            raise LogFormatError(f"{file} is not an MCAP file: {exc}") from exc
        if header.profile not in ("ros2", ""):
            raise LogFormatError(f"{file} has MCAP profile {header.profile!r}, not 'ros2'")
        try:
            summary = reader.get_summary()
        except _DAMAGED:
            summary = None
        if summary is not None and summary.chunk_indexes:
            try:
                yield from _in_time_order(stream, summary, topics)
            except _DAMAGED as exc:
                raise LogFormatError(f"{file} is damaged: {exc}") from exc
            return
        if summary is not None:
            try:
                yield from reader.iter_messages(topics=topics, log_time_order=True)
            except _DAMAGED as exc:
                raise LogFormatError(f"{file} is damaged: {exc}") from exc
            return
        # No summary: the writer did not finish (killed). Read what is complete.
        stream.seek(0)
        try:
            yield from NonSeekingReader(stream, validate_crcs=True).iter_messages(
                topics=topics, log_time_order=False
            )
        except _DAMAGED:
            self.truncated.append(file)


def _in_time_order(
    stream: IO[bytes], summary: Summary, topics: list[str] | None
) -> Iterator[tuple[Schema | None, Channel, Message]]:
    """Messages in log-time order, one chunk in memory at a time.

    Chunks are read by their start time; a message is released once no later chunk can
    hold an earlier one (its time is below the next chunk's start). The mcap reader's own
    time ordering does the same with a Python-level comparison per heap step, which makes
    it the slowest part of a merge; plain tuples compare in C.
    """
    wanted = None if topics is None else set(topics)
    chunks = summary.chunk_indexes
    if wanted is not None:  # skip chunks without the wanted channels (their index says)
        ids = {cid for cid, ch in summary.channels.items() if ch.topic in wanted}
        chunks = [c for c in chunks if not c.message_index_offsets
                  or ids.intersection(c.message_index_offsets)]
    chunks = sorted(chunks, key=lambda c: (c.message_start_time, c.chunk_start_offset))
    heap: list[tuple[int, int, Schema | None, Channel, Message]] = []
    order = 0
    for i, index in enumerate(chunks):
        stream.seek(index.chunk_start_offset + 1 + 8)  # opcode, record length
        chunk = Chunk.read(ReadDataStream(stream))
        for record in breakup_chunk(chunk, validate_crc=True):
            if not isinstance(record, Message):
                continue
            channel = summary.channels[record.channel_id]
            if wanted is not None and channel.topic not in wanted:
                continue
            order += 1
            heapq.heappush(heap, (record.log_time, order, summary.schemas.get(channel.schema_id),
                                  channel, record))
        horizon = chunks[i + 1].message_start_time if i + 1 < len(chunks) else None
        while heap and (horizon is None or heap[0][0] < horizon):
            _, _, schema, channel, message = heapq.heappop(heap)
            yield schema, channel, message


def _scan_metadata(file: Path) -> Iterator[tuple[str, dict[str, str]]]:
    from mcap.records import Metadata
    from mcap.stream_reader import StreamReader

    with open(file, "rb") as stream:
        try:
            for record in StreamReader(stream, skip_magic=False).records:
                if isinstance(record, Metadata):
                    yield record.name, dict(record.metadata)
        except _DAMAGED:
            return


def log_files(path: Path) -> list[Path]:
    """The MCAP files a log consists of, in recording order."""
    if path.is_file():
        return [path]
    if not path.is_dir():
        raise LogFormatError(f"{path}: no such log (an .mcap file or a rosbag2 directory)")
    meta = path / "metadata.yaml"
    if meta.exists():
        try:
            info = yaml.safe_load(meta.read_text())["rosbag2_bagfile_information"]
            storage = info.get("storage_identifier", "mcap")
            names = [Path(p).name for p in info["relative_file_paths"]]
        except (yaml.YAMLError, KeyError, TypeError) as exc:
            raise LogFormatError(f"{meta} is not rosbag2 metadata: {exc}") from exc
        if storage != "mcap":
            raise LogFormatError(f"{path} uses storage {storage!r}; only mcap is supported")
        files = [path / n for n in names]
        if missing := [str(f) for f in files if not f.exists()]:
            raise LogFormatError(f"{path}: files listed in metadata.yaml are missing: {missing}")
        if compressed := [str(f) for f in files if f.suffix != ".mcap"]:
            raise LogFormatError(f"{path}: file-compressed bags are not supported: {compressed}")
        return files
    files = sorted(path.glob("*.mcap"))
    if not files:
        raise LogFormatError(f"{path} has neither metadata.yaml nor .mcap files")
    return files


@dataclass
class _Topic:
    name: str
    type_name: str
    channel_id: int
    qos: str
    count: int = 0


class BagWriter:
    """Writes one MCAP file in the rosbag2 layout (a context manager).

    ``path`` ending in ``.mcap`` writes just that file; any other path becomes a bag
    directory with ``<name>_0.mcap`` and ``metadata.yaml``. An existing target is refused,
    so a merge never overwrites a log.
    """

    def __init__(self, path: str | os.PathLike[str], *, compression: str = "zstd",
                 chunk_size: int = 1 << 20) -> None:
        self.path = Path(path)
        kinds = {"zstd": CompressionType.ZSTD, "lz4": CompressionType.LZ4,
                 "none": CompressionType.NONE}
        if compression not in kinds:  # before anything is created
            raise MergeError(f"compression must be one of {sorted(kinds)}, got {compression!r}")
        if self.path.exists():
            raise FileExistsError(f"{self.path} exists; refusing to overwrite it")
        if self.path.suffix == ".mcap":
            self.file = self.path
            self.directory: Path | None = None
        else:
            self.directory = self.path
            self.path.mkdir(parents=True)
            self.file = self.path / f"{self.path.name}_0.mcap"
        self._stream = open(self.file, "wb")  # noqa: SIM115 - closed in close()
        self._writer = Writer(self._stream, chunk_size=chunk_size, compression=kinds[compression])
        self._writer.start(profile="ros2", library="team_clock")
        self._schemas: dict[tuple[str, str, bytes], int] = {}
        self._topics: dict[str, _Topic] = {}
        self._by_channel: dict[int, _Topic] = {}
        self._start: int | None = None
        self._end = 0
        self._closed = False

    def __enter__(self) -> BagWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _schema(self, name: str, encoding: str, data: bytes) -> int:
        key = (name, encoding, data)
        if key not in self._schemas:
            self._schemas[key] = self._writer.register_schema(name, encoding, data)
        return self._schemas[key]

    def add_topic(self, topic: str, type_name: str, *, definition: str | bytes | None = None,
                  schema_encoding: str = "ros2msg",
                  metadata: Mapping[str, str] | None = None) -> int:
        """Register ``topic`` (``pkg/msg/Type``); returns the channel id to write with."""
        if topic in self._topics:
            existing = self._topics[topic]
            if existing.type_name != type_name:
                raise MergeError(f"{topic} is already {existing.type_name}, not {type_name}: "
                                 "one topic cannot hold two types in one bag")
            return existing.channel_id
        if definition is None:
            definition = message_definition(type_name)
        data = definition.encode() if isinstance(definition, str) else definition
        schema_id = self._schema(type_name, schema_encoding, data)
        meta = dict(metadata or {})
        meta.setdefault("offered_qos_profiles", "")
        channel_id = self._writer.register_channel(topic, "cdr", schema_id, meta)
        entry = _Topic(topic, type_name, channel_id, meta["offered_qos_profiles"])
        self._topics[topic] = self._by_channel[channel_id] = entry
        return channel_id

    def write(self, channel_id: int, log_time: int, data: bytes, *,
              publish_time: int | None = None, sequence: int = 0) -> None:
        self._writer.add_message(channel_id, log_time=log_time, data=data,
                                 publish_time=log_time if publish_time is None else publish_time,
                                 sequence=sequence)
        self._by_channel[channel_id].count += 1
        self._start = log_time if self._start is None else min(self._start, log_time)
        self._end = max(self._end, log_time)

    def add_metadata(self, name: str, values: Mapping[str, str]) -> None:
        self._writer.add_metadata(name, dict(values))

    def abort(self) -> None:
        """Stop and delete what was written (the file, or the bag directory)."""
        if not self._closed:
            self._closed = True
            self._stream.close()
        self.file.unlink(missing_ok=True)
        if self.directory is not None:
            (self.directory / "metadata.yaml").unlink(missing_ok=True)
            with contextlib.suppress(OSError):
                self.directory.rmdir()

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        self._writer.finish()  # type: ignore[no-untyped-call]
        self._stream.close()
        if self.directory is not None:
            self._write_metadata_yaml(self.directory)

    def _write_metadata_yaml(self, directory: Path) -> None:
        start = self._start or 0
        duration = max(0, self._end - start)
        count = sum(t.count for t in self._topics.values())
        info: dict[str, Any] = {
            "version": 9,
            "storage_identifier": "mcap",
            "relative_file_paths": [self.file.name],
            "duration": {"nanoseconds": duration},
            "starting_time": {"nanoseconds_since_epoch": start},
            "message_count": count,
            "topics_with_message_count": [
                {
                    "topic_metadata": {
                        "name": t.name,
                        "type": t.type_name,
                        "serialization_format": "cdr",
                        "offered_qos_profiles": _qos_list(t.qos),
                        "type_description_hash": "",
                    },
                    "message_count": t.count,
                }
                for t in self._topics.values()
            ],
            "compression_format": "",
            "compression_mode": "",
            "files": [{
                "path": self.file.name,
                "starting_time": {"nanoseconds_since_epoch": start},
                "duration": {"nanoseconds": duration},
                "message_count": count,
            }],
            "custom_data": None,
            "ros_distro": "jazzy",
        }
        text = yaml.safe_dump({"rosbag2_bagfile_information": info}, sort_keys=False)
        tmp = directory / "metadata.yaml.tmp"
        tmp.write_text(text)
        tmp.replace(directory / "metadata.yaml")


def _qos_list(qos: str) -> list[Any]:
    """Channel metadata holds the offered QoS as YAML text; metadata.yaml v9 as a list."""
    if not qos.strip():
        return []
    try:
        value = yaml.safe_load(qos)
    except yaml.YAMLError:
        return []
    return value if isinstance(value, list) else []
