"""A merged team log played back as a :class:`~debug_gui.source.Source`: one cursor in log
time drives every view.

The views do not know whether their robots run now or were recorded: a :class:`Playback`
offers the log's robots, topics and messages through the same ``subscribe`` the live Hub
has. Its robots are named as the live GUI names a match's robots (the namespace
``/blue1``; the domain is what ``domains`` says, else 0), so the views bound to robots work
on a log as they do live, and :func:`rebind` moves a layout saved live (whose domains
were the match's) onto the log's robots by namespace.

One thread of the playback's own delivers every message, in log-time order (the thread
rule of ARCHITECTURE.md: callbacks never run on the UI's event loop); the commands
(:meth:`~Playback.play`, :meth:`~Playback.pause`, :meth:`~Playback.step`,
:meth:`~Playback.seek`, :meth:`~Playback.set_rate`) only tell it what to do and return at
once, and :meth:`~Playback.settle` waits until it did. Playing, a message is delivered
when the cursor, running at ``rate`` times real time, reaches its log time, and each
stream at most at its own ``rate_hz`` in log time (a view at 10 Hz sees 10 messages a
second of log, whatever the playback rate). A seek calls the ``on_reset`` callbacks (the
models forget what they accumulated), then delivers what leads up to the new instant: the
last message of each subscribed topic at or before it, found by reading windows that reach
back further and further (1 s, 4 s, 16 s, ...) from the instant, so a seek reads about one
second of log for periodic topics, never the whole log.

A log answers no service call (:class:`~debug_gui.errors.NotLive`). The parameters view
shows a node's parameters as recorded: its ``/parameter_events``, which a seek delivers
whole up to the instant (each event tells only what changed).

A log that cannot be read is :class:`~debug_gui.errors.LogUnreadable` when opened; one
damaged further in stops the playback with :attr:`Playback.error` saying why.
"""

from __future__ import annotations

import contextlib
import logging
import math
import os
import threading
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from efficient_comm.handle import QoSLike
from log_analysis import Event, LogAnalysisError, LogMessage, TeamLog
from rosbag2_layout import Rosbag2Error, type_name

from .errors import NOT_LIVE, InvalidInput, LogUnreadable, NotLive
from .layout import Layout, Panel
from .params import PARAMETER_EVENTS
from .robots import STATS_SUFFIX, RobotId, check_domain
from .security import check_name, check_rate

__all__ = ["MAX_RATE", "WORLD", "Playback", "PlaybackStream", "filter_events", "next_event",
           "previous_event", "rebind"]

_log = logging.getLogger(__name__)
#: The world's namespace in a match's merged log (humanoid_sim's ``match_log.WORLD``): the
#: ground truth's recorder, not a robot (live, the GUI does not watch the world's domain).
WORLD = "world"
#: The fastest playback rate offered (times real time).
MAX_RATE = 100.0
#: How much log time (at rate 1) the playing thread reads at once.
_PLAY_WINDOW_NS = 250_000_000
#: The first look-back of a seek; each further one reaches back four times as far.
_LOOKBACK_NS = 1_000_000_000


def _ns(seconds: float) -> int:
    return round(seconds * 1e9)


