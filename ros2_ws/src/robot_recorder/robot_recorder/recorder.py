"""The recorder component: subscribes, enqueues by reference, and takes remote commands.

Composed with the robot's components it receives their messages by reference (no copy, no
serialization in the callback); messages from other processes reach it through its DDS
reader like any composed subscriber. Its callback only appends to the writer's queue
(:mod:`robot_recorder.writer`); serializing, compressing and writing happen in the writer
thread.

Remote control (services, relative to the node: ``~/start``, ``~/stop``, ``~/split``,
``~/snapshot``, ``~/set_topics``) and ``~/status`` (about once a second and on every change).

Clock estimates (``clock_topic``, team_clock's ``/team_clock/offset``) are recorded for one
robot only, this one: on a DDS domain shared by a team every robot's estimates reach every
recorder, and a log holding another robot's estimates would be aligned with the wrong
clock. The robot is the ``clock_robot`` parameter, else the one whose clock sync publishes
the estimates in this process (composed in the same container).
"""

from __future__ import annotations

import datetime
import math
import sys
import threading
from collections.abc import Callable, Iterable, Sequence
from concurrent.futures import Future
from pathlib import Path
from typing import Any

from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy

from efficient_comm import matching_qos, to_msg
from efficient_comm.handle import NodeHandle, Subscription, TimerSchedule
from rosbag2_layout import (
    FileSystem,
    full_definition,
    import_type,
    qos_dict,
    type_name,
)
from rosbag2_layout import UnknownTypeError as BagTypeError
from throttle_publisher import Gate, ThrottledSubscription, ThrottleOptions

from .errors import RecorderConfigError, RecorderError, UnknownTypeError
from .selection import TopicSelection, parse_selection
from .writer import RECORDING, RecordWriter, TopicState

__all__ = ["DEFAULT_CLOCK_TOPIC", "Recorder"]

DEFAULT_CLOCK_TOPIC = "/team_clock/offset"
#: How long a service waits for the writer thread to confirm a command.
SERVICE_WAIT_S = 5.0


class _Active:
    """A subscribed topic: its selection, state and endpoint."""

    def __init__(self, selection: TopicSelection, state: TopicState, endpoint: Any) -> None:
        self.selection = selection
        self.state = state
        self.endpoint = endpoint


class _Subsampled:
    """A throttled selection's endpoints: the throttle request, and the recorder's own
    subsampling for publishers that do not honour it.

    A ThrottledPublisher sends the recorder its share on a reply topic of its own; a plain
    publisher ignores the request and would send a throttled recorder nothing at all. So
    until a throttle-aware publisher answers (:attr:`ThrottledSubscription.answered`), the
    plain topic is subscribed too and a :class:`~throttle_publisher.Gate` (the same
    decision a ThrottledPublisher makes) drops the surplus here. :meth:`settle`, called by
    the recorder's timer, drops the plain subscription once the publisher throttles itself,
    so the link then carries only the asked rate.
    """

    def __init__(self, node: NodeHandle, msg_type: type, name: str,
                 callback: Callable[[Any], None], *, options: ThrottleOptions,
                 qos: QoSProfile) -> None:
        self._node = node
        self._callback = callback
        self._gate = Gate(options)
        self.throttled = ThrottledSubscription(node, msg_type, name, callback,
                                               options=options, qos=qos)
        self._plain: Subscription | None = None
        if not self.throttled.answered:
            self._plain = node.create_subscription(msg_type, name, self._on_plain, qos=qos)

    @property
    def subsampling(self) -> bool:
        """Whether the recorder drops the surplus itself (no throttle-aware publisher)."""
        return self._plain is not None

    def _on_plain(self, msg: Any) -> None:
        if self.throttled.answered:
            return  # the publisher now sends this recorder's share on the reply topic
        if self._gate.offer(self._node.clock.now_ns()):
            self._callback(msg)

    def settle(self) -> None:
        if self._plain is not None and self.throttled.answered:
            self._node.destroy_subscription(self._plain)
            self._plain = None

    def close(self) -> None:
        if self._plain is not None:
            self._node.destroy_subscription(self._plain)
            self._plain = None
        self.throttled.close()


