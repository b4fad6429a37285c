"""The recorder view's data: each robot's recorders, their status, and their remote control.

A recorder is found on the Hub's graph by what it offers, not by its name: a
``robot_recorder_interfaces/msg/RecorderStatus`` topic ``<node>/status`` together with a
``robot_recorder_interfaces/srv/Start`` service ``<node>/start`` under the robot's namespace.
A robot may run several (one per container); each is named by its node.

Its status is the recorder's own ``~/status`` topic (about once a second and on every
change of state), so following it costs the robot what it publishes anyway. Control goes
through the recorder's services (``~/start``, ``~/stop``, ``~/split``, ``~/snapshot``,
``~/set_topics``); every answer, refused or not, reaches the caller as a
:class:`ControlResult` with the recorder's own message.

Every control call checks the token first, here and not only in the page: a write without
the server's token is refused whatever a browser sends. Topic selections are parsed by
robot_recorder's own :func:`robot_recorder.parse_selection`, so the GUI accepts exactly
what the recorder does.

A log played back holds the recorders' status topics but answers no service: there a
recorder is found by its status alone, its status shows as recorded (its age by the
status' stamp on the source's clock), a seek (``reset``) forgets it, and every control
call is :class:`~debug_gui.errors.NotLive`.
"""

from __future__ import annotations

import functools
import threading
from collections.abc import Callable, Iterable, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import Any

from efficient_comm import from_msg
from robot_recorder import RecorderConfigError, TopicSelection, parse_selection

from ..errors import NOT_LIVE, DebugGuiError, InvalidInput, NotLive, RobotUnavailable
from ..robots import RobotId
from ..security import AccessPolicy
from ..source import Source, Stream
from .ages import StampAges

STATUS_TYPE = "robot_recorder_interfaces/msg/RecorderStatus"
START_TYPE = "robot_recorder_interfaces/srv/Start"
STATUS_SUFFIX = "/status"
#: RecorderStatus.state as the view names it.
STATES = {0: "idle", 1: "recording", 2: "failed"}
#: Longest bag path accepted from a browser (a path on the robot; PATH_MAX).
MAX_BAG_CHARS = 4096
#: Most topic entries one selection may hold.
MAX_ENTRIES = 512


@dataclass(frozen=True, slots=True)
class TopicFigures:
    """One recorded topic's counters (RecorderStatus.topics)."""

    name: str
    type: str
    messages: int
    bytes: int
    drops: int


@dataclass(frozen=True, slots=True)
class RecorderState:
    """What one recorder said last (``state`` is ``waiting`` until its first status)."""

    robot: RobotId
    #: The recorder's node, absolute (``/robot2/recorder``).
    node: str
    state: str = "waiting"
    bag: str = ""
    file: str = ""
    messages: int = 0
    bytes: int = 0
    drops: int = 0
    free_bytes: int = 0
    snapshot_bytes: int = 0
    snapshot_seconds: float = 0.0
    error: str = ""
    topics: tuple[TopicFigures, ...] = ()
    #: Seconds since the last status (None: none yet).
    age_s: float | None = None
    #: Status messages received from it.
    statuses: int = 0

    @property
    def short(self) -> str:
        """The node relative to the robot's namespace (``recorder``)."""
        return relative(self.node, self.robot)


@dataclass(frozen=True, slots=True)
class ControlResult:
    """A recorder's answer to one command (also a refusal, with its reason)."""

    robot: RobotId
    #: The recorder's node ("" when the robot has none).
    node: str
    action: str
    success: bool
    message: str = ""
    bag: str = ""
    file: str = ""
    messages: int = 0

    @property
    def text(self) -> str:
        """One line for the page: who, what, and the recorder's answer."""
        who = f"{self.robot.label}" + (f" {relative(self.node, self.robot)}" if self.node
                                       else "")
        if not self.success:
            return f"{who}: {self.action} refused: {self.message or 'no reason given'}"
        detail = {"start": f"recording into {self.bag}", "stop": f"stopped, bag {self.bag}",
                  "split": f"closed {self.file}" if self.file else "nothing to split",
                  "snapshot": f"{self.messages} messages into {self.bag}",
                  "set_topics": "topic selection applied"}.get(self.action, "done")
        if self.action == "stop" and not self.bag:
            detail = self.message or "was not recording"
        return f"{who}: {detail}"