class PlaybackStream:
    """One view's subscription to one topic of the log (the live Hub's ``Feed``)."""

    def __init__(self, playback: Playback, robot: RobotId, topic: str, log_name: str,
                 msg_type: type, callback: Callable[[Any], None], *,
                 rate_hz: float | None) -> None:
        self.robot = robot
        self.topic = topic
        #: The topic's name in the log (``/blue1/rosout`` for the robot's ``/rosout``).
        self.log_name = log_name
        self.received = 0
        self._type = type_name(msg_type)
        self._callback = callback
        self._rate_hz = rate_hz
        self._playback = playback
        self._last_ns: int | None = None
        self.closed = False

    @property
    def rate_hz(self) -> float | None:
        return self._rate_hz

    def set_rate(self, rate_hz: float | None) -> None:
        self._rate_hz = check_rate(rate_hz)

    def close(self) -> None:
        self.closed = True
        self._playback._forget(self)

    def forget_rate(self) -> None:
        """After a seek the next message is due at once, whenever the last one was."""
        self._last_ns = None

    def offer(self, m: LogMessage, *, instant: bool = False) -> None:
        """Deliver ``m`` unless closed, of another type, or within the rate's period of the
        last one delivered (log time); ``instant``: the message of a new instant, always."""
        if self.closed or m.type != self._type:
            return
        rate = self._rate_hz
        if (not instant and rate is not None and self._last_ns is not None
                and m.log_time_ns - self._last_ns < 1e9 / rate):
            return
        self._last_ns = m.log_time_ns
        self.received += 1
        try:
            self._callback(m.message)
        except Exception:  # a view's failure must not stop the others' playback
            _log.exception("a view's callback failed on %s", self.topic)


@dataclass(frozen=True)
class _Step:
    span_ns: int | None  # None: to the next (or previous) message
    back: bool