class Recorder:
    """Records selected topics into MCAP bags (rosbag2 layout), controlled remotely.

    Parameters (ROS): ``topics`` (see :mod:`robot_recorder.selection`), ``output_dir``,
    ``autostart``, ``queue_depth``, ``chunk_interval_s``, ``chunk_bytes``,
    ``max_file_bytes``, ``max_file_duration_s``, ``min_free_bytes``, ``compression``,
    ``snapshot_bytes``, ``snapshot_seconds``, ``status_period_s``, ``clock_topic``,
    ``clock_robot`` (whose clock estimates to record; empty: the robot whose clock sync
    shares the container),
    ``gil_switch_interval_s`` (0 leaves the interpreter's setting alone),
    ``pace_before_timers_s`` and ``pace_after_timers_s`` (the writer keeps off the GIL
    around the container's timer deadlines; 0 and 0 turn that off).
    Keyword options override them from Python; ``fs`` is the file-system seam.
    """

    def __init__(
        self,
        node: NodeHandle,
        *,
        topics: Sequence[TopicSelection | str] | None = None,
        output_dir: str | Path | None = None,
        autostart: bool | None = None,
        clock_topic: str | None = None,
        fs: FileSystem | None = None,
    ) -> None:
        self._node = node
        p = node.declare_parameter
        names = p("topics", [""], description="NAME [TYPE] [max_rate_hz=R] [every_nth=N]")
        # Absolute from the start: the status and the services' answers tell a viewer on
        # another machine where the bags are, and it cannot know this process's directory.
        self.output_dir = Path(output_dir if output_dir is not None
                               else p("output_dir", "recordings")).absolute()
        start = p("autostart", False) if autostart is None else autostart
        self.clock_topic = (p("clock_topic", DEFAULT_CLOCK_TOPIC)
                            if clock_topic is None else clock_topic)
        #: The robot whose clock estimates are recorded ("": not known yet).
        self.clock_robot: str = p("clock_robot", "", description="whose clock estimates to "
                                  "record (empty: the clock sync in this container's)")
        self._clock_robots_heard: set[str] = set()  # whose estimates were not recorded
        self._local_robots: set[str] = set()  # whose estimates were published in-process
        self._clock_tap: Any = None
        bag_options = {
            "chunk_interval_s": p("chunk_interval_s", 1.0),
            "chunk_bytes": p("chunk_bytes", 1 << 20),
            "max_file_bytes": p("max_file_bytes", 0),
            "max_file_duration_s": p("max_file_duration_s", 0.0),
            "min_free_bytes": p("min_free_bytes", 64 << 20),
            "compression": p("compression", "zstd"),
        }
        # The writer thread holds the GIL while it serializes; a thread waking up meanwhile
        # (the control loop's timer) waits for it up to the switch interval, 5 ms by
        # default. A shorter interval bounds that wait (see docs/RECORDER.md). It is
        # process-wide: applied once construction succeeded, restored by close().
        switch_interval = float(p("gil_switch_interval_s", 0.0002))
        if switch_interval < 0:
            raise RecorderConfigError(
                f"gil_switch_interval_s must be >= 0 (0: leave it alone), not {switch_interval}")
        self._switch_interval: float | None = None
        selections = [s if isinstance(s, TopicSelection) else parse_selection(s)
                      for s in (topics if topics is not None else [n for n in names if n])]
        self._clock_name = self._resolve(self.clock_topic) if self.clock_topic else ""
        self.writer = RecordWriter(
            queue_depth=p("queue_depth", 1000),
            snapshot_bytes=p("snapshot_bytes", 0),
            snapshot_seconds=p("snapshot_seconds", 10.0),
            bag_options=bag_options,
            fs=fs,
            clock_topic=self._clock_name,
            on_state=self._state_changed,
            pacer=_timer_pacer(node, p("pace_before_timers_s", 0.002),
                               p("pace_after_timers_s", 0.001)),
            name=node.name,
        )
        self._fs = fs or FileSystem()
        self._selections: dict[str, TopicSelection] = {}
        self._active: dict[str, _Active] = {}
        self._status_pub: Any = None
        try:
            self._select(selections)
            self._serve(node)
            node.create_timer(p("status_period_s", 1.0), self._on_timer)
            if switch_interval > 0:
                _SWITCH_INTERVAL.request(switch_interval)
                self._switch_interval = switch_interval
            if start:
                self.start().result(SERVICE_WAIT_S)
        except BaseException:
            self.close()
            raise

    # -- Python API ----------------------------------------------------------------------

    def start(self, bag: str | Path | None = None) -> Future[Path]:
        """Start recording into ``bag`` (default: a new directory under ``output_dir``).

        Returns a future of the bag path (completed by the writer thread). The path is
        also logged, so a user of the command knows which directory to play back.
        """
        future = self.writer.start(Path(bag).absolute() if bag else self._new_bag_path(""))
        future.add_done_callback(self._say_started)
        return future

    def _say_started(self, future: Future[Path]) -> None:
        if future.exception() is None:
            self._node.logger.info(f"recording to {future.result()}")

    def stop(self) -> Future[Path | None]:
        """Close the bag once every message received so far is written; a future of its
        path (None if nothing was recording)."""
        return self.writer.stop()

    def split(self) -> Future[Path | None]:
        """Close the current file and go on in the next; a future of the closed file."""
        return self.writer.split()

    def snapshot(self, bag: str | Path | None = None) -> Future[tuple[Path, int]]:
        """Write the ring buffer (the last ``snapshot_seconds``) as bag ``bag`` (default: a
        new ``snapshot_`` directory under ``output_dir``); a future of it and its count."""
        return self.writer.snapshot(Path(bag).absolute() if bag
                                    else self._new_bag_path("snapshot_"))

    def set_topics(self, selections: Iterable[TopicSelection]) -> None:
        """Record exactly these topics from now on (throttle options may change).

        A selection that cannot be recorded (a topic named twice, a type given that is not
        installed) raises :class:`RecorderError` and changes nothing: what was recorded
        before goes on being recorded.
        """
        selections = list(selections)
        for selection in selections:
            if selection.type:
                _checked_type(selection.type)
        self._select(selections)

    def _select(self, selections: Iterable[TopicSelection]) -> None:
        wanted: dict[str, TopicSelection] = {}
        for selection in selections:
            name = self._resolve(selection.name)
            if name in wanted:
                raise RecorderConfigError(f"topic {name} selected twice")
            wanted[name] = selection
        for name in list(self._active):
            if wanted.get(name) != self._active[name].selection:
                self._unsubscribe(name)
        self._selections = wanted
        self._subscribe_known()

    def topic_states(self) -> dict[str, TopicState]:
        """The counters of every subscribed topic, by resolved name."""
        return {name: a.state for name, a in self._active.items()}

    def close(self) -> None:
        """Finish the recording (every queued message is written); called on unload.

        Raises :class:`StorageError` if the bag could not be finished; the switch interval
        is given back either way.
        """
        try:
            self.writer.close()
        finally:
            if self._clock_tap is not None:
                self._node.destroy_subscription(self._clock_tap)
                self._clock_tap = None
            if self._switch_interval is not None:
                _SWITCH_INTERVAL.release(self._switch_interval)
                self._switch_interval = None

    # -- subscriptions -------------------------------------------------------------------

    def _resolve(self, topic: str) -> str:
        return self._node.resolve_topic_name(topic)

    def _subscribe_known(self) -> None:
        pending = {n: s for n, s in self._selections.items() if n not in self._active}
        clock = self._clock_name
        if clock and clock not in self._selections and clock not in self._active:
            pending[clock] = TopicSelection(name=clock)
        if not pending:
            return
        graph = _graph_types(self._node)
        for name, selection in pending.items():
            type_str = selection.type or graph.get(name, "")
            if not type_str:
                continue  # no publisher yet: the timer looks again
            try:
                msg_type, type_str = _checked_type(type_str)
            except UnknownTypeError as exc:
                self._node.logger.error(f"not recording {name}: {exc}")
                self.writer.error = str(exc)
                continue
            self._subscribe(name, selection, msg_type, type_str)

    def _subscribe(self, name: str, selection: TopicSelection, msg_type: type,
                   type_str: str) -> None:
        qos, offered = _record_qos(self._node, name)
        state = self.writer.topics.get(name)
        if state is None or state.type_name != type_str:
            state = self.writer.topics[name] = TopicState(name, type_str)
        state.qos_profiles = tuple(qos_dict(q) for q in offered)
        enqueue, clock = self.writer.enqueue, self._node.clock

        def on_message(msg: Any, state: TopicState = state) -> None:
            enqueue(state, msg, clock.now_ns())

        callback: Callable[[Any], None] = on_message
        if name == self._clock_name:
            callback = self._own_estimates(on_message, msg_type)

        throttle = selection.throttle()
        endpoint: Any
        if throttle is not None:
            endpoint = _Subsampled(self._node, msg_type, name, callback,
                                   options=throttle, qos=qos)
        else:
            def lost(count: int, state: TopicState = state) -> None:
                if self.writer.accepting:
                    state.dds_lost += count

            endpoint = self._node.create_subscription(msg_type, name, callback, qos=qos,
                                                      on_lost=lost)
        self._active[name] = _Active(selection, state, endpoint)

    def _own_estimates(self, record: Callable[[Any], None], msg_type: type
                       ) -> Callable[[Any], None]:
        """``record`` for the estimates of :attr:`clock_robot` only (see the module doc).

        Without the parameter, the robot is learnt from the estimates published in this
        process: a tap on the in-process bus (no DDS reader) sees only those. It is made
        before the recording subscription, so it hears each estimate first.
        """
        if not self.clock_robot and self._clock_tap is None:
            def learn(msg: Any) -> None:
                robot = str(getattr(msg, "robot", ""))
                if not self.clock_robot and robot:
                    self.clock_robot = robot
                    self._node.logger.info(f"recording the clock estimates of robot {robot!r} "
                                           "(its clock sync shares this container)")
                elif robot and robot != self.clock_robot and robot not in self._local_robots:
                    self._node.logger.warning(
                        f"robots {self.clock_robot!r} and {robot!r} both publish clock "
                        f"estimates in this container; recording {self.clock_robot!r}'s "
                        "(the clock_robot parameter chooses)")
                self._local_robots.add(robot)

            # None standalone: no clock sync shares the process, clock_robot must say.
            self._clock_tap = self._node.observe_in_process(msg_type, self._clock_name, learn)

        def on_estimate(msg: Any) -> None:
            robot = str(getattr(msg, "robot", ""))
            if robot and robot == self.clock_robot:
                record(msg)
            elif robot not in self._clock_robots_heard:
                self._clock_robots_heard.add(robot)
                self._node.logger.info(
                    f"not recording the clock estimates of robot {robot!r} on "
                    f"{self._clock_name}: this log is robot "
                    f"{self.clock_robot or '(none yet: set clock_robot)'}'s")

        return on_estimate

    def _unsubscribe(self, name: str) -> None:
        active = self._active.pop(name)
        if isinstance(active.endpoint, _Subsampled):
            active.endpoint.close()
        else:
            sub: Subscription = active.endpoint
            self._node.destroy_subscription(sub)

    # -- services and status --------------------------------------------------------------

    def _serve(self, node: NodeHandle) -> None:
        from robot_recorder_interfaces.msg import RecorderStatus
        from robot_recorder_interfaces.srv import SetTopics, Snapshot, Split, Start, Stop

        self._status_pub = node.create_publisher(RecorderStatus, "~/status", qos=10)
        node.create_service(Start, "~/start", self._srv_start)
        node.create_service(Stop, "~/stop", self._srv_stop)
        node.create_service(Split, "~/split", self._srv_split)
        node.create_service(Snapshot, "~/snapshot", self._srv_snapshot)
        node.create_service(SetTopics, "~/set_topics", self._srv_set_topics)

    def _answer(self, response: Any, call: Callable[[], Any],
                fill: Callable[[Any], None]) -> Any:
        try:
            result = call()
            fill(result.result(SERVICE_WAIT_S) if hasattr(result, "result") else result)
            response.success = True
        except (RecorderError, OSError, TimeoutError) as exc:
            response.success = False
            response.message = str(exc) or type(exc).__name__
        self.publish_status()
        return response

    def _srv_start(self, request: Any, response: Any) -> Any:
        def fill(bag: Path) -> None:
            response.bag = str(bag)
        return self._answer(response, lambda: self.start(request.bag or None), fill)

    def _srv_stop(self, request: Any, response: Any) -> Any:
        def fill(bag: Path | None) -> None:
            response.bag = str(bag or "")
            response.message = "" if bag else "was not recording"
        return self._answer(response, self.stop, fill)

    def _srv_split(self, request: Any, response: Any) -> Any:
        def fill(closed: Path | None) -> None:
            response.file = str(closed or "")
        return self._answer(response, self.split, fill)

    def _srv_snapshot(self, request: Any, response: Any) -> Any:
        def fill(result: tuple[Path, int]) -> None:
            response.bag, response.messages = str(result[0]), result[1]
        return self._answer(response, lambda: self.snapshot(request.bag or None), fill)

    def _srv_set_topics(self, request: Any, response: Any) -> Any:
        def call() -> None:
            self.set_topics([
                TopicSelection(name=t.name, type=t.type, max_rate_hz=t.max_rate_hz,
                               every_nth=max(1, t.every_nth))
                for t in request.topics
            ])
        return self._answer(response, call, lambda _: None)

    def _state_changed(self) -> None:
        """The writer thread started, stopped, split or failed: tell ``~/status`` at once
        (publishing from another thread is allowed on every backend)."""
        try:
            self.publish_status()
        except Exception as exc:  # unloading: the publisher is gone; nothing to tell
            self._node.logger.debug(f"status not published: {exc!r}")

    def _on_timer(self) -> None:
        self._subscribe_known()
        for active in self._active.values():
            if isinstance(active.endpoint, _Subsampled):
                active.endpoint.settle()
        self.publish_status()

    def status(self) -> Any:
        """The current :class:`RecorderStatus` message."""
        from robot_recorder_interfaces.msg import RecorderStatus, TopicStatus

        w = self.writer
        msg = RecorderStatus()
        msg.stamp = to_msg(self._node.clock.now_ns())
        msg.state = w.state
        msg.bag = str(w.bag_path or "")
        msg.file = str(w.current_file or "")
        msg.error = w.error
        topics = list(w.topics.values())
        msg.topics = [TopicStatus(name=t.name, type=t.type_name, messages=t.messages,
                                  bytes=t.bytes, drops=t.drops) for t in topics]
        msg.messages = sum(t.messages for t in topics)
        msg.bytes = sum(t.bytes for t in topics)
        msg.drops = sum(t.drops for t in topics)
        try:
            where = w.bag_path if w.bag_path and w.bag_path.exists() else self.output_dir
            while not where.exists() and where != where.parent:
                where = where.parent
            msg.free_bytes = max(0, self._fs.free_bytes(where))
        except OSError:
            msg.free_bytes = 0
        msg.snapshot_bytes = w.ring_bytes
        msg.snapshot_seconds = w.ring_seconds()
        return msg

    def publish_status(self) -> None:
        if self._status_pub is not None:
            self._status_pub.publish(self.status())

    @property
    def recording(self) -> bool:
        return self.writer.state == RECORDING

    def _new_bag_path(self, kind: str) -> Path:
        stamp = datetime.datetime.now(datetime.UTC).strftime("%Y%m%d_%H%M%S_%f")
        return self.output_dir / f"{self._node.name}_{kind}{stamp}"


