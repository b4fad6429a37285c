"""The writer thread: everything that costs time happens here, off the callback path.

A recorder's subscription callback only appends ``(topic, message, receive time)`` to a
bounded queue; messages are shared by reference in a container, so nothing is copied. This
thread serializes (CDR), keeps the pre-event ring buffer, and writes through
:class:`rosbag2_layout.BagWriter` (compression happens there, per chunk).
Commands (start, stop, split, snapshot) travel through the same queue, so a stop writes every
message received before it.

When the queue is full the newest message is dropped and counted for its topic: a full
queue means the writer cannot keep up, and blocking the callback would stall the robot.
"""

from __future__ import annotations

import contextlib
import threading
import time
from collections import deque
from collections.abc import Callable, Iterator, Mapping
from concurrent.futures import Future
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from rclpy.serialization import serialize_message

from rosbag2_layout import (
    BagConfigError,
    BagWriteError,
    BagWriter,
    FileSystem,
    QosDict,
    Rosbag2Error,
    trim,
)
from rosbag2_layout import UnknownTypeError as BagTypeError

from .errors import RecorderConfigError, RecorderError, StorageError, UnknownTypeError

__all__ = ["RecordWriter", "TopicState", "message_fields"]

IDLE, RECORDING, FAILED = 0, 1, 2
# The longest the writer holds back for the executor before working regardless.
_PACE_MAX_S = 0.005


@dataclass(eq=False)
class TopicState:
    """One recorded topic; each counter is written by one thread only and read by any
    (two threads incrementing one counter could lose counts)."""

    name: str
    type_name: str
    #: The QoS profiles its publishers offered (stored in the bag, offered again on play).
    qos_profiles: tuple[QosDict, ...] = ()
    messages: int = 0  # written to the current recording (writer thread)
    bytes: int = 0  # serialized bytes written (writer thread)
    queue_drops: int = 0  # queue full (callback thread)
    write_drops: int = 0  # could not be serialized or written (writer thread)
    #: Never received: DDS reported them lost (a reliable KEEP_LAST publisher under load
    #: drops its oldest unacknowledged samples). Callback thread.
    dds_lost: int = 0

    @property
    def drops(self) -> int:
        """Messages published but not recorded, for whatever reason (DDS's losses too)."""
        return self.queue_drops + self.write_drops + self.dds_lost


@dataclass
class _Command:
    action: Callable[[], Any]
    future: Future[Any]


