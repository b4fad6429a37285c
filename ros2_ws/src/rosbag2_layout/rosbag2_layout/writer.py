"""Writing a bag: a directory of MCAP files in the rosbag2 layout (or one ``.mcap`` file).

Layout, as rosbag2's MCAP storage writes it so ROS tools read it: profile ``ros2``, one
schema per type with encoding ``ros2msg`` and the complete definition, channels with
message encoding ``cdr`` and the offered QoS profiles in their metadata, zstd-compressed
chunks, and ``metadata.yaml`` (rosbag2 format version 9, :mod:`.metadata`) beside the
files ``<bag>_0.mcap``, ``<bag>_1.mcap``, ...

Robustness is decided here:

* chunks are closed at least every ``chunk_interval_s`` (and at ``chunk_bytes``) and handed
  to the operating system, so a process killed with SIGKILL leaves a file readable up to its
  last completed chunk (:func:`rosbag2_layout.recover` rewrites such a file whole);
* ``metadata.yaml`` exists from the moment the directory does and is rewritten whenever a
  file closes, so it always lists every completed file: a bag cut short by a crash or a
  full disk still opens in rosbag2 and rosbags (with the completed files);
* files split by size and by duration;
* a free-space guard closes the bag cleanly while ``min_free_bytes`` are still free, and a
  write error (disk full) closes what can be closed and raises :class:`BagWriteError`.

The file system is a seam (:class:`FileSystem`): tests inject failures through it.
"""

from __future__ import annotations

import contextlib
import shutil
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

from mcap.writer import CompressionType, Writer

from .errors import BagConfigError, BagWriteError
from .livefile import LiveMcapStream
from .metadata import QosDict, bag_metadata, dump_qos, metadata_text, parse_qos
from .msgdefs import full_definition

__all__ = ["BagWriter", "FileSystem", "TopicInfo"]

# The free-space guard asks the file system at every flush and after each chunk's worth of
# bytes (at most this many).
_FREE_CHECK_BYTES = 4 << 20


class FileSystem:
    """Where the bytes go. Subclass to inject failures (disk full) or to count bytes."""

    def open_new(self, path: Path) -> IO[bytes]:
        """Open ``path`` for writing; it must not exist yet."""
        return open(path, "xb")

    def free_bytes(self, path: Path) -> int:
        """Bytes available to this process on the file system holding ``path``."""
        return shutil.disk_usage(path).free

    def write_text(self, path: Path, text: str) -> None:
        """Replace ``path`` atomically (readers never see half a file)."""
        tmp = path.with_name(path.name + ".tmp")
        tmp.write_text(text, encoding="utf-8")
        tmp.replace(path)


@dataclass
class TopicInfo:
    """What the bag knows about one topic: its type, schema, offered QoS and counts."""

    name: str
    type: str
    qos_profiles: list[QosDict] = field(default_factory=list)
    definition: bytes | None = None  # None: the installed .msg files' (msgdefs)
    schema_encoding: str = "ros2msg"
    messages: int = 0
    bytes: int = 0
    committed: int = 0  # messages as of the last flush (what metadata.yaml says)


@dataclass
class _FileInfo:
    path: Path
    start_ns: int = 0
    end_ns: int = 0
    messages: int = 0
    complete: bool = False  # finished with summary and footer
    #: ``(start_ns, end_ns, messages)`` as of the last flush: what the file holds for sure.
    committed: tuple[int, int, int] = (0, 0, 0)


@dataclass
class _OpenFile:
    info: _FileInfo
    stream: LiveMcapStream
    writer: Writer
    opened_ns: int
    channels: dict[str, int] = field(default_factory=dict)
    schemas: dict[str, int] = field(default_factory=dict)
    bytes: int = 0
    unflushed: int = 0
    flushed_at: float = 0.0


