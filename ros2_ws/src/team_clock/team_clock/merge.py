"""Several robots' logs -> one time-aligned MCAP in the rosbag2 layout.

Each robot's messages move to team reference time through its :class:`OffsetModel`
(usually read from the log itself) and to its own namespace (``/robotA/joint_states``);
the merged file lists them in reference-time order. Log and publish times are always
moved; with ``stamps=True`` the ``header.stamp`` of messages that start with a
``std_msgs/Header`` is moved too, patched in the CDR bytes without decoding (the stamp is
the first field, so it sits right after the 4-byte encapsulation header). Only stamps
within ``stamp_window_ns`` of the log time are taken to be on the robot's clock; others
(simulated time, zeros, stamps copied from elsewhere) are left as they are and counted.

Streaming: one message per log is held at a time, so logs larger than memory merge.
"""

from __future__ import annotations

import heapq
import os
import re
import struct
from collections import Counter
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from mcap.records import Channel, Message, Schema

from rosbag2_layout import BagConfigError, BagWriter, Rosbag2Error

from .bag import LogReader
from .errors import MergeError, OtherRobotError
from .model import OffsetModel

__all__ = ["MergeReport", "RobotLog", "RobotReport", "merge"]

_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")
_HEADER_TYPES = {"std_msgs/Header", "std_msgs/msg/Header", "Header"}


@dataclass(frozen=True)
class RobotLog:
    """One robot's log and how to align it.

    ``model`` None reads the offsets recorded in the log: those of ``robot``, else of the
    robot named like ``namespace`` (``b=LOG`` on the command line means robot b), and a log
    holding only other robots' estimates is refused. ``namespace`` None uses the model's
    robot name.
    """

    path: Path
    namespace: str | None = None
    model: OffsetModel | None = None
    robot: str | None = None


@dataclass
class RobotReport:
    namespace: str
    path: Path
    model: OffsetModel
    messages: int = 0
    #: Messages not merged, by reason (e.g. ``schemaless``): counted, never silent.
    skipped: Counter[str] = field(default_factory=Counter)
    stamps_moved: int = 0
    stamps_left: int = 0
    truncated_files: list[Path] = field(default_factory=list)
    #: Largest error bound of the applied offsets over this robot's messages.
    max_uncertainty_ns: int = 0


@dataclass
class MergeReport:
    output: Path
    robots: list[RobotReport]

    @property
    def messages(self) -> int:
        return sum(r.messages for r in self.robots)


def merge(
    logs: Sequence[RobotLog],
    output: str | os.PathLike[str],
    *,
    stamps: bool = False,
    stamp_window_ns: int = 3_600_000_000_000,
    compression: str = "zstd",
) -> MergeReport:
    """Merge ``logs`` into ``output`` (a bag directory, or a file if it ends in ``.mcap``)."""
    if not logs:
        raise MergeError("nothing to merge: no logs given")
    if Path(output).exists():
        raise MergeError(f"{output} exists; refusing to overwrite it")
    named: list[str] = []
    for log in logs:  # the names given first: a clash is said as such, not as a wrong robot
        if log.namespace is not None:
            _check_namespace(log.namespace, log.path, named)
            named.append(log.namespace)
    reports: list[RobotReport] = []
    for log in logs:
        model = log.model or _model_of(log)
        namespace = log.namespace or model.robot or Path(log.path).stem
        if log.namespace is None:
            _check_namespace(namespace, log.path, [r.namespace for r in reports] + named)
        reports.append(RobotReport(namespace, Path(log.path), model))
    references = {r.model.reference for r in reports} - {""}
    if len(references) > 1:
        raise MergeError(f"the logs are aligned to different reference robots {sorted(references)}")

    readers = [LogReader(r.path) for r in reports]
    streams = [_aligned(i, reader, report) for i, (reader, report)
               in enumerate(zip(readers, reports, strict=True))]
    # Keyed by topic and type, not channel id: each file of a split bag numbers its
    # channels afresh, so one id can stand for different topics in one log.
    channels: dict[tuple[int, str, str], str] = {}
    has_header: dict[tuple[int, str, str], bool] = {}
    first_seen: dict[int, int] = {}  # log index -> earliest / latest local log time
    last_seen: dict[int, int] = {}
    try:
        writer = BagWriter(Path(output), compression=compression, min_free_bytes=0,
                           library="team_clock")
    except (Rosbag2Error, OSError) as exc:
        raise MergeError(f"cannot create {output}: {exc}") from exc
    try:
        for report in reports:
            m = report.model
            first = m.knots[0]
            writer.add_metadata(f"team_clock.merge.{report.namespace}", {
                "path": str(report.path), "robot": m.robot, "reference": m.reference,
                "estimates": str(len(m.knots)), "first_offset_ns": str(first.offset_ns),
                "first_stamp_ns": str(first.stamp_ns), "drift_ppm": repr(first.drift_ppm),
            })
        for ref_time, _, index, schema, channel, message in heapq.merge(*streams):
            report = reports[index]
            assert schema is not None  # schemaless channels are skipped in _aligned
            key = (index, channel.topic, schema.name)
            out_topic = channels.get(key)
            if out_topic is None:
                out_topic = _namespaced(report.namespace, channel.topic)
                try:
                    writer.add_topic(
                        out_topic, schema.name, definition=schema.data,
                        schema_encoding=schema.encoding,
                        qos_profiles=channel.metadata.get("offered_qos_profiles", ""))
                except BagConfigError as exc:
                    raise MergeError(str(exc)) from exc
                channels[key] = out_topic
                has_header[key] = _starts_with_header(schema)
            data = message.data
            if stamps and has_header[key]:
                data = _move_stamp(data, message.log_time, report, stamp_window_ns)
            publish_time = message.publish_time
            writer.write(out_topic, schema.name, data, ref_time, sequence=message.sequence,
                         publish_time_ns=ref_time if publish_time == message.log_time
                         else report.model.to_reference(publish_time))
            report.messages += 1
            first_seen[index] = min(first_seen.get(index, message.log_time), message.log_time)
            last_seen[index] = max(last_seen.get(index, message.log_time), message.log_time)
        writer.close()
    except BaseException:
        # A half-merged file would look like a complete one: remove it, keep the inputs.
        writer.abort()
        raise
    for index, (reader, report) in enumerate(zip(readers, reports, strict=True)):
        report.truncated_files = list(reader.truncated)
        if index in first_seen:
            report.max_uncertainty_ns = report.model.max_uncertainty(first_seen[index],
                                                                     last_seen[index])
    return MergeReport(Path(output), reports)