class _SwitchInterval:
    """The interpreter's switch interval, shared by every recorder of the process.

    ``sys.setswitchinterval`` is process-wide, so recorders ask for an interval and give it
    back: while any recorder lives the shortest one asked for applies, and when the last one
    closes the interval from before the first is restored (unless someone else changed it
    meanwhile; then it is left alone).
    """

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._asked: list[float] = []
        self._before = 0.0
        self._applied = 0.0

    def request(self, seconds: float) -> None:
        with self._lock:
            if not self._asked:
                self._before = sys.getswitchinterval()
            self._asked.append(seconds)
            self._apply(min([self._before, *self._asked]))

    def release(self, seconds: float) -> None:
        with self._lock:
            self._asked.remove(seconds)
            self._apply(min([self._before, *self._asked]))

    def _apply(self, seconds: float) -> None:
        current = sys.getswitchinterval()
        if not self._applied or math.isclose(current, self._applied):  # else: theirs wins
            if current != seconds:
                sys.setswitchinterval(seconds)
            self._applied = sys.getswitchinterval()
        if not self._asked:
            self._applied = 0.0


_SWITCH_INTERVAL = _SwitchInterval()


def _checked_type(type_str: str) -> tuple[type, str]:
    """The message class and canonical name of ``type_str``; :class:`UnknownTypeError` if
    it is not installed or its definition could not be written into the bag."""
    try:
        msg_type = import_type(type_str)
        canonical = type_name(msg_type)
        full_definition(canonical)  # refuse now what could not be written later
    except BagTypeError as exc:  # the recorder's own class: callers catch RecorderError
        raise UnknownTypeError(str(exc)) from exc
    return msg_type, canonical


