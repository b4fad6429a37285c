"""A team log as a source of time-ordered messages, each told by robot and topic.

A match's merged log (humanoid_sim's ``match_log``, team_clock's merge) holds every robot's
topics under its name (``/blue1/fall/state``) and the world's under ``/world/...``, all in
the world's time. One robot's own bag holds its topics without that prefix; opened with
``robot="blue1"`` it reads as that robot's part of a team log. Several robots' own bags,
each recorded on its robot's clock, read as one team log in team reference time
(:meth:`TeamLog.from_robot_logs`: team_clock's offset models move each bag's times, as its
merge would, without writing the merged copy). Either way a message is a
:class:`LogMessage`: the robot (the first name of the topic), the topic relative to it and
the log time, with the message itself deserialized only when someone asks for it (an
analysis that needs three topics of a log full of images never decodes an image).

Reading seeks by time window (rosbag2_layout decompresses only the chunks that meet it).
"""

from __future__ import annotations

import heapq
import os
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass, field
from functools import cache, cached_property
from pathlib import Path
from typing import Any

from rclpy.serialization import deserialize_message

from rosbag2_layout import BagReader, Rosbag2Error, import_type
from team_clock import OffsetModel, RobotLog, TeamClockError

from .errors import LogSourceError

__all__ = ["LogMessage", "TeamLog", "split_topic"]


#: A type name's class, looked up once per type rather than once per message.
_message_class = cache(import_type)


def split_topic(topic: str) -> tuple[str, str]:
    """``/blue1/fall/state`` -> ``("blue1", "fall/state")``; a root topic (``/rosout``)
    belongs to no robot: ``("", "rosout")``."""
    parts = topic.strip("/").split("/", 1)
    return (parts[0], parts[1]) if len(parts) == 2 else ("", parts[0])


@dataclass(eq=False)
class LogMessage:
    """One logged message: ``robot`` (its namespace, ``"world"`` for the world's), ``topic``
    relative to it, the full ``name``, the ``type`` and ``log_time_ns`` on the log's time
    base. :attr:`message` decodes the CDR bytes at first use (once, shared by every reader).
    """

    robot: str
    topic: str
    name: str
    type: str
    log_time_ns: int
    data: bytes = field(repr=False)

    @cached_property
    def message(self) -> Any:
        return deserialize_message(self.data, _message_class(self.type))

    @property
    def t(self) -> float:
        """The log time in seconds (for printing and thresholds)."""
        return self.log_time_ns * 1e-9


@dataclass(frozen=True)
class _Part:
    """One bag of a log: its reader, the name of each stored topic as the analysis names
    it, and the model that moves its times to the log's time base (None: already on it)."""

    path: Path
    reader: BagReader
    #: Stored topic -> the analysis' name; the analysis' name -> its type.
    names: dict[str, str]
    types: dict[str, str]
    model: OffsetModel | None

    def to_log(self, local_ns: int) -> int:
        return local_ns if self.model is None else self.model.to_reference(local_ns)

    def to_local(self, log_ns: int) -> int:
        """The bag's time at which its clock read ``log_ns`` on the log's time base: the
        model inverted by fixed-point iteration (its slope is 1 within ppm, so three steps
        reach the nanosecond)."""
        if self.model is None:
            return log_ns
        local = log_ns
        for _ in range(3):
            local = log_ns - round(self.model.offset_at(local))
        return local


def _namespaced(robot: str, topic: str) -> str:
    """``topic`` of ``robot``'s own bag under ``/robot``, unless it is there already (a
    recorder that kept the robot's namespace), as team_clock's merge names them."""
    if not robot:
        return topic
    prefix = f"/{robot.strip('/')}"
    absolute = topic if topic.startswith("/") else f"/{topic}"
    return absolute if absolute == prefix or absolute.startswith(prefix + "/") \
        else prefix + absolute


def _open(path: Path, robot: str | None, model: OffsetModel | None, *,
          only_own: bool = False) -> _Part:
    """A bag of a log. With ``only_own`` a bag that has topics under ``/robot`` (a merged
    log, or a robot's bag recorded in its namespace) is read as that robot's part alone;
    one that has none as ``robot``'s own bag recorded without its namespace."""
    if path.name.endswith(".events.mcap"):
        raise LogSourceError(f"{path} is an events sidecar (what events writes), not a log: "
                             "give the log it sits beside")
    try:
        reader = BagReader(path)
        if reader.files and all(f.name.endswith(".events.mcap") for f in reader.files):
            raise LogSourceError(f"{path} holds only events sidecars "
                                 f"({reader.files[0].name}), no log: give the log's own "
                                 "folder")
        records = reader.topic_records()
    except Rosbag2Error as exc:
        raise LogSourceError(f"cannot read {path}: {exc}") from exc
    prefix = f"/{(robot or '').strip('/')}/"
    if robot and only_own and any(stored.startswith(prefix) for stored in records):
        records = {k: v for k, v in records.items() if k.startswith(prefix)}
    names = {stored: _namespaced(robot or "", stored) for stored in records}
    return _Part(path, reader, names, {names[stored]: r.type for stored, r in records.items()},
                 model)