class BagWriter:
    """Writes one bag directory (or, for a path ending in ``.mcap``, that one file with no
    ``metadata.yaml`` and no splitting). An existing target is refused, so nothing is ever
    overwritten. Not thread-safe: one thread owns it. A context manager (closes on exit,
    :meth:`abort` removes everything on an exception).

    ``file_metadata()`` gives MCAP metadata records written into each file as it closes
    (so they reflect the latest state); :meth:`add_metadata` adds fixed ones.
    """

    def __init__(
        self,
        bag: str | Path,
        *,
        chunk_interval_s: float = 1.0,
        chunk_bytes: int = 1 << 20,
        max_file_bytes: int = 0,
        max_file_duration_s: float = 0.0,
        min_free_bytes: int = 64 << 20,
        compression: str = "zstd",
        file_metadata: Callable[[], Mapping[str, Mapping[str, str]]] | None = None,
        fs: FileSystem | None = None,
        library: str = "rosbag2_layout",
        custom_data: Mapping[str, str] | None = None,
    ) -> None:
        if compression not in ("zstd", "lz4", "none"):
            raise BagConfigError(f"compression must be zstd, lz4 or none, not {compression!r}")
        if chunk_interval_s <= 0 or chunk_bytes <= 0:
            raise BagConfigError("chunk_interval_s and chunk_bytes must be positive")
        if max_file_bytes < 0 or max_file_duration_s < 0 or min_free_bytes < 0:
            raise BagConfigError("split limits and min_free_bytes must be >= 0 (0 = none)")
        self.path = Path(bag)
        #: One ``.mcap`` file rather than a bag directory.
        self.single_file = self.path.suffix == ".mcap"
        self._library = library
        self._custom_data = dict(custom_data or {})
        self._records: dict[str, dict[str, str]] = {}
        self._fs = fs or FileSystem()
        self._compression = {
            "zstd": CompressionType.ZSTD, "lz4": CompressionType.LZ4, "none": CompressionType.NONE
        }[compression]
        self._chunk_interval_s = chunk_interval_s
        self._chunk_bytes = chunk_bytes
        self._max_file_bytes = max_file_bytes
        self._max_file_ns = int(max_file_duration_s * 1e9)
        self._min_free_bytes = min_free_bytes
        self._file_metadata = file_metadata
        self.topics: dict[str, TopicInfo] = {}
        self.files: list[_FileInfo] = []
        self._open: _OpenFile | None = None
        self._since_free_check = 0
        self.closed = False
        if self.path.exists():
            raise BagConfigError(f"{self.path} exists already; refusing to overwrite it")
        directory = self.path.parent if self.single_file else self.path
        try:
            directory.mkdir(parents=True, exist_ok=self.single_file)
        except FileExistsError as exc:
            raise BagConfigError(f"bag directory {self.path} exists already") from exc
        except OSError as exc:
            raise BagWriteError(f"cannot create bag directory {directory}: {exc}") from exc
        if self.single_file:
            self._open_file(0)  # created at once, so the target is taken
        else:
            try:
                self._write_metadata()  # a bag cut short at any point still has one
            except OSError as exc:
                self._remove_all()
                raise BagWriteError(f"cannot write {self.path}/metadata.yaml: {exc}") from exc
        self._check_free()

    def __enter__(self) -> BagWriter:
        return self

    def __exit__(self, exc_type: object, *_: object) -> None:
        if exc_type is None:
            self.close()
        else:
            self.abort()

    def add_topic(
        self,
        topic: str,
        type_name: str,
        *,
        qos_profiles: Sequence[QosDict] | str = (),
        definition: str | bytes | None = None,
        schema_encoding: str = "ros2msg",
    ) -> TopicInfo:
        """Declare ``topic`` before its first message: its offered QoS profiles (as
        :func:`.metadata.qos_dict` gives them, or channel-metadata YAML text) and, when
        copying from another bag, its schema as stored there. Undeclared topics get no
        profiles and the installed definition. Declaring again with the same type updates
        the profiles for files opened from now on and for ``metadata.yaml``."""
        profiles = parse_qos(qos_profiles) if isinstance(qos_profiles, str) \
            else list(qos_profiles)
        data = definition.encode() if isinstance(definition, str) else definition
        info = self.topics.get(topic)
        if info is None:
            if data is None and schema_encoding == "ros2msg":
                full_definition(type_name)  # refuse an unknown type now, not mid-recording
            info = self.topics[topic] = TopicInfo(topic, type_name, profiles, data,
                                                  schema_encoding)
        elif info.type != type_name:
            raise BagConfigError(f"{topic} is already {info.type}, not {type_name}: "
                                 "one topic cannot hold two types in one bag")
        else:
            info.qos_profiles = profiles
        return info

    def add_metadata(self, name: str, values: Mapping[str, str]) -> None:
        """An MCAP metadata record written into every file of the bag (at its close)."""
        self._records[name] = dict(values)

    # -- writing ---------------------------------------------------------------------------

    @property
    def current_file(self) -> Path | None:
        return self._open.info.path if self._open is not None else None

    @property
    def bytes_written(self) -> int:
        """Serialized message bytes written to the bag so far."""
        return sum(t.bytes for t in self.topics.values())

    def write(self, topic: str, type_name: str, data: bytes, log_time_ns: int, *,
              publish_time_ns: int | None = None, sequence: int = 0) -> None:
        """Add one serialized (CDR) message; splits, flushes and guards as configured."""
        if self.closed:
            raise BagWriteError(f"bag {self.path} is closed")
        f = self._open
        if f is not None and self._should_split(f, log_time_ns):
            self._close_file()
            f = None
        if f is None:
            f = self._open_file(log_time_ns)
        commits = f.stream.commits
        try:
            channel = f.channels.get(topic)
            if channel is None:
                channel = self._channel(f, topic, type_name)
            f.writer.add_message(channel, log_time_ns, data,
                                 log_time_ns if publish_time_ns is None else publish_time_ns,
                                 sequence)
        except OSError as exc:
            self._fail(f"writing {f.info.path}: {exc}", exc)
        info = f.info
        if info.messages == 0 or log_time_ns < info.start_ns:
            info.start_ns = log_time_ns
        info.end_ns = max(info.end_ns, log_time_ns)
        info.messages += 1
        meta = self.topics[topic]
        meta.messages += 1
        meta.bytes += len(data)
        f.bytes += len(data)
        f.unflushed += 1
        if f.stream.commits != commits:  # a full chunk, this message in it, is in the file
            self._committed(f)
        self._since_free_check += len(data)
        if self._since_free_check >= min(_FREE_CHECK_BYTES, self._chunk_bytes):
            self._check_free()

    def tick(self, now: float | None = None) -> None:
        """Close the chunk in progress if it is older than ``chunk_interval_s``; guard space."""
        f = self._open
        if f is None or not f.unflushed:
            return
        now = time.monotonic() if now is None else now
        if now - f.flushed_at >= self._chunk_interval_s:
            self.flush()

    def flush(self) -> None:
        """Close the chunk in progress and hand everything written to the operating system."""
        f = self._open
        if f is None:
            return
        try:
            f.writer.flush()  # type: ignore[no-untyped-call]
        except OSError as exc:
            self._fail(f"writing {f.info.path}: {exc}", exc)
        f.unflushed = 0
        f.flushed_at = time.monotonic()
        self._committed(f)
        try:
            self._write_metadata()  # a bag killed from now on lists this file and its counts
        except OSError as exc:
            self._fail(f"writing {self.path}/metadata.yaml: {exc}", exc)
        self._check_free()

    def split(self) -> Path | None:
        """Close the current file; the next message opens the next one. Returns the closed file."""
        if self._open is None:
            return None
        path = self._open.info.path
        self._close_file()
        return path

    def close(self) -> None:
        """Close the current file and write ``metadata.yaml``. Idempotent."""
        if self.closed:
            return
        try:
            if self._open is not None:
                self._close_file()
            else:
                self._write_metadata()
        finally:
            self.closed = True

    def abort(self) -> None:
        """Stop and delete everything written (the file, or the bag directory): a half
        written bag must not look like a complete one."""
        f, self._open = self._open, None
        if f is not None:
            _abandon(f.stream)
        self.closed = True
        self._remove_all()

    def _remove_all(self) -> None:
        for info in self.files:
            with contextlib.suppress(OSError):
                info.path.unlink()
        if not self.single_file:
            for name in ("metadata.yaml", "metadata.yaml.tmp"):
                with contextlib.suppress(OSError):
                    (self.path / name).unlink()
            with contextlib.suppress(OSError):
                self.path.rmdir()

    # -- internals -------------------------------------------------------------------------

    def _should_split(self, f: _OpenFile, log_time_ns: int) -> bool:
        if self.single_file:
            return False
        if self._max_file_bytes and f.bytes >= self._max_file_bytes:
            return True
        return bool(self._max_file_ns and log_time_ns - f.opened_ns >= self._max_file_ns)

    def _open_file(self, log_time_ns: int) -> _OpenFile:
        path = self.path if self.single_file \
            else self.path / f"{self.path.name}_{len(self.files)}.mcap"
        try:
            stream = LiveMcapStream(self._fs.open_new(path))
        except OSError as exc:
            self._fail(f"opening {path}: {exc}", exc)
        writer = Writer(stream, chunk_size=self._chunk_bytes,  # type: ignore[arg-type]
                        compression=self._compression)
        info = _FileInfo(path)
        self.files.append(info)
        f = _OpenFile(info, stream, writer, log_time_ns, flushed_at=time.monotonic())
        self._open = f
        try:
            writer.start(profile="ros2", library=self._library)
            stream.flush()  # a valid, empty MCAP file from the start (livefile)
        except OSError as exc:
            self._fail(f"writing {path}: {exc}", exc)
        return f

    def _channel(self, f: _OpenFile, topic: str, type_name: str) -> int:
        info = self.topics.get(topic)
        if info is None or info.type != type_name:
            info = self.add_topic(topic, type_name)  # raises on a type clash
        data = info.definition
        if data is None:
            data = full_definition(type_name).encode()
        key = f"{info.schema_encoding}:{type_name}:{hash(data)}"
        schema = f.schemas.get(key)
        if schema is None:
            schema = f.writer.register_schema(type_name, info.schema_encoding, data)
            f.schemas[key] = schema
        channel = f.writer.register_channel(
            topic, "cdr", schema, {"offered_qos_profiles": dump_qos(info.qos_profiles)})
        f.channels[topic] = channel
        return channel

    def _close_file(self) -> None:
        f, self._open = self._open, None
        if f is None:
            return
        try:
            records: dict[str, Mapping[str, str]] = dict(self._records)
            if self._file_metadata is not None:
                records.update(self._file_metadata())
            for name, data in records.items():
                f.writer.add_metadata(name, dict(data))
            f.stream.finishing = True
            f.writer.finish()  # type: ignore[no-untyped-call]
            f.stream.close()
            f.info.complete = True
            self._committed(f)
        except OSError as exc:
            _abandon(f.stream)
            self._fail(f"closing {f.info.path}: {exc}", exc, metadata=True)
        except BaseException:  # unforeseen: still give the file descriptor back
            _abandon(f.stream)
            raise
        self._write_metadata()

    def _committed(self, f: _OpenFile) -> None:
        """Everything written to ``f`` so far is in the file (after a flush or close)."""
        info = f.info
        info.committed = (info.start_ns, info.end_ns, info.messages)
        for topic in self.topics.values():
            topic.committed = topic.messages

    def _check_free(self) -> None:
        self._since_free_check = 0
        if not self._min_free_bytes:
            return
        try:
            free = self._fs.free_bytes(self.path)
        except OSError as exc:
            self._fail(f"cannot ask free space of {self.path}: {exc}", exc)
        if free < self._min_free_bytes:
            message = (f"free-space guard: {free} bytes free on the file system of {self.path}, "
                       f"below min_free_bytes={self._min_free_bytes}; recording stopped")
            self._abort(message)

    def _abort(self, message: str) -> None:
        """Close cleanly (space for the summary is what the guard keeps) and raise."""
        f, self._open = self._open, None
        if f is not None:
            try:
                f.stream.finishing = True
                f.writer.finish()  # type: ignore[no-untyped-call]
                f.stream.close()
                f.info.complete = True
                self._committed(f)
            except OSError:
                _abandon(f.stream)
        with contextlib.suppress(OSError):
            self._write_metadata()
        self.closed = True
        raise BagWriteError(message)

    def _fail(self, message: str, exc: OSError, *, metadata: bool = True) -> Any:
        f, self._open = self._open, None
        if f is not None:
            _abandon(f.stream)
        if metadata:
            with contextlib.suppress(OSError):
                self._write_metadata()
        self.closed = True
        raise BagWriteError(message) from exc

    def _write_metadata(self) -> None:
        # At creation, after every flush, close, split or failure. Every file is listed
        # with what it held at its last flush: the open one is a valid MCAP file at every
        # moment (livefile), so rosbag2 and rosbags open a bag killed at any point.
        if self.single_file:
            return
        metadata = bag_metadata(
            files=[(f.path.name, *f.committed) for f in self.files],
            topics=[(t.name, t.type, t.qos_profiles, t.committed)
                    for t in self.topics.values()],
            custom_data={"writer": self._library, **self._custom_data},
        )
        self._fs.write_text(self.path / "metadata.yaml", metadata_text(metadata))


def _abandon(stream: LiveMcapStream) -> None:
    with contextlib.suppress(OSError):
        stream.abandon()
