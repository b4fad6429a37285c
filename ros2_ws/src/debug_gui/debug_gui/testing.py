"""Test doubles for users of debug_gui: drive a view's model without DDS or a browser.

:class:`FakeSource` is a :class:`~debug_gui.source.Source` whose robots, topics, messages,
clock and service answers the test sets::

    source = FakeSource()
    robot = source.add_robot("/robot1", topics={"odom": "nav_msgs/msg/Odometry"})
    model = WorldModel(source, [robot])
    model.activate()
    source.publish(robot, "odom", odom_msg)     # delivered now, on the test's thread
    source.advance(5.0)                          # five seconds later, nothing delivered
    source.reset()                               # a seek: the models forget

It behaves as the live Hub does where a model can tell (topic names resolved under the
robot's namespace, a stream's ``rate_hz`` honoured against the source's clock, ``call``
refused with :class:`~debug_gui.errors.NotLive` when the source is not live), and as a
test wants where the Hub cannot be (delivery at once, on the caller's thread; a callback's
exception reaches the test instead of a log).
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterable, Mapping
from typing import TYPE_CHECKING, Any

from efficient_comm.handle import QoSLike

from .errors import InvalidInput, NotLive, RobotUnavailable
from .robots import STATS_SUFFIX, RobotId
from .security import check_name, check_rate

if TYPE_CHECKING:
    from .source import Source

#: A service's answer: the response itself, or a function of the request (typed Any: a
#: response is any service's Response class).
Answer = Any


class FakeStream:
    """One subscription to a :class:`FakeSource` (a :class:`~debug_gui.source.Stream`)."""

    def __init__(self, source: FakeSource, robot: RobotId, topic: str, msg_type: type,
                 callback: Callable[[Any], None], *, rate_hz: float | None,
                 qos: QoSLike) -> None:
        self._source = source
        self._robot = robot
        self._topic = topic
        self.msg_type = msg_type
        self.qos = qos
        self._callback = callback
        self._rate_hz = rate_hz
        self._last_s: float | None = None
        self._received = 0
        self.closed = False

    @property
    def robot(self) -> RobotId:
        return self._robot

    @property
    def topic(self) -> str:
        return self._topic

    @property
    def received(self) -> int:
        return self._received

    @property
    def rate_hz(self) -> float | None:
        return self._rate_hz

    def set_rate(self, rate_hz: float | None) -> None:
        self._rate_hz = check_rate(rate_hz)

    def close(self) -> None:
        if not self.closed:
            self.closed = True
            self._source._forget(self)

    def _offer(self, msg: Any, now: float) -> bool:
        """Deliver ``msg`` unless the stream's rate says it comes too soon after the last."""
        if self.closed:
            return False
        if self._rate_hz is not None and self._last_s is not None \
                and self._last_s <= now < self._last_s + 1.0 / self._rate_hz:
            return False
        self._last_s = now
        self._received += 1
        self._callback(msg)
        return True

    def _rewind(self) -> None:
        self._last_s = None


class _Robot:
    def __init__(self, robot: RobotId) -> None:
        self.robot = robot
        self.topics: dict[str, list[str]] = {}
        self.services: dict[str, list[str]] = {}
        self.nodes: set[str] = set()
        self.answers: dict[str, Answer] = {}