def _graph_types(node: NodeHandle) -> dict[str, str]:
    """Topic name -> ``pkg/msg/Type`` of every topic this process or the DDS graph knows."""
    return {name: types[0] for name, types in node.graph.topic_names_and_types().items()
            if types}


def _record_qos(node: NodeHandle, topic: str) -> tuple[QoSProfile, list[QoSProfile]]:
    """The QoS to record ``topic`` with, and the profiles its known publishers offer.

    :func:`efficient_comm.matching_qos`: best effort if a publisher is, transient local if
    all are, so a latched publisher's message from before the recorder started is recorded.
    """
    offered = node.graph.publishers_qos(topic)
    qos = matching_qos(offered, depth=100)
    if qos.reliability == ReliabilityPolicy.RELIABLE:
        # KEEP_ALL: the reader never replaces a sample the executor has not taken yet (a
        # loss nobody would report); a publisher that outruns it is held back by DDS's flow
        # control, and what its own KEEP_LAST history drops then is reported (on_lost).
        qos.history = HistoryPolicy.KEEP_ALL
    return qos, offered


def _timer_pacer(node: NodeHandle, before_s: float, after_s: float
                 ) -> Callable[[], float] | None:
    """Keeps the writer thread off the GIL around the container's next timer deadline.

    A timer callback that is due while the writer thread runs Python code waits for the
    GIL (up to the switch interval, more on a loaded machine): that is the whole latency a
    background writer adds to a timer-driven control loop. So the writer holds back from
    ``before_s`` ahead of the next deadline until ``after_s`` after it (the callbacks of that
    round run meanwhile). Only for composed components on a real clock; None otherwise.
    """
    schedule = node.timer_schedule
    if schedule is None or node.clock_kind != "system":  # manual or /clock: no wall deadlines
        return None
    if before_s <= 0 and after_s <= 0:
        return None
    return _pacer(schedule, int(before_s * 1e9), int(after_s * 1e9))


def _pacer(executor: TimerSchedule, before_ns: int, after_ns: int) -> Callable[[], float]:
    """The pacing function of :func:`_timer_pacer` (runs in the writer thread)."""
    clock, next_due = executor.clock, executor.next_timer_due_ns
    last_due = -(1 << 62)  # no round of callbacks seen yet

    def pace() -> float:
        nonlocal last_due
        now = clock.now_ns()
        if now - last_due < after_ns:  # a round of callbacks has just started
            return (last_due + after_ns - now) / 1e9
        due = next_due()  # a hint from another thread: good enough to keep clear
        if due is None or due - now > before_ns:
            return 0.0
        last_due = due
        return max(0, due - now + after_ns) / 1e9

    return pace