class TeamLog:
    """One log to analyse: a merged team log, or one robot's bag named with ``robot``, or
    several robots' own bags on one time base (:meth:`from_robot_logs`).

    Raises :class:`LogSourceError` when ``path`` is no readable bag.
    """

    def __init__(self, path: str | os.PathLike[str], *, robot: str | None = None) -> None:
        self._setup([_open(Path(path), robot, None, only_own=True)])

    @classmethod
    def from_robot_logs(cls, logs: Sequence[RobotLog]) -> TeamLog:
        """Several robots' own bags read as one team log in team reference time, without
        writing a merged copy: each robot's messages under its name (``/blue1/...``), its
        log times moved by its clock's :class:`team_clock.OffsetModel`, all in one time
        order, read by time window as a merged log is (each bag reads only the chunks of
        the window on its own clock).

        Each :class:`team_clock.RobotLog` says what team_clock's ``merge`` reads from it:
        the robot's ``namespace`` (None: the robot its recorded estimates name), and its
        ``model`` (None: the ``/team_clock/offset`` estimates recorded in the bag, of
        ``robot`` or else of the robot named like ``namespace``). So the events of the
        bags are those of ``merge``'s log of them, at the same times (message stamps stay
        on each robot's clock, as ``merge`` leaves them without ``stamps=True``).

        Raises :class:`LogSourceError` for a bag that cannot be read, one without its
        robot's clock estimates, two bags of one robot, or robots aligned to different
        reference clocks.
        """
        if not logs:
            raise LogSourceError("no robot logs given")
        parts, models = [], []
        for log in logs:
            path = Path(log.path)
            model = log.model
            if model is None:
                robot = log.robot if log.robot is not None else log.namespace
                try:
                    model = OffsetModel.from_mcap(path, robot=robot)
                except TeamClockError as exc:
                    raise LogSourceError(f"cannot put {path} on the team's time: {exc}") \
                        from exc
            name = log.namespace or model.robot
            if not name:
                raise LogSourceError(f"{path}: its clock estimates name no robot; say "
                                     "whose it is (NAME=LOG)")
            parts.append(_open(path, name, model))
            models.append((name, model))
        names = [n for n, _ in models]
        if len(set(names)) != len(names):
            raise LogSourceError(f"two logs of one robot: {sorted(names)}")
        references = {m.reference for _, m in models} - {""}
        if len(references) > 1:
            raise LogSourceError(f"the logs are aligned to different reference robots "
                                 f"{sorted(references)}")
        team = cls.__new__(cls)
        team._setup(parts)
        return team

    def _setup(self, parts: list[_Part]) -> None:
        self._parts = parts
        #: The bag (the first one, of several robots' bags).
        self.path = parts[0].path
        self.paths = [p.path for p in parts]
        #: Every topic (as the analysis names it: with the robot's prefix) -> its type.
        self.topics: dict[str, str] = {}
        for part in parts:
            self.topics.update(part.types)

    @property
    def robots(self) -> list[str]:
        """The robots (and the world) that logged something, by name."""
        return sorted({split_topic(t)[0] for t in self.topics} - {""})

    @property
    def problems(self) -> list[str]:
        """Where files of the log ended early (a killed recorder): read up to there. Each
        once (every pass over a file finds its end again)."""
        return list(dict.fromkeys(problem for part in self._parts
                                  for problem in part.reader.problems))

    def time_range(self) -> tuple[int, int]:
        """``(first, last)`` log time in ns over every file (0, 0 for an empty log)."""
        first = last = None
        for part in self._parts:
            for file in part.reader.files:
                start, end, count = part.reader.file_stats(file)
                if count:
                    start, end = part.to_log(start), part.to_log(end)
                    first = start if first is None else min(first, start)
                    last = end if last is None else max(last, end)
        return (first or 0, last or 0)

    def names(self, topics: Iterable[str]) -> list[str]:
        """The log's topics that ``topics`` name: an absolute name (``/world/game_state``)
        itself, a relative one (``fall/state``) on every robot that has it."""
        wanted = list(topics)
        found = []
        for name in self.topics:
            _, rest = split_topic(name)
            if any(w == name or (not w.startswith("/") and rest == w) for w in wanted):
                found.append(name)
        return sorted(found)

    def messages(self, topics: Sequence[str] | None = None, *, start_ns: int | None = None,
                 end_ns: int | None = None) -> Iterator[LogMessage]:
        """The messages of ``topics`` (as :meth:`names` reads them; ``None``: every topic)
        logged in ``[start_ns, end_ns)``, in log-time order.

        A file damaged in the middle raises :class:`LogSourceError` naming it; a file cut
        short (a killed recorder) is read up to its last complete record (:attr:`problems`).
        """
        names = None if topics is None else set(self.names(topics))
        streams = [self._part_messages(part, names, start_ns, end_ns) for part in self._parts]
        yield from streams[0] if len(streams) == 1 else heapq.merge(
            *streams, key=lambda m: m.log_time_ns)

    def _part_messages(self, part: _Part, names: set[str] | None, start_ns: int | None,
                       end_ns: int | None) -> Iterator[LogMessage]:
        stored = None if names is None else [s for s, n in part.names.items() if n in names]
        if stored == []:
            return
        # The window on the bag's own clock, a millisecond wider each side; exact below.
        lo = None if start_ns is None else part.to_local(start_ns) - 1_000_000
        hi = None if end_ns is None else part.to_local(end_ns) + 1_000_000
        try:
            for m in part.reader.messages(topics=stored, start_ns=lo, end_ns=hi):
                t = part.to_log(m.log_time_ns)
                if (start_ns is not None and t < start_ns) or (end_ns is not None
                                                               and t >= end_ns):
                    continue
                name = part.names[m.topic]
                robot, rest = split_topic(name)
                yield LogMessage(robot, rest, name, m.type, t, m.data)
        except Rosbag2Error as exc:
            raise LogSourceError(f"cannot read {part.path}: {exc}") from exc