def _check_namespace(namespace: str, path: Path, taken: Sequence[str]) -> None:
    if not _NAME.match(namespace):
        raise MergeError(f"namespace {namespace!r} of {path} is not a ROS name token")
    if namespace in taken:
        raise MergeError(f"two logs would be merged under /{namespace}")


def _model_of(log: RobotLog) -> OffsetModel:
    """The recorded model of the robot the log is named for (see :class:`RobotLog`).

    Never another robot's: on a shared domain a log may hold its neighbours' estimates
    too (recorders before robot_recorder kept only their own), and aligning robot b with
    robot c's clock would be wrong by their offset while stating c's small error bound.
    """
    robot = log.robot if log.robot is not None else log.namespace
    try:
        return OffsetModel.from_mcap(log.path, robot=robot)
    except OtherRobotError as exc:
        raise MergeError(
            f"{log.path} holds the clock estimates of robot {', '.join(exc.found)}, not of "
            f"robot {robot}: the log was recorded on another robot (name it as "
            f"{exc.found[0]}=LOG if it is {exc.found[0]}'s)") from exc


def _aligned(
    index: int, reader: LogReader, report: RobotReport
) -> Iterator[tuple[int, int, int, Schema | None, Channel, Message]]:
    """``(reference time, order, log index, ...)`` tuples, sortable without comparing records."""
    order = 0
    for schema, channel, message in reader.records():
        if schema is None or not schema.data or channel.message_encoding != "cdr":
            report.skipped["schemaless" if schema is None or not schema.data else
                           f"encoding {channel.message_encoding}"] += 1
            continue
        order += 1
        yield report.model.to_reference(message.log_time), order, index, schema, channel, message


def _namespaced(namespace: str, topic: str) -> str:
    """``topic`` under ``/namespace``, unless it is there already: a robot's recorder
    often records its topics with the robot's namespace (``/a/x``), which must not
    become ``/a/a/x``."""
    absolute = topic if topic.startswith("/") else f"/{topic}"
    prefix = f"/{namespace}"
    if absolute == prefix or absolute.startswith(prefix + "/"):
        return absolute
    return prefix + absolute


def _starts_with_header(schema: Schema | None) -> bool:
    """Whether the message's first field is a std_msgs/Header (so its stamp leads the CDR)."""
    if schema is None or schema.encoding != "ros2msg":
        return False
    for line in schema.data.decode(errors="replace").splitlines():
        line = line.split("#", 1)[0].strip()
        if line:
            parts = line.split()
            return len(parts) >= 2 and parts[0] in _HEADER_TYPES
    return False


def _move_stamp(data: bytes, log_time: int, report: RobotReport, window_ns: int) -> bytes:
    """Shift the leading header stamp (int32 sec, uint32 nanosec) to reference time."""
    if len(data) < 12 or data[0] != 0 or data[1] not in (0, 1):
        report.stamps_left += 1
        return data
    fmt = "<iI" if data[1] == 1 else ">iI"
    sec, nanosec = struct.unpack_from(fmt, data, 4)
    stamp = sec * 1_000_000_000 + nanosec
    if stamp == 0 or nanosec >= 1_000_000_000 or abs(stamp - log_time) > window_ns:
        report.stamps_left += 1
        return data
    moved = report.model.to_reference(stamp)
    out = bytearray(data)
    struct.pack_into(fmt, out, 4, moved // 1_000_000_000, moved % 1_000_000_000)
    report.stamps_moved += 1
    return bytes(out)
