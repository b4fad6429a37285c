"""The diagnostics and log view's data: /diagnostics and /rosout of one robot, filterable.

Both topics are absolute: every node of a DDS domain writes to the same two, whatever its
namespace. An entry is the robot's when it names a node of the robot's namespace: a log
record by its logger name (``robot2.ball_detector`` for ``/robot2/ball_detector``), a
diagnostic status by its name (``/robot2/servo_driver: servo 3``, the fully qualified node
name first, as our components write it). An entry that names no robot's namespace (a plain
node in the root namespace, a status named without its node) belongs to every robot of its
domain, and is marked ``shared``: it is shown rather than lost.

Buffers are bounded (:data:`CAPACITY` log records; the newest status per name), so a
chatty node cannot grow the GUI's memory. A seek of the source (``reset``) empties them:
the playback then delivers the records leading up to the new instant.
"""

from __future__ import annotations

import threading
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from efficient_comm import from_msg

from ..errors import InvalidInput
from ..robots import RobotId
from ..source import Source, Stream

CAPACITY = 2000
#: rcl_interfaces/Log levels (a byte each) and the names the filter accepts.
LEVELS = {"debug": 10, "info": 20, "warn": 30, "error": 40, "fatal": 50}
#: diagnostic_msgs/DiagnosticStatus levels.
DIAGNOSTIC_LEVELS = {0: "OK", 1: "WARN", 2: "ERROR", 3: "STALE"}


@dataclass(frozen=True, slots=True)
class LogEntry:
    stamp_ns: int
    level: int
    logger: str
    text: str
    where: str
    shared: bool

    @property
    def level_name(self) -> str:
        for name, value in sorted(LEVELS.items(), key=lambda kv: -kv[1]):
            if self.level >= value:
                return name.upper()
        return str(self.level)


@dataclass(frozen=True, slots=True)
class StatusEntry:
    name: str
    level: int
    message: str
    hardware_id: str
    values: tuple[tuple[str, str], ...]
    stamp_ns: int
    shared: bool

    @property
    def level_name(self) -> str:
        return DIAGNOSTIC_LEVELS.get(self.level, str(self.level))


def logger_prefix(namespace: str) -> str:
    """The logger-name prefix of a namespace's nodes: ``/a/b`` -> ``a.b.``."""
    return namespace.strip("/").replace("/", ".") + "." if namespace != "/" else ""


def check_filter(level: str, text: str) -> tuple[int, str]:
    """A filter as typed in the browser: a level name and a case-insensitive substring."""
    if level not in LEVELS:
        raise InvalidInput(f"a log level is one of {', '.join(LEVELS)}, not {level!r}")
    if not isinstance(text, str) or len(text) > 200:
        raise InvalidInput("a filter text is a string of at most 200 characters")
    return LEVELS[level], text.lower()


class LogsModel:
    """One robot's log records and diagnostic statuses (activate to receive)."""

    def __init__(self, source: Source, robot: RobotId, *, capacity: int = CAPACITY,
                 others: Callable[[], list[RobotId]] | None = None) -> None:
        self.source = source
        self.robot = robot
        #: The other robots of the hub, to tell entries of theirs from shared ones.
        self._others = others or (lambda: [r for r in source.robots() if r != robot])
        self._lock = threading.Lock()
        self._logs: deque[LogEntry] = deque(maxlen=capacity)
        self._statuses: dict[str, StatusEntry] = {}
        self._feeds: list[Stream] = []
        self._unsubscribe_reset: Callable[[], None] | None = None
        self.received = 0

    def activate(self) -> None:
        from diagnostic_msgs.msg import DiagnosticArray
        from rcl_interfaces.msg import Log

        if not self._feeds:
            self._unsubscribe_reset = self.source.on_reset(self.reset)
            self._feeds = [
                self.source.subscribe(self.robot, "/rosout", Log, self.on_log, qos=100),
                self.source.subscribe(self.robot, "/diagnostics", DiagnosticArray,
                                   self.on_diagnostics, qos=100),
            ]

    def deactivate(self) -> None:
        feeds, self._feeds = self._feeds, []
        unsubscribe, self._unsubscribe_reset = self._unsubscribe_reset, None
        for feed in feeds:
            feed.close()
        if unsubscribe is not None:
            unsubscribe()

    def reset(self) -> None:
        """Forget every record and status (the source moved to another instant)."""
        with self._lock:
            self._logs.clear()
            self._statuses.clear()
            self.received = 0

    @property
    def active(self) -> bool:
        return bool(self._feeds)

    def _owner(self, name: str, *, separator: str) -> bool | None:
        """True: ``name`` is this robot's; None: no robot's (shared); False: another's."""
        def owns(robot: RobotId) -> bool:
            if robot.domain != self.robot.domain or robot.namespace == "/":
                return False
            prefix = (logger_prefix(robot.namespace) if separator == "."
                      else robot.namespace.rstrip("/") + "/")
            return name.startswith(prefix)

        if owns(self.robot):
            return True
        if any(owns(other) for other in self._others()):
            return False
        return None

    def on_log(self, msg: Any) -> None:
        owner = self._owner(msg.name, separator=".")
        if owner is False:
            return
        entry = LogEntry(
            stamp_ns=from_msg(msg.stamp),
            level=int(msg.level), logger=msg.name, text=msg.msg,
            where=f"{msg.file}:{msg.line} ({msg.function})", shared=owner is None,
        )
        with self._lock:
            self._logs.append(entry)
            self.received += 1

    def on_diagnostics(self, msg: Any) -> None:
        stamp = from_msg(msg.header.stamp)
        with self._lock:
            for status in msg.status:
                owner = self._owner(status.name, separator="/")
                if owner is False:
                    continue
                level = status.level if isinstance(status.level, int) else ord(status.level)
                self._statuses[status.name] = StatusEntry(
                    name=status.name, level=level, message=status.message,
                    hardware_id=status.hardware_id,
                    values=tuple((kv.key, kv.value) for kv in status.values),
                    stamp_ns=stamp, shared=owner is None,
                )
            self.received += 1

    def logs(self, *, level: str = "debug", text: str = "", limit: int = 200) -> list[LogEntry]:
        """Records at ``level`` or above whose logger or text contains ``text``, newest first."""
        minimum, needle = check_filter(level, text)
        with self._lock:
            entries = list(self._logs)
        out = []
        for e in reversed(entries):
            if e.level >= minimum and (
                    not needle or needle in e.logger.lower() or needle in e.text.lower()):
                out.append(e)
                if len(out) >= limit:
                    break
        return out

    def statuses(self, *, level: str = "debug", text: str = "") -> list[StatusEntry]:
        """The newest status per name, worst first; ``level`` warn/error hides OK ones."""
        minimum, needle = check_filter(level, text)
        floor = {10: 0, 20: 0, 30: 1, 40: 2, 50: 2}[minimum]
        with self._lock:
            entries = list(self._statuses.values())
        return sorted(
            (s for s in entries if s.level >= floor and (
                not needle or needle in s.name.lower() or needle in s.message.lower())),
            key=lambda s: (-s.level, s.name),
        )