class FakeSource:
    """A Source without DDS: robots, topics and answers as the test adds them.

    ``live=False`` makes it stand for a log played back: :meth:`call` then raises NotLive,
    as a playback does. The clock starts at ``start_s`` and moves only when the test moves
    it (:meth:`advance`, :meth:`set_time`): a paused playback.
    """

    def __init__(self, *, live: bool = True, start_s: float = 0.0) -> None:
        self._live = bool(live)
        self._now = float(start_s)
        self._lock = threading.RLock()
        self._robots: dict[RobotId, _Robot] = {}
        self._streams: list[FakeStream] = []
        self._reset_listeners: list[Callable[[], None]] = []
        self._robot_listeners: list[Callable[[], None]] = []

    # -- what the test drives ---------------------------------------------------------

    def add_robot(
        self,
        robot: RobotId | str,
        *,
        domain: int = 0,
        topics: Mapping[str, str] = {},
        services: Mapping[str, str] = {},
        nodes: Iterable[str] = (),
        statistics: bool = True,
    ) -> RobotId:
        """Add a robot (a RobotId, or a namespace in ``domain``) with ``topics`` and
        ``services`` (names relative to its namespace or absolute, to their types), its
        ``nodes``, and, with ``statistics``, an efficient_comm statistics topic. Returns
        the robot; ``on_robots_changed`` callbacks run."""
        rid = robot if isinstance(robot, RobotId) else RobotId(domain, robot)
        with self._lock:
            entry = self._robots.setdefault(rid, _Robot(rid))
            if statistics:
                entry.topics[rid.stats_topic] = ["efficient_comm_interfaces/msg/ExecutorStats"]
            for name, type_name in topics.items():
                entry.topics[rid.resolve(name)] = [type_name]
            for name, type_name in services.items():
                entry.services[rid.resolve(name)] = [type_name]
            entry.nodes.update(rid.resolve(n) for n in nodes)
        self._notify(self._robot_listeners)
        return rid

    def add_topic(self, robot: RobotId, topic: str, type_name: str) -> None:
        """The robot publishes ``topic`` (relative or absolute) of ``type_name`` from now on."""
        with self._lock:
            self._robot(robot).topics[robot.resolve(topic)] = [type_name]

    def remove_robot(self, robot: RobotId) -> None:
        """The robot goes (its streams stay open and deliver nothing, as the Hub's do)."""
        with self._lock:
            self._robots.pop(robot, None)
        self._notify(self._robot_listeners)

    def answer(self, robot: RobotId, service: str, response: Answer) -> None:
        """``call`` of ``service`` answers ``response`` (or ``response(request)`` if it is
        callable; raising from it is the call raising)."""
        with self._lock:
            self._robot(robot).answers[robot.resolve(service)] = response

    def publish(self, robot: RobotId, topic: str, msg: Any) -> int:
        """Deliver ``msg`` now to every open stream of ``topic`` (relative or absolute)
        whose rate lets it through, on this thread; returns how many streams got it."""
        full = robot.resolve(topic)
        with self._lock:
            streams = [s for s in self._streams if s.robot == robot and s.topic == full]
            now = self._now
        for s in streams:
            if not isinstance(msg, s.msg_type):
                raise InvalidInput(f"{full} is subscribed as {s.msg_type.__name__}, "
                                   f"not {type(msg).__name__}")
        return sum(s._offer(msg, now) for s in streams)

    def advance(self, seconds: float) -> float:
        """Move the clock forward by ``seconds`` (nothing is delivered); the new time."""
        if not seconds >= 0:
            raise InvalidInput(f"advance by a positive number of seconds, not {seconds!r}; "
                               "set_time and reset go back")
        return self.set_time(self._now + seconds)

    def set_time(self, now_s: float) -> float:
        """Set the clock (backwards too: call :meth:`reset` as a seek would)."""
        with self._lock:
            self._now = float(now_s)
            return self._now

    def reset(self) -> None:
        """What a seek does: the ``on_reset`` callbacks run, the streams' rate limits start
        over (the next message of each is delivered)."""
        with self._lock:
            for s in self._streams:
                s._rewind()
        self._notify(self._reset_listeners)

    def streams(self, robot: RobotId | None = None, topic: str | None = None
                ) -> list[FakeStream]:
        """The open streams (of ``robot``, of ``topic``): what the models subscribed to."""
        with self._lock:
            return [s for s in self._streams
                    if (robot is None or s.robot == robot)
                    and (topic is None or robot is None or s.topic == robot.resolve(topic))]

    # -- the Source protocol --------------------------------------------------------------

    @property
    def live(self) -> bool:
        return self._live

    def now(self) -> float:
        with self._lock:
            return self._now

    def on_reset(self, callback: Callable[[], None]) -> Callable[[], None]:
        return self._listen(self._reset_listeners, callback)

    def robots(self) -> list[RobotId]:
        with self._lock:
            return sorted(self._robots)

    def on_robots_changed(self, callback: Callable[[], None]) -> Callable[[], None]:
        return self._listen(self._robot_listeners, callback)

    def topics(self, robot: RobotId) -> dict[str, list[str]]:
        with self._lock:
            return {k: list(v) for k, v in sorted(self._robot(robot).topics.items())}

    def publishes(self, robot: RobotId, topic: str) -> bool:
        with self._lock:
            entry = self._robots.get(robot)
            return entry is not None and robot.resolve(topic) in entry.topics

    def publishes_statistics(self, robot: RobotId) -> bool:
        return self.publishes(robot, STATS_SUFFIX)

    def nodes(self, robot: RobotId) -> list[str]:
        with self._lock:
            return sorted(self._robot(robot).nodes)

    def services(self, robot: RobotId) -> dict[str, list[str]]:
        with self._lock:
            return {k: list(v) for k, v in sorted(self._robot(robot).services.items())}

    def subscribe(
        self,
        robot: RobotId,
        topic: str,
        msg_type: type,
        callback: Callable[[Any], None],
        *,
        rate_hz: float | None = None,
        qos: QoSLike = 10,
    ) -> FakeStream:
        check_name(topic, what="topic name")
        stream = FakeStream(self, robot, robot.resolve(topic), msg_type, callback,
                            rate_hz=check_rate(rate_hz), qos=qos)
        with self._lock:
            self._streams.append(stream)
        return stream

    def call(
        self,
        robot: RobotId,
        service: str,
        srv_type: type,
        request: Any,
        *,
        timeout_s: float = 5.0,
    ) -> Any:
        full = robot.resolve(service)
        if not self._live:
            raise NotLive(f"{robot.label}: {full} cannot be called on a recorded log")
        with self._lock:
            answer = self._robot(robot).answers.get(full)
        if answer is None:
            raise RobotUnavailable(f"{robot.label}: no service {full}")
        return answer(request) if callable(answer) else answer

    # -- internals -------------------------------------------------------------------

    def _robot(self, robot: RobotId) -> _Robot:
        entry = self._robots.get(robot)
        if entry is None:
            raise RobotUnavailable(f"{robot.label} is not a robot of this source")
        return entry

    def _forget(self, stream: FakeStream) -> None:
        with self._lock:
            if stream in self._streams:
                self._streams.remove(stream)

    def _listen(self, listeners: list[Callable[[], None]], callback: Callable[[], None]
                ) -> Callable[[], None]:
        with self._lock:
            listeners.append(callback)

        def unsubscribe() -> None:
            with self._lock:
                if callback in listeners:
                    listeners.remove(callback)

        return unsubscribe

    def _notify(self, listeners: list[Callable[[], None]]) -> None:
        with self._lock:
            todo = list(listeners)
        for cb in todo:
            cb()


__all__ = ["FakeSource", "FakeStream"]

if TYPE_CHECKING:
    _FAKE_IS_A_SOURCE: type[Source] = FakeSource
