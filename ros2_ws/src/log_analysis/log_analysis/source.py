"""A team log as a source of time-ordered messages, each told by robot and topic.

A match's merged log (humanoid_sim's ``match_log``, team_clock's merge) holds every robot's
topics under its name (``/blue1/fall/state``) and the world's under ``/world/...``, all in
the world's time. One robot's own bag holds its topics without that prefix; opened with
``robot="blue1"`` it reads as that robot's part of a team log. Either way a message is a
:class:`LogMessage`: the robot (the first name of the topic), the topic relative to it and
the log time, with the message itself deserialized only when someone asks for it (an
analysis that needs three topics of a log full of images never decodes an image).

Reading seeks by time window (rosbag2_layout decompresses only the chunks that meet it).
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass, field
from functools import cache, cached_property
from pathlib import Path
from typing import Any

from rclpy.serialization import deserialize_message

from rosbag2_layout import BagReader, Rosbag2Error, import_type

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


class TeamLog:
    """One log to analyse: a merged team log, or one robot's bag named with ``robot``.

    Raises :class:`LogSourceError` when ``path`` is no readable bag.
    """

    def __init__(self, path: str | os.PathLike[str], *, robot: str | None = None) -> None:
        self.path = Path(path)
        self._prefix = f"/{robot.strip('/')}" if robot else ""
        try:
            self._reader = BagReader(self.path)
            self._records = self._reader.topic_records()
        except Rosbag2Error as exc:
            raise LogSourceError(f"cannot read {self.path}: {exc}") from exc
        #: Every topic (as the analysis names it: with the robot's prefix) -> its type.
        self.topics: dict[str, str] = {
            self._prefix + name: record.type for name, record in self._records.items()}

    @property
    def robots(self) -> list[str]:
        """The robots (and the world) that logged something, by name."""
        return sorted({split_topic(t)[0] for t in self.topics} - {""})

    @property
    def problems(self) -> list[str]:
        """Where files of the log ended early (a killed recorder): read up to there."""
        return list(self._reader.problems)

    def time_range(self) -> tuple[int, int]:
        """``(first, last)`` log time in ns over every file (0, 0 for an empty log)."""
        first = last = None
        for file in self._reader.files:
            start, end, count = self._reader.file_stats(file)
            if count:
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
        names = None if topics is None else self.names(topics)
        if names == []:
            return
        stored = None if names is None else [n[len(self._prefix):] for n in names]
        try:
            for m in self._reader.messages(topics=stored, start_ns=start_ns, end_ns=end_ns):
                name = self._prefix + m.topic
                robot, rest = split_topic(name)
                yield LogMessage(robot, rest, name, m.type, m.log_time_ns, m.data)
        except Rosbag2Error as exc:
            raise LogSourceError(f"cannot read {self.path}: {exc}") from exc