class Playback:
    """A merged team log as a :class:`~debug_gui.source.Source` with a cursor.

    ``log``: the log's path or an open :class:`~log_analysis.TeamLog`. ``domains``: a
    robot's domain by name (as the match ran them, so a layout keeps its robots); others
    get domain 0. ``world``: the name under which the log holds the world's recording,
    which is not offered as a robot. A context manager (:meth:`close` on exit).

    Raises :class:`LogUnreadable` when the log cannot be read or holds nothing.
    """

    live = False

    def __init__(self, log: str | os.PathLike[str] | TeamLog, *,
                 domains: Mapping[str, int] | None = None, world: str = WORLD) -> None:
        try:
            self._log = log if isinstance(log, TeamLog) else TeamLog(log)
            self.start_ns, self.end_ns = self._log.time_range()
        except (LogAnalysisError, Rosbag2Error) as exc:
            raise LogUnreadable(f"cannot play back {log}: {exc}") from None
        if self.end_ns <= 0:
            raise LogUnreadable(f"cannot play back {self._log.path}: it holds no messages")
        domains = dict(domains or {})
        self._robots: dict[RobotId, str] = {}
        for name in self._log.robots:
            if name == world:
                continue
            try:
                robot = RobotId(domain=check_domain(domains.get(name, 0)), namespace=f"/{name}")
            except InvalidInput as exc:
                raise LogUnreadable(f"robot {name!r} of {self._log.path}: {exc}") from None
            self._robots[robot] = name
        self._cond = threading.Condition()
        self._streams: list[PlaybackStream] = []
        self._resets: list[Callable[[], None]] = []
        self._cursor_ns = self.start_ns
        self._rate = 1.0
        self._playing = False
        #: While playing: (log time, monotonic time) the cursor ran from.
        self._base: tuple[int, float] | None = None
        self._seek_to: int | None = None
        self._primes: list[PlaybackStream] = []
        self._steps: list[_Step] = []
        self._issued = 0
        self._done = 0
        self._closed = False
        self._error: str | None = None
        #: Each robot's recorded parameter events (by their name in the log), once read.
        self._parameters: dict[str, list[LogMessage]] = {}
        self._thread = threading.Thread(target=self._run, daemon=True, name="playback")
        self._thread.start()

    # -- the cursor ----------------------------------------------------------------------

    @property
    def path(self) -> str:
        return str(self._log.path)

    @property
    def log(self) -> TeamLog:
        return self._log

    @property
    def cursor_ns(self) -> int:
        """The cursor in log time (ns); while playing, where it runs to now."""
        with self._cond:
            if self._playing and self._base is not None:
                log_ns, wall = self._base
                ahead = (time.monotonic() - wall) * self._rate * 1e9
                return min(self.end_ns, log_ns + int(ahead))
            return self._cursor_ns

    def now(self) -> float:
        """The cursor in seconds of log time."""
        return self.cursor_ns * 1e-9

    @property
    def playing(self) -> bool:
        return self._playing

    @property
    def rate(self) -> float:
        return self._rate

    @property
    def error(self) -> str | None:
        """Why the playback stopped, if the log turned out damaged; None otherwise."""
        return self._error

    @property
    def problems(self) -> list[str]:
        """Where files of the log ended early (damaged, or a killed recorder): the
        playback shows them up to there."""
        return self._log.problems

    def play(self) -> None:
        """Run the cursor at :attr:`rate` times real time from where it is (to the end)."""
        with self._cond:
            if self._cursor_ns >= self.end_ns:
                self._seek_locked(self.start_ns)
            self._playing = True
            self._error = None
            self._cond.notify_all()

    def pause(self) -> None:
        """Stop the cursor where it is now."""
        with self._cond:
            self._playing = False
            self._cond.notify_all()

    def set_rate(self, rate: float) -> None:
        """Play at ``rate`` times real time (0 < rate <= MAX_RATE)."""
        if isinstance(rate, bool) or not isinstance(rate, int | float) or not (
                math.isfinite(rate) and 0 < rate <= MAX_RATE):
            raise InvalidInput(f"a playback rate is a number in (0, {MAX_RATE:g}], not {rate!r}")
        with self._cond:
            self._rate = float(rate)
            self._cond.notify_all()  # the playing thread starts again from here at the new rate

    def seek(self, t: float) -> None:
        """Move the cursor to ``t`` (seconds of log time, clamped to the log): every view
        is reset and shown the instant ``t``. Returns at once (see :meth:`settle`)."""
        if not math.isfinite(t):
            raise InvalidInput(f"not a time to seek to: {t!r}")
        self.seek_ns(_ns(t))

    def seek_ns(self, t_ns: int) -> None:
        """:meth:`seek` to exactly ``t_ns`` (an event's start: seconds as a float are
        100 ns coarse at a wall-clock epoch, and would land before it)."""
        with self._cond:
            self._seek_locked(min(max(int(t_ns), self.start_ns), self.end_ns))

    def _seek_locked(self, t_ns: int) -> None:
        self._seek_to = t_ns
        self._steps.clear()  # a step queued before the seek would start from elsewhere
        self._issued += 1
        self._cond.notify_all()

    def step(self, span_s: float | None = None, *, back: bool = False) -> None:
        """Move the cursor to the next message of the subscribed topics (``back``: the
        previous one), or by ``span_s`` seconds (negative: back), delivering what it passes
        going forward; going back is a seek. Pauses a playing cursor."""
        if span_s is not None and not math.isfinite(span_s):
            raise InvalidInput(f"not a span to step by: {span_s!r}")
        with self._cond:
            self._playing = False
            self._steps.append(_Step(None if span_s is None else _ns(span_s), back))
            self._issued += 1
            self._cond.notify_all()

    def settle(self, timeout_s: float = 10.0) -> bool:
        """Wait until every command given so far (seek, step, subscribe) is delivered;
        False if that took longer than ``timeout_s``."""
        with self._cond:
            target = self._issued
            return self._cond.wait_for(lambda: self._done >= target or self._closed,
                                       timeout=timeout_s)

    def wait_stopped(self, timeout_s: float = 10.0) -> bool:
        """Wait until the cursor stops (paused, or at the end of the log); False if it
        still ran after ``timeout_s``."""
        with self._cond:
            return self._cond.wait_for(lambda: not self._playing or self._closed,
                                       timeout=timeout_s)

    def close(self) -> None:
        with self._cond:
            self._closed = True
            self._cond.notify_all()
        if threading.current_thread() is not self._thread:
            self._thread.join(timeout=5.0)

    def __enter__(self) -> Playback:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- the Source ----------------------------------------------------------------------

    def on_reset(self, callback: Callable[[], None]) -> Callable[[], None]:
        with self._cond:
            self._resets.append(callback)

        def unsubscribe() -> None:
            with self._cond, contextlib.suppress(ValueError):
                self._resets.remove(callback)

        return unsubscribe

    def robots(self) -> list[RobotId]:
        return sorted(self._robots)

    def on_robots_changed(self, callback: Callable[[], None]) -> Callable[[], None]:
        """A log's robots never change."""
        return lambda: None

    def _log_name(self, robot: RobotId, topic: str) -> str:
        """The log's name of the robot's ``topic``: the merge put every topic of a robot
        under its namespace, the absolute ones (``/rosout``) too."""
        full = robot.resolve(topic)
        return full if robot.contains(full) else robot.namespace.rstrip("/") + full

    def topics(self, robot: RobotId) -> dict[str, list[str]]:
        if robot not in self._robots:
            return {}
        return {name: [kind] for name, kind in sorted(self._log.topics.items())
                if robot.contains(name)}

    def publishes(self, robot: RobotId, topic: str) -> bool:
        return robot in self._robots and self._log_name(robot, topic) in self._log.topics

    def publishes_statistics(self, robot: RobotId) -> bool:
        return self.publishes(robot, STATS_SUFFIX)

    def nodes(self, robot: RobotId) -> list[str]:
        """A log records topics, not nodes: the nodes it knows are those whose parameters
        it recorded (``/parameter_events``)."""
        return sorted({m.message.node for m in self._parameter_events(robot)
                       if robot.contains(m.message.node)})

    def services(self, robot: RobotId) -> dict[str, list[str]]:
        """None: a log answers no service (see :meth:`call`)."""
        return {}

    def _parameter_events(self, robot: RobotId) -> list[LogMessage]:
        """The robot's recorded ``/parameter_events``, read once (a reader of its own: the
        playing thread reads the playback's meanwhile). One sparse topic over the log."""
        name = self._log_name(robot, PARAMETER_EVENTS)
        with self._cond:
            cached = self._parameters.get(name)
        if cached is not None:
            return cached
        events: list[LogMessage] = []
        if robot in self._robots and name in self._log.topics:
            try:
                events = list(TeamLog(self._log.path).messages([name]))
            except (LogAnalysisError, Rosbag2Error) as exc:
                _log.warning("the recorded parameters of %s: %s", robot.label, exc)
        with self._cond:
            self._parameters[name] = events
        return events

    def subscribe(self, robot: RobotId, topic: str, msg_type: type,
                  callback: Callable[[Any], None], *, rate_hz: float | None = None,
                  qos: QoSLike = 10) -> PlaybackStream:
        """Deliver the log's ``topic`` of ``robot`` from the cursor on; the stream gets the
        topic's last message at or before the cursor first (as a latched topic would)."""
        check_name(topic, what="topic name")
        stream = PlaybackStream(self, robot, robot.resolve(topic), self._log_name(robot, topic),
                                msg_type, callback, rate_hz=check_rate(rate_hz))
        with self._cond:
            self._streams.append(stream)
            self._primes.append(stream)
            self._issued += 1
            self._cond.notify_all()
        return stream

    def subscribed(self) -> list[str]:
        """The log's names of the topics open streams read (what a seek reads)."""
        return sorted({s.log_name for s in self._open_streams()})

    def _forget(self, stream: PlaybackStream) -> None:
        with self._cond, contextlib.suppress(ValueError):
            self._streams.remove(stream)

    def call(self, robot: RobotId, service: str, srv_type: type, request: Any, *,
             timeout_s: float = 5.0) -> Any:
        """A log answers no service: NotLive. (The parameters view shows a node's parameters
        as recorded from its ``/parameter_events``, which a seek delivers whole.)"""
        raise NotLive(f"{robot.label}: {NOT_LIVE}: a log does not answer {service}")

    # -- the playing thread --------------------------------------------------------------

    def _run(self) -> None:
        while True:
            with self._cond:
                self._cond.wait_for(lambda: self._closed or self._seek_to is not None
                                    or bool(self._primes) or bool(self._steps) or self._playing)
                if self._closed:
                    return
                seek, self._seek_to = self._seek_to, None
                # A seek delivers to every stream: it covers the subscriptions waiting too.
                finished = (seek is not None) + len(self._primes)
                primes, self._primes = ([] if seek is not None else self._primes), []
                step = self._steps.pop(0) if seek is None and not primes and self._steps \
                    else None
                finished += step is not None
            try:
                if seek is not None:
                    self._reset_to(seek)
                elif primes:
                    self._deliver_instant(self._cursor_ns, primes)
                elif step is not None:
                    self._step(step)
                else:
                    self._play_window()
            except (LogAnalysisError, Rosbag2Error) as exc:
                with self._cond:
                    self._error = f"playback stopped: {exc}"
                    self._playing = False
                _log.warning("%s", self._error)
            with self._cond:
                self._done += finished
                self._cond.notify_all()

    def _open_streams(self) -> list[PlaybackStream]:
        with self._cond:
            return list(self._streams)

    def _reset_to(self, t_ns: int) -> None:
        with self._cond:
            self._cursor_ns = t_ns
            self._base = None
            resets = list(self._resets)
        for reset in resets:
            try:
                reset()
            except Exception:
                _log.exception("a view's reset failed")
        streams = self._open_streams()
        for stream in streams:
            stream.forget_rate()
        self._deliver_instant(t_ns, streams)

    def _last_before(self, t_ns: int, names: Iterable[str]) -> dict[str, LogMessage]:
        """The last message of each of ``names`` logged at or before ``t_ns``: windows
        reaching back 1 s, 4 s, 16 s, ... until each is found or the log starts."""
        missing = {n for n in names if n in self._log.topics}
        found: dict[str, LogMessage] = {}
        end, width = t_ns + 1, _LOOKBACK_NS
        while missing and end > self.start_ns:
            start = max(self.start_ns, end - width)
            for m in self._log.messages(sorted(missing), start_ns=start, end_ns=end):
                found[m.name] = m
            missing -= found.keys()
            end, width = start, width * 4
        return found

    def _deliver_instant(self, t_ns: int, streams: Sequence[PlaybackStream]) -> None:
        """The instant ``t_ns`` to ``streams``: each topic's last message at or before it,
        but every recorded parameter event up to it (each tells only what changed, so a
        node's parameters at ``t_ns`` are the sum of them all)."""
        events = [s for s in streams if s.log_name == self._log_name(s.robot, PARAMETER_EVENTS)]
        for stream in events:
            for m in self._parameter_events(stream.robot):
                if m.log_time_ns > t_ns:
                    break
                stream.offer(m, instant=True)
        streams = [s for s in streams if s not in events]
        last = self._last_before(t_ns, {s.log_name for s in streams})
        for m in sorted(last.values(), key=lambda m: m.log_time_ns):
            for stream in streams:
                if stream.log_name == m.name:
                    stream.offer(m, instant=True)

    def _names(self) -> list[str]:
        """The subscribed topics of the log (every topic when nothing is subscribed: a
        step then still finds the next message)."""
        names = {s.log_name for s in self._open_streams()} & self._log.topics.keys()
        return sorted(names or self._log.topics)

    def _deliver(self, messages: Iterable[LogMessage]) -> None:
        streams = self._open_streams()
        for m in messages:
            for stream in streams:
                if stream.log_name == m.name:
                    stream.offer(m)

    def _step(self, step: _Step) -> None:
        cursor = self._cursor_ns
        if step.span_ns is not None and (step.back or step.span_ns < 0):
            self._reset_to(max(self.start_ns, cursor - abs(step.span_ns)))
        elif step.span_ns is not None:
            end = min(self.end_ns, cursor + step.span_ns)
            self._deliver(self._log.messages(self._names(), start_ns=cursor + 1, end_ns=end + 1))
            with self._cond:
                self._cursor_ns = end
        elif step.back:
            before = self._last_before(cursor - 1, self._names()) if cursor > self.start_ns \
                else {}
            self._reset_to(max((m.log_time_ns for m in before.values()), default=self.start_ns))
        else:
            self._step_next(cursor)

    def _step_next(self, cursor: int) -> None:
        names, start, width = self._names(), cursor + 1, _LOOKBACK_NS
        while start <= self.end_ns:
            end = min(self.end_ns + 1, start + width)
            first = next(iter(self._log.messages(names, start_ns=start, end_ns=end)), None)
            if first is not None:
                at = first.log_time_ns
                self._deliver(self._log.messages(names, start_ns=at, end_ns=at + 1))
                with self._cond:
                    self._cursor_ns = at
                return
            start, width = end, width * 4
        with self._cond:
            self._cursor_ns = self.end_ns

    def _play_window(self) -> None:
        """Deliver the next window of log time, each message when the cursor reaches it;
        return early (the cursor where it got to) when a command comes."""
        with self._cond:
            base_ns, rate = self._cursor_ns, self._rate
            self._base = (base_ns, time.monotonic())
            wall = self._base[1]
        end = min(self.end_ns, base_ns + int(_PLAY_WINDOW_NS * max(1.0, rate)))
        names = self._names() if self._open_streams() else []
        messages = list(self._log.messages(names, start_ns=base_ns + 1, end_ns=end + 1)) \
            if names else []
        for target, batch in [*((m.log_time_ns, [m]) for m in messages), (end, [])]:
            due = wall + (target - base_ns) / (rate * 1e9)
            with self._cond:
                interrupted = self._cond.wait_for(
                    lambda: self._interrupted(rate), timeout=max(0.0, due - time.monotonic()))
                if interrupted:
                    played = int((time.monotonic() - wall) * rate * 1e9)
                    self._cursor_ns = min(target - 1, base_ns + played)
                    self._base = None
                    return
                self._cursor_ns = target
            self._deliver(batch)
        with self._cond:
            self._base = None
            if end >= self.end_ns:
                self._playing = False

    def _interrupted(self, rate: float) -> bool:
        return (self._closed or not self._playing or self._rate != rate
                or self._seek_to is not None or bool(self._primes) or bool(self._steps))