def relative(name: str, robot: RobotId) -> str:
    """``/robot2/recorder`` as ``recorder`` (the robot is shown beside it)."""
    return robot.relative(name)


def parse_entries(entries: Iterable[str]) -> list[TopicSelection]:
    """Topic entries ``NAME [TYPE] [max_rate_hz=R] [every_nth=N]``, one per topic, parsed by
    robot_recorder's own parser; blank entries are skipped, a bad one is InvalidInput with
    robot_recorder's reason."""
    out: list[TopicSelection] = []
    for entry in entries:
        if not isinstance(entry, str):
            raise InvalidInput(f"a topic entry is text, not {entry!r}")
        if not entry.strip():
            continue
        try:
            out.append(parse_selection(entry))
        except RecorderConfigError as exc:
            raise InvalidInput(f"topic selection: {exc}") from None
        if len(out) > MAX_ENTRIES:
            raise InvalidInput(f"a selection holds at most {MAX_ENTRIES} topics")
    return out


def format_entry(selection: TopicSelection) -> str:
    """The inverse of :func:`parse_entries` for one topic (what the editor shows)."""
    parts = [selection.name]
    if selection.type:
        parts.append(selection.type)
    if selection.max_rate_hz:
        parts.append(f"max_rate_hz={selection.max_rate_hz:g}")
    if selection.every_nth > 1:
        parts.append(f"every_nth={selection.every_nth}")
    return " ".join(parts)


def check_bag(bag: object) -> str:
    """A bag directory to ask a recorder for ("" = the recorder's own choice)."""
    if not isinstance(bag, str) or len(bag) > MAX_BAG_CHARS or any(
        c in bag for c in "\0\n\r"
    ):
        raise InvalidInput(f"a bag is a directory path of at most {MAX_BAG_CHARS} characters "
                           f"on one line, not {bag!r:.80}")
    return bag.strip()


class _Follow:
    __slots__ = ("count", "feed", "heard", "last", "stamp_ns")

    def __init__(self) -> None:
        self.feed: Stream | None = None
        self.last: Any = None
        self.heard: float | None = None
        self.stamp_ns = 0
        self.count = 0