class RecordWriter:
    """Owns the queue, the thread and the open bag. Create, :meth:`start`, :meth:`close`."""

    def __init__(
        self,
        *,
        queue_depth: int = 1000,
        snapshot_bytes: int = 0,
        snapshot_seconds: float = 10.0,
        bag_options: Mapping[str, Any] | None = None,
        fs: FileSystem | None = None,
        clock_topic: str = "",
        on_state: Callable[[], None] | None = None,
        pacer: Callable[[], float] | None = None,
        batch_s: float = 0.01,
        name: str = "recorder",
    ) -> None:
        """``pacer()`` returns how long the writer should hold back before its next piece of
        work (seconds; 0 = go): the recorder uses it to stay clear of the executor's timer
        deadlines, so the control loop never waits for the GIL (see docs/RECORDER.md)."""
        if queue_depth < 1:
            raise RecorderConfigError(f"queue_depth must be >= 1, not {queue_depth}")
        if snapshot_bytes < 0 or snapshot_seconds < 0:
            raise RecorderConfigError("snapshot_bytes and snapshot_seconds must be >= 0")
        self._queue: deque[tuple[TopicState, Any, int] | _Command] = deque()
        self._depth = queue_depth
        self._snapshot_bytes = snapshot_bytes
        self._snapshot_ns = int(snapshot_seconds * 1e9)
        self._ring: deque[tuple[TopicState, bytes, int]] = deque()
        self.ring_bytes = 0
        self._bag_options = dict(bag_options or {})
        self._fs = fs
        self._clock_topic = clock_topic
        self._clock_msg: Any = None
        self._on_state = on_state
        self._pacer = pacer
        self.paced_s = 0.0  # time spent holding back for the executor (measuring)
        self._bag: BagWriter | None = None
        self._wake = threading.Event()
        self._sleeping = False
        self._batch_s = batch_s
        self._wake_at = max(0, queue_depth // 4 - 1)  # queue length that ends a batch wait
        self._closing = False
        # Read by the callback on every message: a plain attribute, no lock.
        self.accepting = snapshot_bytes > 0
        self.high_water = 0  # the longest the queue has been (how close to dropping)
        self.state = IDLE
        self.error = ""
        self.bag_path: Path | None = None
        self.topics: dict[str, TopicState] = {}
        self._thread = threading.Thread(target=self._run, name=f"{name}-writer", daemon=True)
        self._thread.start()

    # -- the hot path (subscription callbacks) ---------------------------------------------

    def enqueue(self, topic: TopicState, msg: Any, receive_ns: int) -> None:
        """Hand ``msg`` (by reference) to the writer; count a drop if the queue is full."""
        if not self.accepting:
            return
        queue = self._queue
        length = len(queue)
        if length >= self._depth:
            topic.queue_drops += 1
            return
        if length >= self.high_water:
            self.high_water = length + 1
        queue.append((topic, msg, receive_ns))
        if self._sleeping and length >= self._wake_at:
            self._wake.set()

    # -- commands (any thread) -------------------------------------------------------------

    def start(self, bag: Path) -> Future[Path]:
        """Open ``bag``; messages enqueued from now on are recorded.

        Call it from the thread that runs the subscription callbacks (or before they run):
        it resets the drop counters those callbacks increment (the writer thread resets its
        own when the start command reaches it).
        """
        if self.state == RECORDING:
            raise RecorderError(f"already recording into {self.bag_path}")
        if bag.exists():
            raise RecorderConfigError(f"bag directory {bag} exists already")
        for topic in self.topics.values():
            topic.queue_drops = topic.dds_lost = 0
        self.accepting = True
        return self._command(lambda: self._start(bag))

    def stop(self) -> Future[Path | None]:
        return self._command(self._stop)

    def split(self) -> Future[Path | None]:
        """Close the current file; returns the closed file (None if none was open)."""
        return self._command(self._split)

    def snapshot(self, bag: Path) -> Future[tuple[Path, int]]:
        """Write the ring buffer's messages as bag ``bag``; returns it and the message count."""
        return self._command(lambda: self._snapshot(bag))

    def drain(self) -> Future[None]:
        """Completes once everything enqueued before it was handled (tests, benchmarks)."""
        return self._command(lambda: None)

    def queue_length(self) -> int:
        return len(self._queue)

    @property
    def current_file(self) -> Path | None:
        bag = self._bag
        return bag.current_file if bag is not None else None

    def close(self, *, timeout_s: float = 10.0) -> None:
        """Finish the recording (every queued message is written) and end the thread.

        Raises :class:`StorageError` if the bag could not be closed, or if the thread did
        not finish within ``timeout_s`` (a stalled disk): what was queued then is lost, and
        the caller is told so instead of the loss going unnoticed.
        """
        if self._closing:
            return
        stopped = self.stop()
        self._closing = True
        self._wake.set()
        self._thread.join(timeout_s)
        self.accepting = False  # nobody takes messages off the queue any more
        if self._thread.is_alive():
            stopped.cancel()
            raise StorageError(
                f"the writer thread did not finish within {timeout_s} s; "
                f"{len(self._queue)} queued items are not written")
        error = stopped.exception()
        if error is not None:
            raise error

    def _command(self, action: Callable[[], Any]) -> Future[Any]:
        future: Future[Any] = Future()
        if self._closing:
            future.set_exception(RecorderError("the recorder is closed"))
            return future
        self._queue.append(_Command(action, future))
        self._wake.set()
        return future

    # -- the writer thread -----------------------------------------------------------------

    def _run(self) -> None:
        # The writer works in batches: once the queue is empty it sleeps ``batch_s`` (0.1 s
        # when nothing came at all) unless the queue fills to a quarter or a command
        # arrives. One wake-up per batch instead of one per message saves the context
        # switches and GIL hand-overs that would otherwise cost more than the writing.
        queue = self._queue
        worked = False
        while True:
            if not queue:
                if self._closing:
                    return
                self._sleeping = True
                if not queue:
                    self._wake.wait(self._batch_s if worked else 0.1)
                    self._wake.clear()
                self._sleeping = False
                worked = False
                self._tick()
                continue
            worked = True
            if self._pacer is not None and len(queue) < self._depth // 2:
                self._pace()
            item = queue.popleft()
            if isinstance(item, _Command):
                self._execute(item)
                continue
            try:
                self._record(*item)
            except Exception as exc:  # unforeseen (a library's bug): stop and say so
                item[0].write_drops += 1
                self._failed(f"recording a message of {item[0].name} failed: {exc!r}")

    def _record(self, topic: TopicState, msg: Any, receive_ns: int) -> None:
        """Serialize one message, keep it for snapshots, write it if recording."""
        try:
            data = trim(msg, serialize_message(msg))
        except Exception as exc:  # a message rclpy cannot serialize: count, report
            topic.write_drops += 1
            self.error = f"cannot serialize a message of {topic.name}: {exc!r}"
            return
        if topic.name == self._clock_topic:
            self._clock_msg = msg
        if self._snapshot_bytes:
            self._keep(topic, data, receive_ns)
        bag = self._bag
        if bag is None:
            return
        try:
            with _storage_errors():
                if topic.name not in bag.topics:
                    bag.add_topic(topic.name, topic.type_name,
                                  qos_profiles=list(topic.qos_profiles))
                bag.write(topic.name, topic.type_name, data, receive_ns)
        except StorageError as exc:
            topic.write_drops += 1
            self._failed(str(exc))
            return
        except RecorderError as exc:  # a topic changed its type: keep the rest
            topic.write_drops += 1
            self.error = str(exc)
            return
        topic.messages += 1
        topic.bytes += len(data)
        self._tick()

    def _pace(self) -> None:
        """Hold back while the pacer asks, at most ``_PACE_MAX_S`` in a row (no starvation)."""
        assert self._pacer is not None
        waited = 0.0
        while waited < _PACE_MAX_S and not self._closing:
            wait = min(self._pacer(), _PACE_MAX_S - waited)
            if wait <= 0:
                break
            time.sleep(wait)
            waited += wait
        self.paced_s += waited

    def _tick(self) -> None:
        bag = self._bag
        if bag is not None:
            try:
                with _storage_errors():
                    bag.tick()
            except Exception as exc:  # StorageError, or anything unforeseen: stop, report
                self._failed(str(exc) if isinstance(exc, StorageError) else repr(exc))

    def _execute(self, command: _Command) -> None:
        if not command.future.set_running_or_notify_cancel():
            return
        try:
            result = command.action()
        except BaseException as exc:
            command.future.set_exception(exc)
        else:
            command.future.set_result(result)
        if self._on_state is not None:
            self._on_state()

    def _keep(self, topic: TopicState, data: bytes, receive_ns: int) -> None:
        ring = self._ring
        ring.append((topic, data, receive_ns))
        self.ring_bytes += len(data)
        while ring and (
            self.ring_bytes > self._snapshot_bytes
            or (self._snapshot_ns and receive_ns - ring[0][2] > self._snapshot_ns)
        ):
            self.ring_bytes -= len(ring.popleft()[1])

    def ring_seconds(self) -> float:
        ring = self._ring
        try:
            return (ring[-1][2] - ring[0][2]) / 1e9 if ring else 0.0
        except IndexError:  # emptied by the writer thread meanwhile
            return 0.0

    def _new_bag(self, bag: Path) -> BagWriter:
        with _storage_errors():
            return BagWriter(bag, file_metadata=self._file_metadata, fs=self._fs,
                             library="robot_recorder", **self._bag_options)

    def _start(self, bag: Path) -> Path:
        if self._bag is not None:
            raise RecorderError(f"already recording into {self._bag.path}")
        try:
            self._bag = self._new_bag(bag)
        except RecorderError:
            self.accepting = self._snapshot_bytes > 0
            raise
        for topic in self.topics.values():
            topic.messages = topic.bytes = topic.write_drops = 0
        self.bag_path = bag
        self.state, self.error = RECORDING, ""
        self.accepting = True
        return bag

    def _stop(self) -> Path | None:
        bag, self._bag = self._bag, None
        self.accepting = self._snapshot_bytes > 0
        if bag is None:
            return None
        try:
            with _storage_errors():
                bag.close()
        except StorageError as exc:
            self._failed(str(exc))
            raise
        self.state = IDLE
        return bag.path

    def _split(self) -> Path | None:
        if self._bag is None:
            raise RecorderError("not recording")
        try:
            with _storage_errors():
                return self._bag.split()
        except StorageError as exc:
            self._failed(str(exc))
            raise

    def _snapshot(self, path: Path) -> tuple[Path, int]:
        if not self._snapshot_bytes:
            raise RecorderConfigError("snapshots are off (snapshot_bytes = 0)")
        bag = self._new_bag(path)
        count = 0
        with _storage_errors():
            try:
                for topic, data, receive_ns in list(self._ring):
                    if topic.name not in bag.topics:
                        bag.add_topic(topic.name, topic.type_name,
                                      qos_profiles=list(topic.qos_profiles))
                    bag.write(topic.name, topic.type_name, data, receive_ns)
                    count += 1
            finally:
                bag.close()
        return path, count

    def _failed(self, message: str) -> None:
        """Stop recording after an error; what the bag holds so far stays readable."""
        bag, self._bag = self._bag, None
        if bag is not None and not bag.closed:  # not closed by a StorageError already
            try:
                bag.close()
            except Exception as exc:  # the first error is the one to report
                message += f" (closing the bag failed too: {exc!r})"
        self.accepting = self._snapshot_bytes > 0
        self.state, self.error = FAILED, message
        if self._on_state is not None:
            self._on_state()

    def _file_metadata(self) -> dict[str, dict[str, str]]:
        if self._clock_msg is None:
            return {}
        fields = message_fields(self._clock_msg)
        fields["topic"] = self._clock_topic
        return {"team_clock": fields}


@contextlib.contextmanager
def _storage_errors() -> Iterator[None]:
    """rosbag2_layout's errors as robot_recorder's (one root for the recorder's callers)."""
    try:
        yield
    except BagWriteError as exc:
        raise StorageError(str(exc)) from exc
    except BagConfigError as exc:
        raise RecorderConfigError(str(exc)) from exc
    except BagTypeError as exc:
        raise UnknownTypeError(str(exc)) from exc
    except Rosbag2Error as exc:
        raise RecorderError(str(exc)) from exc


def message_fields(msg: Any, prefix: str = "") -> dict[str, str]:
    """A message flattened to ``{"stamp.sec": "12", ...}`` (MCAP metadata holds strings)."""
    out: dict[str, str] = {}
    for name in msg.get_fields_and_field_types():
        value = getattr(msg, name)
        if hasattr(value, "get_fields_and_field_types"):
            out.update(message_fields(value, f"{prefix}{name}."))
        else:
            out[f"{prefix}{name}"] = str(value)
    return out