def rebind(layout: Layout, robots: Sequence[RobotId]) -> Layout:
    """``layout`` with each panel's robot replaced by the one of ``robots`` with its
    namespace: a layout saved live (the match's domains) opens on a log's robots."""
    by_namespace = {r.namespace: r for r in robots}
    panels = []
    for panel in layout.panels:
        robot = panel.robot
        if robot is not None and robot not in robots and robot.namespace in by_namespace:
            robot = by_namespace[robot.namespace]
        panels.append(Panel(kind=panel.kind, robot=robot, settings=panel.settings))
    return Layout(tuple(panels))


# -- the event list ------------------------------------------------------------------------

def filter_events(events: Iterable[Event], *, text: str = "", robot: str = "",
                  generator: str = "") -> list[Event]:
    """The events whose name or description contains ``text`` (any case), of ``robot``
    and ``generator`` (empty: any), in time order."""
    needle = text.strip().lower()
    return sorted((e for e in events
                   if (not needle or needle in e.name.lower() or needle in e.description.lower())
                   and (not robot or e.robot == robot)
                   and (not generator or e.generator == generator)),
                  key=lambda e: (e.start_ns, e.end_ns))


def next_event(events: Sequence[Event], t_ns: int) -> Event | None:
    """The first of ``events`` (time-ordered) starting after ``t_ns``."""
    return next((e for e in events if e.start_ns > t_ns), None)


def previous_event(events: Sequence[Event], t_ns: int) -> Event | None:
    """The last of ``events`` (time-ordered) starting before ``t_ns``."""
    return next((e for e in reversed(events) if e.start_ns < t_ns), None)