class RecorderModel:
    """One robot's recorders: status while active, and control (each write checks the token).

    Discovery, status and the answers are plain data; the service calls block (never on a
    UI event loop: through ``run.io_bound``).
    """

    def __init__(
        self,
        source: Source,
        robot: RobotId,
        *,
        policy: AccessPolicy,
        token: str | None,
        timeout_s: float = 10.0,
        clock: Callable[[], float] | None = None,
    ) -> None:
        self.source = source
        self.robot = robot
        self._policy = policy
        self._token = token
        self.timeout_s = timeout_s
        #: The source's clock (seconds): monotonic live, the log's time in a playback.
        self._clock = clock or source.now
        self._ages = StampAges(self._clock)
        self._unsubscribe_reset: Callable[[], None] | None = None
        self._lock = threading.Lock()
        self._active = False
        self._recorders: dict[str, _Follow] = {}
        #: The selection this GUI last applied per recorder (the status lists only
        #: subscribed topics, without their throttle options).
        self._applied: dict[str, list[TopicSelection]] = {}

    # -- discovery and status ------------------------------------------------------------

    def discover(self) -> list[str]:
        """The robot's recorders on the graph now (absolute node names, sorted); while
        active, a newly found one's status is followed at once."""
        services = self.source.services(self.robot)
        recorded = not self.source.live  # a log holds no services: the status tells
        found = []
        for name, types in self.source.topics(self.robot).items():
            if STATUS_TYPE in types and name.endswith(STATUS_SUFFIX):
                node = name[: -len(STATUS_SUFFIX)]
                if recorded or START_TYPE in services.get(f"{node}/start", ()):
                    found.append(node)
        with self._lock:
            for node in found:
                self._recorders.setdefault(node, _Follow())
            active = self._active
        if active:
            self._follow_all()
        return sorted(found)

    def activate(self) -> None:
        """Follow every known recorder's status (idempotent)."""
        with self._lock:
            self._active = True
            if self._unsubscribe_reset is None:
                self._unsubscribe_reset = self.source.on_reset(self.reset)
        self.discover()

    def deactivate(self) -> None:
        """Stop following: no status crosses the link for this view any more."""
        with self._lock:
            self._active = False
            feeds = [f.feed for f in self._recorders.values() if f.feed is not None]
            for follow in self._recorders.values():
                follow.feed = None
            unsubscribe, self._unsubscribe_reset = self._unsubscribe_reset, None
        for feed in feeds:
            feed.close()
        if unsubscribe is not None:
            unsubscribe()

    def reset(self) -> None:
        """Forget every recorder's status (the source moved to another instant); the
        recorders stay known and followed."""
        with self._lock:
            for follow in self._recorders.values():
                follow.last, follow.heard, follow.stamp_ns, follow.count = None, None, 0, 0
            self._ages.reset()

    @property
    def active(self) -> bool:
        return self._active

    def _follow_all(self) -> None:
        from robot_recorder_interfaces.msg import RecorderStatus

        with self._lock:
            todo = [n for n, f in self._recorders.items() if f.feed is None]
        for node in todo:
            feed = self.source.subscribe(
                self.robot, node + STATUS_SUFFIX, RecorderStatus,
                functools.partial(self.on_status, node),
            )
            with self._lock:
                follow = self._recorders[node]
                if follow.feed is None and self._active:
                    follow.feed, feed = feed, None  # type: ignore[assignment]
            if feed is not None:  # deactivated meanwhile, or followed twice
                feed.close()

    def on_status(self, node: str, msg: Any) -> None:
        """One RecorderStatus of recorder ``node`` (on the Hub's thread, or by tests)."""
        stamp_ns = from_msg(msg.stamp)
        with self._lock:
            follow = self._recorders.setdefault(node, _Follow())
            follow.last = msg
            follow.heard, follow.stamp_ns = self._ages.heard(stamp_ns), stamp_ns
            follow.count += 1

    def states(self) -> list[RecorderState]:
        """Every recorder known, with its last status, sorted by node."""
        out = []
        with self._lock:
            items = [(node, follow.last, follow.count,
                      None if follow.heard is None
                      else self._ages.age_s(follow.stamp_ns, delivered_s=follow.heard))
                     for node, follow in sorted(self._recorders.items())]
        for node, msg, count, age in items:
            if msg is None:
                out.append(RecorderState(robot=self.robot, node=node))
                continue
            out.append(RecorderState(
                robot=self.robot, node=node, state=STATES.get(int(msg.state), "unknown"),
                bag=str(msg.bag), file=str(msg.file), messages=int(msg.messages),
                bytes=int(msg.bytes), drops=int(msg.drops), free_bytes=int(msg.free_bytes),
                snapshot_bytes=int(msg.snapshot_bytes),
                snapshot_seconds=float(msg.snapshot_seconds), error=str(msg.error),
                topics=tuple(TopicFigures(name=str(t.name), type=str(t.type),
                                          messages=int(t.messages), bytes=int(t.bytes),
                                          drops=int(t.drops)) for t in msg.topics),
                age_s=age, statuses=count,
            ))
        return out

    def selection(self, node: str | None = None) -> list[TopicSelection]:
        """The recorder's topic selection as far as the GUI knows it: what it applied last,
        else the topics the recorder's status lists (without throttle options)."""
        node = self._one(node)
        with self._lock:
            applied = self._applied.get(node)
            follow = self._recorders.get(node)
            last = follow.last if follow is not None else None
        if applied is not None:
            return list(applied)
        if last is None:
            return []
        return [TopicSelection(name=str(t.name)) for t in last.topics]

    # -- control (each write needs the token) --------------------------------------------

    def start(self, node: str | None = None, *, bag: str = "") -> ControlResult:
        """Start a new bag (``bag`` = its directory on the robot; "" = the recorder's)."""
        from robot_recorder_interfaces.srv import Start

        bag = check_bag(bag)
        return self._call(node, "start", Start, Start.Request(bag=bag))

    def stop(self, node: str | None = None) -> ControlResult:
        from robot_recorder_interfaces.srv import Stop

        return self._call(node, "stop", Stop, Stop.Request())

    def split(self, node: str | None = None) -> ControlResult:
        from robot_recorder_interfaces.srv import Split

        return self._call(node, "split", Split, Split.Request())

    def snapshot(self, node: str | None = None, *, bag: str = "") -> ControlResult:
        """Write the recorder's pre-event ring buffer as a bag of its own."""
        from robot_recorder_interfaces.srv import Snapshot

        bag = check_bag(bag)
        return self._call(node, "snapshot", Snapshot, Snapshot.Request(bag=bag))

    def set_topics(self, entries: Sequence[str], node: str | None = None) -> ControlResult:
        """Replace the recorder's topic selection (``NAME [TYPE] [max_rate_hz=R]
        [every_nth=N]`` per entry). Malformed entries are InvalidInput before anything is
        sent; a selection the recorder cannot record comes back refused with its reason."""
        from robot_recorder_interfaces.msg import TopicSelection as SelectionMsg
        from robot_recorder_interfaces.srv import SetTopics

        if isinstance(entries, str):
            raise InvalidInput("a selection is a list of entries, one per topic")
        selections = parse_entries(entries)
        request = SetTopics.Request(topics=[
            SelectionMsg(name=s.name, type=s.type, max_rate_hz=s.max_rate_hz,
                         every_nth=s.every_nth) for s in selections])
        result = self._call(node, "set_topics", SetTopics, request)
        if result.success:
            with self._lock:
                self._applied[result.node] = selections
        return result

    def _one(self, node: str | None) -> str:
        with self._lock:
            known = sorted(self._recorders)
        if node is None:
            if not known:
                known = self.discover()
            if not known:
                raise RobotUnavailable(
                    f"{self.robot.label} has no recorder (no {STATUS_TYPE} topic with a "
                    f"start service under {self.robot.namespace})")
            if len(known) > 1:
                raise InvalidInput(f"{self.robot.label} has {len(known)} recorders "
                                   f"({', '.join(known)}): name one")
            return known[0]
        if node not in known and node not in self.discover():
            raise RobotUnavailable(f"{self.robot.label} has no recorder {node}")
        return node

    def _call(self, node: str | None, action: str, srv_type: type, request: Any
              ) -> ControlResult:
        if not self.source.live:
            raise NotLive(f"{self.robot.label}: {NOT_LIVE}: a log's recorder cannot "
                          f"{action.replace('_', ' ')}")
        self._policy.check_write(self._token)
        node = self._one(node)
        response = self.source.call(self.robot, f"{node}/{action}", srv_type, request,
                                 timeout_s=self.timeout_s)
        return ControlResult(
            robot=self.robot, node=node, action=action, success=bool(response.success),
            message=str(response.message), bag=str(getattr(response, "bag", "")),
            file=str(getattr(response, "file", "")),
            messages=int(getattr(response, "messages", 0)),
        )


