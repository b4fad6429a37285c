"""Events found in a log by event generators, and the one pass that runs them.

A team's logs hold more than anyone can review by hand; the dissertation's answer is custom
event generators: small programs that know one known issue (a robot fell, the roles
oscillate, a callback overran its period) and mark where it happens, so that a user
navigates by events instead of scrolling (sec. 2.3.7, 5.4).

An event generator is a callable over time-ordered :class:`~.source.LogMessage`\\ s with
state of its own: it names the ``topics`` it reads (relative names such as ``fall/state``
mean every robot's), is called with each of their messages in log-time order (several
robots interleaved), returns the events that message completes, and at the end of the log
its ``finish(end_ns)`` returns those still open. Hysteresis, thresholds and per-robot
state are the generator's own. :func:`event_generator` makes one of a plain function.

:func:`detect` reads the log once for all generators and decodes each message once. A
generator that raises is reported (:attr:`Detection.failures`) and left out from then on;
the others go on.
"""

from __future__ import annotations

import inspect
import traceback
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from functools import partial
from typing import Protocol, runtime_checkable

from .source import LogMessage, TeamLog

__all__ = ["Detection", "Event", "EventGenerator", "detect", "event_generator"]


@dataclass(frozen=True)
class Event:
    """Something that happened from ``start_ns`` to ``end_ns`` (equal for an instant) on the
    log's time base: its ``name`` (what happened: ``"fell"``), the ``robot`` it concerns
    (``""`` for the team), a ``description`` for people, and ``metadata`` for tools.
    ``generator`` is filled in by :func:`detect`."""

    name: str
    start_ns: int
    end_ns: int
    robot: str = ""
    description: str = ""
    metadata: Mapping[str, str] = field(default_factory=dict)
    generator: str = ""

    def __post_init__(self) -> None:
        if self.end_ns < self.start_ns:
            raise ValueError(f"event {self.name!r} ends ({self.end_ns}) before it starts "
                             f"({self.start_ns})")


@runtime_checkable
class EventGenerator(Protocol):
    """What :func:`detect` runs: ``topics`` to read, a call per message, ``finish`` at the
    end. ``name`` names it in reports (its class name where it has none)."""

    @property
    def topics(self) -> Sequence[str]: ...

    def __call__(self, message: LogMessage, /) -> Iterable[Event]: ...

    def finish(self, end_ns: int) -> Iterable[Event]: ...


class _FunctionGenerator:
    def __init__(self, fn: Callable[[LogMessage], Iterable[Event] | None],
                 topics: Sequence[str], name: str) -> None:
        self._fn, self._topics, self.name = fn, tuple(topics), name

    @property
    def topics(self) -> Sequence[str]:
        return self._topics

    def __call__(self, message: LogMessage) -> Iterable[Event]:
        return self._fn(message) or ()

    def finish(self, end_ns: int) -> Iterable[Event]:
        return ()


def event_generator(*, topics: Sequence[str], name: str = ""
                    ) -> Callable[[Callable[[LogMessage], Iterable[Event] | None]],
                                  EventGenerator]:
    """Make a generator of a function of one message (returning events, or ``None``)::

        @event_generator(topics=["behaviour/state"])
        def kicks(m):
            if m.message.data == "kick":
                return [Event("kick", m.log_time_ns, m.log_time_ns, robot=m.robot)]
    """
    if not topics:
        raise ValueError("an event generator reads at least one topic")

    def wrap(fn: Callable[[LogMessage], Iterable[Event] | None]) -> EventGenerator:
        return _FunctionGenerator(fn, topics, name or fn.__name__)

    return wrap


def generator_name(generator: object) -> str:
    name = getattr(generator, "name", "")
    return name if isinstance(name, str) and name else type(generator).__name__


@dataclass
class Detection:
    """What :func:`detect` found: ``events`` in start order, ``failures`` (generator ->
    what it raised, with where), ``messages`` read, and the log's ``problems``."""

    events: list[Event]
    failures: dict[str, str]
    messages: int
    problems: list[str]


def detect(
    log: TeamLog,
    generators: Sequence[EventGenerator],
    *,
    start_ns: int | None = None,
    end_ns: int | None = None,
    progress: Callable[[int], None] | None = None,
) -> Detection:
    """Run ``generators`` over ``log`` (within ``[start_ns, end_ns)`` when given) in one
    pass. ``progress`` is called now and then with the log time reached."""
    names = [generator_name(g) for g in generators]
    if len(set(names)) != len(names):
        raise ValueError(f"two generators share a name: {names}")
    by_topic: dict[str, list[int]] = {}
    for i, g in enumerate(generators):
        for topic in log.names(g.topics):
            by_topic.setdefault(topic, []).append(i)
    events: list[Event] = []
    failures: dict[str, str] = {}
    alive = [True] * len(generators)

    def run(i: int, call: Callable[[], Iterable[Event]]) -> None:
        try:
            result: Iterable[Event] | None = call()  # a user's method may return None
            if result is None:  # pointed at the user's method, not at this list()
                alive[i] = False
                failures[names[i]] = (f"returned None, not a list of events "
                                      f"({_where(call)})")
                return
            found: list[object] = list(result)
        except Exception as exc:  # a user's generator: reported, the others go on
            alive[i] = False
            where = traceback.extract_tb(exc.__traceback__)[-1]
            failures[names[i]] = (f"{type(exc).__name__}: {exc} (at {where.filename}:"
                                  f"{where.lineno})")
            return
        for event in found:
            if not isinstance(event, Event):
                alive[i] = False
                failures[names[i]] = f"returned {type(event).__name__}, not an Event"
                return
            events.append(event if event.generator else _named(event, names[i]))

    count, last = 0, start_ns or 0
    for message in log.messages(sorted(by_topic), start_ns=start_ns, end_ns=end_ns):
        count += 1
        last = message.log_time_ns
        for i in by_topic[message.name]:
            if alive[i]:
                run(i, partial(generators[i], message))
        if progress is not None and count % 2048 == 0:
            progress(last)
    # Open events end where the log (or the window) ends, not at the last message the
    # generators read: a robot down at its last fall/state stays down until the end.
    log_end = log.time_range()[1]
    finish_at = max(last, min(end_ns - 1, log_end) if end_ns is not None else log_end)
    for i, g in enumerate(generators):
        if alive[i]:
            run(i, partial(g.finish, finish_at))
    events.sort(key=lambda e: (e.start_ns, e.end_ns, e.robot, e.name))
    return Detection(events, failures, count, log.problems)


def _where(call: Callable[[], object]) -> str:
    """``at FILE:LINE`` of the method ``call`` (a partial of it) runs."""
    target = call.func if isinstance(call, partial) else call
    target = getattr(target, "_fn", None) or target  # a function made a generator
    try:
        return f"at {inspect.getsourcefile(target)}:{inspect.getsourcelines(target)[1]}"
    except (TypeError, OSError):
        return f"in {target!r}"


def _named(event: Event, generator: str) -> Event:
    return Event(event.name, event.start_ns, event.end_ns, event.robot, event.description,
                 dict(event.metadata), generator)