@dataclass(slots=True)
class RecorderTeam:
    """Several robots' recorder models, followed together and commanded all at once."""

    models: list[RecorderModel] = field(default_factory=list)

    def activate(self) -> None:
        for model in self.models:
            model.activate()

    def deactivate(self) -> None:
        for model in self.models:
            model.deactivate()

    @property
    def active(self) -> bool:
        return any(m.active for m in self.models)

    def for_all(self, action: str) -> list[ControlResult]:
        """``start`` or ``stop`` on every robot's recorder at once (in parallel, so the bags
        begin together); a robot that cannot (no recorder, no token, no answer) gets a
        refused result with the reason instead of stopping the others."""
        if action not in ("start", "stop", "split", "snapshot"):
            raise InvalidInput(f"no recorder action {action!r} for every robot")
        if not self.models:
            return []

        def one(model: RecorderModel) -> list[ControlResult]:
            try:
                found: list[str | None] = list(model.discover())
                nodes = found or [None]
            except DebugGuiError as exc:
                return [ControlResult(robot=model.robot, node="", action=action,
                                      success=False, message=str(exc))]
            out = []
            for node in nodes:
                try:
                    out.append(getattr(model, action)(node))
                except DebugGuiError as exc:
                    out.append(ControlResult(robot=model.robot, node=node or "",
                                             action=action, success=False, message=str(exc)))
            return out

        with ThreadPoolExecutor(max_workers=len(self.models)) as pool:
            return [r for results in pool.map(one, self.models) for r in results]


__all__ = [
    "ControlResult", "RecorderModel", "RecorderState", "RecorderTeam",
    "TopicFigures", "check_bag", "format_entry", "parse_entries", "relative",
]
