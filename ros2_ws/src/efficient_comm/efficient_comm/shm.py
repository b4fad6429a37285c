"""Large messages between efficient_comm processes on one machine, through shared memory.

DDS hands a 1 MiB image from one Python process to another in milliseconds: CDR
serialization and two full copies. This module carries the big array of such a message
(``sensor_msgs/Image``'s ``data``, ``PointCloud2``'s, ``CompressedImage``'s, a
``Float32MultiArray``'s: any message with exactly one top-level sequence of numbers)
through iceoryx2's zero-copy publish-subscribe instead. The publisher copies the array once
into a loaned chunk, next to the rest of the message pickled (small: header, sizes,
encoding; see :class:`_Rest`); each subscribing process reads the chunk in place: the
message it gets holds a read-only numpy array over the shared chunk, and the chunk stays its
until the last reference to that array is gone (iceoryx2 never reuses a chunk a reader
holds). A thread of the receiving process waits on iceoryx2 and posts each ready
subscription's receive to the executor, whose thread waits on DDS as without the
transport (:class:`ShmWatch`).

Turned on per container (``Container(shm=True)``) or for every container of a process by
``EFFICIENT_COMM_SHM=1``; ``shm_threshold_bytes`` (``EFFICIENT_COMM_SHM_THRESHOLD``) is the
array size from which a message takes this path. Components see nothing of it: the node
handle's API is the same.

**Exactly once.** DDS stays: discovery, other machines, plain rclpy nodes and the ``ros2``
tools. So a subscriber in a process with the transport has both a DDS reader and a
shared-memory subscriber, and must not get a message over both. The publisher writes the
DDS copy only while DDS has matched more readers than shared memory serves (a plain peer
listens); then it announces the copy in the chunk's header (its DDS sequence number and a
wall-clock window for its source timestamp), sends the chunk and only then writes the
copy, so a subscriber, which drains shared memory before it takes a DDS sample, has the
announcement first and drops the copy (should a copy still come first, the chunk is the
one dropped). Messages below the threshold go over DDS alone, and are delivered from there.

**Loss.** Every chunk carries its publisher's sequence number; a gap (a slow reader whose
queue overflowed: the publisher never waits for one) is counted in the subscription's
``dropped`` statistic and told to ``on_lost``, as DDS's losses are.

**Crashes.** A process killed with SIGKILL leaves its shared-memory files behind; the next
iceoryx2 node created on the machine (any container with the transport) removes them. The
publisher never blocks on a reader (iceoryx2's safe overflow), so a dead reader stalls
nobody; a dead publisher's chunks a reader still holds stay readable.

**Fallbacks**, each said once in the endpoint's log: a type without exactly one array of
numbers, a transient-local publisher (DDS keeps the history for late joiners), iceoryx2 missing
or failing: DDS carries the topic, as without the transport. Publishers and subscribers
pair up only with the same message type, reliability and DDS domain.
"""

from __future__ import annotations

import contextlib
import ctypes
import functools
import io
import itertools
import os
import pickle
import re
import secrets
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from rclpy.qos import QoSProfile, ReliabilityPolicy

from ._qos import is_transient_local
from .executor import take_samples
from .typenames import type_name

if TYPE_CHECKING:
    from .bus import LocalPublisher, LocalSubscription
    from .executor import ConsecutiveExecutor
    from .handle import Logger

SHM_ENV = "EFFICIENT_COMM_SHM"
THRESHOLD_ENV = "EFFICIENT_COMM_SHM_THRESHOLD"
#: Arrays from this size take shared memory: below it, DDS costs little more.
DEFAULT_THRESHOLD_BYTES = 64 * 1024

# Per service: a few publishers (one per process, usually one), a few subscribing processes,
# each keeping up to _BUFFER unread chunks and holding up to _BORROWED. The data segment
# is about max_subscribers x (buffer + borrowed) chunks of the largest message, sparse.
_MAX_PUBLISHERS = 4
_MAX_SUBSCRIBERS = 4
_BUFFER = 2
_BORROWED = 4
_INITIAL_SLICE = 64 * 1024
_ALIGN = 16
# How long a subscriber remembers DDS copies it may still have to drop (or did deliver).
_REMEMBER = 64
_WAKE_MS = 500
#: How long after a chunk's send its announced DDS copy may carry as its source timestamp
#: (the copy is written right after the send; together with the DDS sequence number, the
#: window tells the copy from any other sample).
_DDS_WINDOW_NS = 5_000_000_000

# rosidl's basic types -> numpy dtypes (the array field's element type).
_DTYPES = {
    "octet": np.uint8, "uint8": np.uint8, "int8": np.int8, "char": np.uint8,
    "uint16": np.uint16, "int16": np.int16, "uint32": np.uint32, "int32": np.int32,
    "uint64": np.uint64, "int64": np.int64, "float": np.float32, "double": np.float64,
}


def enabled_from_env() -> bool:
    """Whether ``EFFICIENT_COMM_SHM`` turns the transport on for containers that do not say."""
    return os.environ.get(SHM_ENV, "").lower() in ("1", "true", "yes", "on")


def threshold_from_env() -> int:
    value = os.environ.get(THRESHOLD_ENV, "")
    try:
        return max(0, int(value)) if value else DEFAULT_THRESHOLD_BYTES
    except ValueError:
        return DEFAULT_THRESHOLD_BYTES


class _Header(ctypes.Structure):
    """What travels next to every chunk (iceoryx2's user header)."""

    _fields_ = (
        ("publisher", ctypes.c_uint64),  # random per publisher: whose sequence `seq` is
        ("pid", ctypes.c_uint64),  # the publishing process (its own subscribers skip it)
        ("seq", ctypes.c_uint64),  # 1, 2, 3, ... per publisher: gaps are losses
        ("dds_seq", ctypes.c_uint64),  # DDS's sequence number of the DDS copy, 0: none
        ("dds_t0", ctypes.c_int64),  # wall-clock window of the DDS write (its source stamp)
        ("dds_t1", ctypes.c_int64),
        ("sent", ctypes.c_int64),  # wall clock at the send: orders it among DDS samples
        ("meta_len", ctypes.c_uint32),  # bytes of the rest of the message (_Rest)
        ("array_offset", ctypes.c_uint32),
    )

    @staticmethod
    def type_name() -> str:  # iceoryx2 matches both sides' header types by this name
        return "efficient_comm.ShmHeader.3"  # .2: the rest pickled; .3: the send time


@dataclass(frozen=True)
class Layout:
    """Where a message type keeps its big array: the field and its element type."""

    field: str
    dtype: np.dtype[Any]


# Classes the rest of a message may name: generated message classes, and array.array's
# reconstructor (a message's other sequences of numbers).
_MESSAGE_MODULE = re.compile(r"[A-Za-z_]\w*\.msg\._\w+")


class _RestUnpickler(pickle.Unpickler):
    """Builds only messages (and arrays of numbers): what a chunk's rest may hold."""

    def find_class(self, module: str, name: str) -> Any:
        if (module == "array" and name == "_array_reconstructor") or (
                _MESSAGE_MODULE.fullmatch(module) and not name.startswith("_")):
            found = super().find_class(module, name)
            if module == "array" or hasattr(found, "get_fields_and_field_types"):
                return found
        raise pickle.UnpicklingError(f"not a message class: {module}.{name}")


class _Rest:
    """The message without its array, as bytes next to the chunk: the values of its other
    slots, pickled. CDR (rclpy's ``serialize_message`` of a copy with an empty array, and
    ``deserialize_message``, which builds the message through its checking setters) took
    0.1-0.2 ms a side for an Image's few fields; this a fifth of that. The reader restores
    message classes and ``array.array`` only (:class:`_RestUnpickler`).
    """

    def __init__(self, msg_type: type, field: str) -> None:
        self._type = msg_type
        self._array_slot = "_" + field
        self._slots = tuple(slot for slot in getattr(msg_type, "__slots__", ())
                            if slot not in (self._array_slot, "_check_fields"))
        self._check_fields = getattr(msg_type(), "_check_fields", None)

    def dump(self, msg: Any) -> bytes:
        return pickle.dumps(tuple(getattr(msg, slot) for slot in self._slots), protocol=5)

    def load(self, data: bytes, array: Any) -> Any:
        values = _RestUnpickler(io.BytesIO(data)).load()
        msg_type = self._type
        msg: Any = object.__new__(msg_type)
        for slot, value in zip(self._slots, values, strict=True):
            setattr(msg, slot, value)
        setattr(msg, self._array_slot, array)  # the field's setter would copy the array
        if self._check_fields is not None:
            msg._check_fields = self._check_fields
        return msg


def layout(msg_type: type) -> Layout | str:
    """The type's one top-level array of numbers, or why it does not fit."""
    from rosidl_parser.definition import (  # type: ignore[import-untyped]
        BasicType,
        UnboundedSequence,
    )

    fields = list(getattr(msg_type, "get_fields_and_field_types", dict)())
    slots = getattr(msg_type, "SLOT_TYPES", ())
    arrays = [
        (name, slot.value_type.typename)
        for name, slot in zip(fields, slots, strict=False)
        if isinstance(slot, UnboundedSequence) and isinstance(slot.value_type, BasicType)
        and slot.value_type.typename in _DTYPES
    ]
    if len(arrays) != 1:
        return (f"{type_name(msg_type)} has {len(arrays)} top-level arrays of numbers "
                "(shared memory carries types with exactly one)")
    name, element = arrays[0]
    return Layout(name, np.dtype(_DTYPES[element]))


class _Chunk:
    """A received sample, alive as long as any array over it (views do not keep it)."""

    __slots__ = ("_transport", "sample")

    def __init__(self, sample: Any, transport: ShmTransport) -> None:
        self.sample = sample
        self._transport = transport
        transport.held += 1

    def __del__(self) -> None:
        self._transport.held -= 1
        self.sample.delete()


@functools.lru_cache(maxsize=64)
def _bytes_type(n: int) -> type[ctypes.Array[ctypes.c_uint8]]:
    """A ctypes byte array type of length ``n`` that can carry the chunk it maps."""
    return type(f"ShmBytes{n}", (ctypes.c_uint8 * n,), {})


class SharedArray(np.ndarray):
    """A received message's array over its shared chunk: a read-only numpy array, except
    that ``==`` and ``!=`` compare the whole sequence and give one bool, as the
    ``array.array`` of the same field from DDS does. A generated message's ``__eq__``
    tests ``if self.data != other.data``, which numpy's element-wise answer made raise.
    Indexing and slicing give plain numpy arrays (element-wise comparisons), as does
    ``np.asarray(msg.data)``."""

    def __eq__(self, other: object) -> bool:
        return _same(self, other)

    def __ne__(self, other: object) -> bool:
        return not _same(self, other)

    __hash__ = None

    def __getitem__(self, key: Any) -> Any:
        return np.ndarray.__getitem__(self.view(np.ndarray), key)


def _same(array: np.ndarray, other: object) -> bool:
    """Sequence equality of ``array`` and ``other`` (an ``array.array``, a numpy array)."""
    try:
        values = np.asarray(other)
    except Exception:
        return False
    return values.shape == array.shape and bool(np.array_equal(array.view(np.ndarray), values))


def _view(chunk: _Chunk, address: int, nbytes: int, dtype: np.dtype[Any]) -> SharedArray:
    raw = _bytes_type(nbytes).from_address(address)
    raw.chunk = chunk  # type: ignore[attr-defined]  # the array's base keeps the sample
    array = np.frombuffer(memoryview(raw), dtype=dtype).view(SharedArray)
    array.flags.writeable = False  # the mapping is read-only: a write would crash
    return array


class ShmTransport:
    """One process's (one container's) iceoryx2 node and its endpoints."""

    def __init__(self, *, domain_id: int, threshold_bytes: int,
                 executor: ConsecutiveExecutor) -> None:
        import iceoryx2 as iox2

        iox2.set_log_level(iox2.LogLevel.Error)  # not its "no config file" warning
        self.iox2 = iox2
        self.domain_id = domain_id
        self.threshold_bytes = threshold_bytes
        self.executor = executor
        self.held = 0  # chunks held by messages in this process
        # Creating a node removes what processes killed earlier left behind.
        self.node = (iox2.NodeBuilder.new()
                     .signal_handling_mode(iox2.SignalHandlingMode.Disabled)
                     .create(iox2.ServiceType.Ipc))
        self._services: dict[str, tuple[Any, Any]] = {}
        self._local_subs: dict[str, int] = {}  # service -> this process's shm subscribers
        self._lock = threading.Lock()
        self._watch: ShmWatch | None = None  # from the first subscription
        self._publishers: list[ShmPublisher] = []
        self._told: set[str] = set()  # topics whose fallback was logged

    def listen(self, sub: ShmSubscription) -> None:
        """Have ``sub``'s chunks wake the executor (:class:`ShmWatch`)."""
        with self._lock:
            if self._watch is None:
                self._watch = ShmWatch(self.iox2, self.executor)
        self._watch.add(sub)

    def drain(self) -> None:
        """Deliver what every subscription has waiting (executor thread): a lockstep
        intake round takes shared memory with DDS, so a chunk sent in a step is delivered
        at the next, as a DDS sample is (:mod:`efficient_comm.simtime`)."""
        watch = self._watch
        for sub in watch.subscriptions() if watch is not None else ():
            sub.drain()

    def unlisten(self, sub: ShmSubscription, listener: Any) -> None:
        """``sub`` is gone; its listener is deleted once the executor no longer waits on it."""
        if self._watch is not None:
            self._watch.remove(sub, listener)
        else:
            listener.delete()

    def service_name(self, topic: str, msg_type: type, qos: QoSProfile) -> str:
        reliability = "r" if qos.reliability == ReliabilityPolicy.RELIABLE else "b"
        return f"efficient_comm/{self.domain_id}/{reliability}/{type_name(msg_type)}{topic}"

    def services(self, name: str) -> tuple[Any, Any]:
        """The publish-subscribe and the event service of ``name`` (opened once)."""
        with self._lock:
            found = self._services.get(name)
            if found is None:
                iox2 = self.iox2
                service_name = iox2.ServiceName.new(name)
                pubsub = (self.node.service_builder(service_name)
                          .publish_subscribe(iox2.Slice[ctypes.c_uint8])
                          .user_header(_Header)
                          .max_publishers(_MAX_PUBLISHERS).max_subscribers(_MAX_SUBSCRIBERS)
                          .subscriber_max_buffer_size(_BUFFER)
                          .subscriber_max_borrowed_samples(_BORROWED)
                          .history_size(0).enable_safe_overflow(True)
                          .open_or_create())
                event = self.node.service_builder(service_name).event().open_or_create()
                found = self._services[name] = (pubsub, event)
            return found

    def local_subscribers(self, name: str) -> int:
        return self._local_subs.get(name, 0)

    def _count_local(self, name: str, change: int) -> None:
        with self._lock:
            self._local_subs[name] = self._local_subs.get(name, 0) + change

    def publisher(self, pub: LocalPublisher, logger: Logger) -> ShmPublisher | None:
        """The shared-memory side of ``pub`` (which has a DDS writer), or None with a log
        line saying why DDS alone carries the topic."""
        why = _unfit(pub.topic.msg_type, pub.qos)
        if isinstance(why, str):
            self._tell_once(logger, pub.topic_name, why)
            return None
        try:
            shm_pub = ShmPublisher(self, pub, why, logger)
        except Exception as exc:  # iceoryx2 refusing (e.g. /dev/shm full)
            logger.warning(f"topic {pub.topic_name}: no shared memory ({exc}); DDS carries it")
            return None
        with self._lock:
            self._publishers.append(shm_pub)
        return shm_pub

    def traffic(self) -> dict[str, ShmTraffic]:
        """Per topic this process publishes with the transport, what its publishers sent
        through shared memory and what they also wrote to DDS: a deployment checks that its
        large messages take shared memory (a split robot's camera image), a benchmark
        reports it."""
        with self._lock:
            publishers = list(self._publishers)
        out: dict[str, ShmTraffic] = {}
        for pub in publishers:
            was = out.get(pub.topic_name, ShmTraffic(0, 0))
            out[pub.topic_name] = ShmTraffic(shm_sends=was.shm_sends + pub.shm_sends,
                                             dds_writes=was.dds_writes + pub.dds_writes)
        return out

    def _tell_once(self, logger: Logger, topic: str, why: str) -> None:
        """Why DDS carries ``topic``, once per process: a robot's joint states have a
        publisher and several subscribers, one line says it for all of them."""
        with self._lock:
            if topic in self._told:
                return
            self._told.add(topic)
        _tell(logger, topic, why)

    def _forget(self, pub: ShmPublisher) -> None:
        with self._lock, contextlib.suppress(ValueError):
            self._publishers.remove(pub)

    def subscription(
        self, sub: LocalSubscription, logger: Logger, on_lost: Callable[[int], None] | None,
    ) -> ShmSubscription | None:
        why = _unfit(sub.topic.msg_type, sub.qos)
        if isinstance(why, str):
            self._tell_once(logger, sub.topic_name, why)
            return None
        try:
            return ShmSubscription(self, sub, why, logger, on_lost)
        except Exception as exc:
            logger.warning(f"topic {sub.topic_name}: no shared memory ({exc}); DDS carries it")
            return None

    def close(self) -> None:
        if self._watch is not None:
            self._watch.stop()
        with self._lock:
            self._services.clear()
        self.node = None  # iceoryx2 removes the node when its last port is gone


@dataclass(frozen=True)
class ShmTraffic:
    """What a topic's publishers in one process sent (:meth:`ShmTransport.traffic`)."""

    #: Messages whose array crossed through shared memory.
    shm_sends: int
    #: Messages also (or only) written to DDS: for plain peers, or below the threshold.
    dds_writes: int


def _tell(logger: Logger, topic: str, why: str) -> None:
    """The one line saying why DDS carries ``topic``: at debug level for the common case of
    a type with nothing large in it (a String, a Twist), so a robot's many small topics do
    not fill the log; at info level for what one might have expected to take shared memory."""
    line = f"topic {topic}: no shared memory ({why}); DDS carries it"
    if " 0 top-level arrays" in why:
        logger.debug(line)
    else:
        logger.info(line)


def _unfit(msg_type: type, qos: QoSProfile) -> Layout | str:
    """The type's layout, or why the endpoint does not fit: a type with nothing large in it
    says so first (told at debug level, even if latched: a robot has many latched states)."""
    fit = layout(msg_type)
    if is_transient_local(qos) and not isinstance(fit, str):
        return "transient local: DDS keeps the history for late joiners"
    return fit


class ShmPublisher:
    """Writes a publisher's large messages to shared memory (and DDS while a plain peer
    listens); called from :meth:`LocalPublisher.publish` instead of its DDS write."""

    def __init__(self, transport: ShmTransport, pub: LocalPublisher, fit: Layout,
                 logger: Logger) -> None:
        self._transport = transport
        self._pub = pub
        self._layout = fit
        self._logger = logger
        self.name = transport.service_name(pub.topic_name, pub.topic.msg_type, pub.qos)
        pubsub, event = transport.services(self.name)
        iox2 = transport.iox2
        self._pubsub = pubsub
        self._port = (pubsub.publisher_builder()
                      .initial_max_slice_len(_INITIAL_SLICE)
                      .allocation_strategy(iox2.AllocationStrategy.PowerOfTwo)
                      .create())
        self._notifier = event.notifier_builder().create()
        self._id = secrets.randbits(63)
        self._pid = os.getpid()
        self._seq = itertools.count(1)
        self._dds_seq = 0  # DDS's sequence number of our last DDS write (it counts from 1)
        self._rest = _Rest(pub.topic.msg_type, fit.field)
        self.topic_name = pub.topic_name
        self.shm_sends = 0  # messages whose array went through shared memory
        self._warned = False
        self._subscribers = 0  # what the port was last connected to

    def publish(self, msg: Any) -> None:
        pub = self._pub
        dds = pub.dds
        array = getattr(msg, self._layout.field)
        data = memoryview(array).cast("B") if not isinstance(array, list) else None
        subscribers = self._pubsub.dynamic_config.number_of_subscribers
        if subscribers != self._subscribers:  # connect new readers before this send
            self._subscribers = subscribers
            self._port.update_connections()
        remote = subscribers - self._transport.local_subscribers(self.name)
        if data is None or data.nbytes < self._transport.threshold_bytes or remote <= 0:
            if dds is not None and pub.dds_matched:
                self._dds_seq += 1  # counted first: a Ctrl-C between the two loses no count
                dds.publish(msg)
            return
        try:
            self._send(msg, data, write_dds=dds is not None and pub.dds_matched > remote)
        except Exception as exc:  # a loan refused: the message still goes over DDS
            if not self._warned:
                self._warned = True
                self._logger.warning(
                    f"topic {pub.topic_name}: shared memory refused a message of "
                    f"{data.nbytes} bytes ({exc}); DDS carries such messages")
            if dds is not None and pub.dds_matched:
                self._dds_seq += 1
                dds.publish(msg)

    def _send(self, msg: Any, data: memoryview, *, write_dds: bool) -> None:
        meta = self._rest.dump(msg)
        offset = -(-len(meta) // _ALIGN) * _ALIGN
        sample = self._port.loan_slice_uninit(offset + data.nbytes)
        base = sample.payload_ptr
        ctypes.memmove(base, meta, len(meta))
        target = np.frombuffer(memoryview(_bytes_type(data.nbytes).from_address(base + offset)),
                               dtype=np.uint8)
        target[:] = np.frombuffer(data, dtype=np.uint8)  # the one copy
        header = _Header.from_address(sample.user_header_ptr)
        header.publisher, header.pid, header.seq = self._id, self._pid, next(self._seq)
        header.meta_len, header.array_offset = len(meta), offset
        header.dds_seq = header.dds_t0 = header.dds_t1 = 0
        header.sent = time.time_ns()
        if write_dds:  # announced before it is written, so no reader can get it first
            header.dds_seq = self._dds_seq + 1
            header.dds_t0 = header.sent
            header.dds_t1 = header.dds_t0 + _DDS_WINDOW_NS
        sample.assume_init().send()
        self.shm_sends += 1
        self._notifier.notify()
        if write_dds:
            self._dds_seq += 1
            self._pub.dds.publish(msg)

    @property
    def remote_readers(self) -> int:
        """Shared-memory subscribers of this topic in other processes (connected now)."""
        subscribers = self._pubsub.dynamic_config.number_of_subscribers
        return int(subscribers - self._transport.local_subscribers(self.name))

    @property
    def dds_writes(self) -> int:
        """Messages this publisher also wrote to DDS (for plain peers, or small ones): 0
        while shared memory serves every reader."""
        return self._dds_seq

    def close(self) -> None:
        self._transport._forget(self)
        self._notifier.delete()
        self._port.delete()


class ShmSubscription:
    """Receives a subscription's large messages from shared memory and keeps the DDS
    copies of them out (see the module docstring)."""

    def __init__(self, transport: ShmTransport, sub: LocalSubscription, fit: Layout,
                 logger: Logger, on_lost: Callable[[int], None] | None) -> None:
        self._transport = transport
        self._sub = sub
        self._remote = (sub,)
        self._layout = fit
        self._logger = logger
        self._on_lost = on_lost
        self._msg_type = sub.topic.msg_type
        self._rest = _Rest(self._msg_type, fit.field)
        self._warned = False
        self.name = transport.service_name(sub.topic_name, self._msg_type, sub.qos)
        pubsub, event = transport.services(self.name)
        depth = sub.queue.maxlen or _BUFFER
        self._port = pubsub.subscriber_builder().buffer_size(min(depth, _BUFFER)).create()
        transport._count_local(self.name, 1)
        self.listener = event.listener_builder().create()
        self._last: dict[int, int] = {}  # publisher -> last sequence number
        self._expected: deque[tuple[int, int, int]] = deque(maxlen=_REMEMBER)  # DDS copies
        self._delivered: deque[tuple[int, int]] = deque(maxlen=_REMEMBER)  # from DDS
        # Chunks received, not yet delivered: (send time, message), in send order.
        self._pending: deque[tuple[int, Any]] = deque()
        self._pid = os.getpid()
        self._running = True
        transport.listen(self)
        transport.executor.post(self.drain)  # a first receive connects the port

    def drain(self) -> None:
        """Deliver every message waiting, from DDS and shared memory, in the order they
        were sent (executor thread; what :class:`ShmWatch` posts when a chunk came)."""
        reader = self._sub.dds
        if reader is not None:
            take_samples(reader)  # each one through from_dds, chunks sent before it first
        self._receive()
        self._deliver_until(None)

    def _receive(self) -> None:
        while self._running:
            sample = self._port.receive()
            if sample is None:
                return
            sent = _Header.from_address(sample.user_header_ptr).sent
            msg = self._decode(sample)
            if msg is not None:
                self._pending.append((sent, msg))

    def _deliver_until(self, stamp: int | None) -> None:
        """Deliver the chunks sent before ``stamp`` (wall-clock ns; None: all)."""
        pending = self._pending
        while pending and (stamp is None or pending[0][0] <= stamp):
            self._transport.executor.receive_remote(self._remote, pending.popleft()[1])

    def _decode(self, sample: Any) -> Any | None:
        header = _Header.from_address(sample.user_header_ptr)
        if header.pid == self._pid:
            sample.delete()  # our own process: the bus delivered it by reference
            return None
        last = self._last.get(header.publisher)
        if last is not None and header.seq > last + 1:
            self._lost(header.seq - last - 1)
        self._last[header.publisher] = header.seq
        if header.dds_seq:
            copy = (header.dds_seq, header.dds_t0, header.dds_t1)
            if any(seq == copy[0] and copy[1] <= stamp <= copy[2]
                   for seq, stamp in self._delivered):
                sample.delete()  # DDS was first: delivered already
                return None
            self._expected.append(copy)
        base = sample.payload_ptr
        nbytes = sample.header.number_of_elements - header.array_offset
        transport = self._transport
        chunk = _Chunk(sample, transport)
        array = _view(chunk, base + header.array_offset, nbytes, self._layout.dtype)
        if transport.held >= _BORROWED:
            # The process holds as many chunks as it may borrow: copy this one out, so that
            # the next receive succeeds (a component keeping every image, say).
            array = array.copy()
            array.flags.writeable = False
        del chunk
        try:
            return self._rest.load(ctypes.string_at(base, header.meta_len), array)
        except Exception as exc:  # not what our publisher writes: told once, dropped
            if not self._warned:
                self._warned = True
                self._logger.warning(f"topic {self._sub.topic_name}: a shared-memory chunk "
                                     f"did not decode ({exc!r}); dropped")
            return None

    def _lost(self, count: int) -> None:
        self._sub.stats.dropped += count
        if self._on_lost is not None:
            self._on_lost(count)

    def from_dds(self, msg: Any, info: Any) -> None:
        """The DDS reader's callback: deliver unless shared memory carries this message.

        Shared memory is received first, so that a chunk announcing this very sample's DDS
        copy is seen before the sample; of its chunks, those sent before this sample was
        written (its source timestamp, the same machine's clock) are delivered before it,
        the later ones after it: each subscriber gets a publisher's messages in the order
        they were published, whichever path each took.
        """
        seq = info.get("publication_sequence_number", 0) if isinstance(info, dict) else 0
        stamp = info.get("source_timestamp", 0) if isinstance(info, dict) else 0
        self._receive()
        self._deliver_until(stamp)
        for copy in self._expected:
            if copy[0] == seq and copy[1] <= stamp <= copy[2]:
                self._expected.remove(copy)
                return
        self._delivered.append((seq, stamp))
        self._transport.executor.receive_remote(self._remote, msg)

    def close(self) -> None:
        self._running = False
        self._transport.unlisten(self, self.listener)
        self._transport._count_local(self.name, -1)
        self._port.delete()


class ShmWatch:
    """Wakes the executor for shared-memory chunks: a thread blocks in an iceoryx2
    ``WaitSet`` over every subscription's listener and, for each that fired, posts its
    :meth:`ShmSubscription.drain` to the executor (:meth:`ConsecutiveExecutor.post`, which
    wakes the executor's DDS wait through its guard condition). The executor's thread waits
    on DDS as it does without the transport, and runs every callback.

    rclpy's wait set takes rcl entities only, and iceoryx2 gives Python no file descriptor
    for a listener, so one side needs a thread. It used to be the other side: the executor's
    thread blocked in the WaitSet (one wake-up a chunk) and a thread relayed DDS to it. But a
    robot takes many small DDS messages for each large one (a 100 Hz IMU, joint states,
    the team link, beside a 30 Hz camera): the relay woke for every DDS sample, 15 % of a
    core in a team match's robot, every DDS message paid a second wake-up, and the walking
    robot fell more often (SHM.md, "The wake-up"). Now the second wake-up is the chunk's.
    """

    def __init__(self, iox2: Any, executor: ConsecutiveExecutor) -> None:
        self._iox2 = iox2
        self._executor = executor
        self._fd = os.eventfd(0, os.EFD_NONBLOCK | os.EFD_CLOEXEC)  # rebuild or stop
        # Subscriptions come and go in any thread (under _lock); the WaitSet is the watch
        # thread's alone, rebuilt there before its next wait (_dirty), and a gone
        # subscription's listener is deleted only then, once no WaitSet holds it (_retired).
        self._lock = threading.Lock()
        self._subs: list[ShmSubscription] = []
        self._retired: list[Any] = []
        self._dirty = True
        self._running = True
        self._thread = threading.Thread(target=self._watch, daemon=True, name="shm watch")
        self._thread.start()

    def add(self, sub: ShmSubscription) -> None:
        with self._lock:
            self._subs.append(sub)
            self._dirty = True
        self._poke()

    def remove(self, sub: ShmSubscription, listener: Any) -> None:
        """``sub`` is gone; its ``listener`` is deleted once no WaitSet holds it."""
        with self._lock:
            if sub in self._subs:
                self._subs.remove(sub)
            running = self._running
            if running:
                self._retired.append(listener)
                self._dirty = True
        if running:
            self._poke()
        else:  # no WaitSet left
            with contextlib.suppress(Exception):
                listener.delete()

    def subscriptions(self) -> list[ShmSubscription]:
        with self._lock:
            return list(self._subs)

    def stop(self) -> None:
        """End the thread (the transport closes); every listener it held is deleted."""
        with self._lock:
            if not self._running:
                return
            self._running = False
        self._poke()
        self._thread.join(timeout=5.0)

    def _poke(self) -> None:
        with contextlib.suppress(OSError):  # closed
            os.eventfd_write(self._fd, 1)

    def __del__(self) -> None:
        os.close(self._fd)  # not in stop(): a late _poke() must not write to a reused fd

    def _watch(self) -> None:
        iox2 = self._iox2
        guards: list[tuple[Any, ShmSubscription]] = []
        waitset: Any = None
        fd_guard: Any = None
        timeout = iox2.Duration.from_millis(_WAKE_MS)
        try:
            while self._running:
                if self._dirty:
                    with self._lock:
                        subs, retired, self._retired = list(self._subs), self._retired, []
                        self._dirty = False
                    guards, fd_guard, waitset = [], None, None  # the old WaitSet's first
                    for listener in retired:
                        with contextlib.suppress(Exception):
                            listener.delete()
                    waitset = (iox2.WaitSetBuilder.new()
                               .signal_handling_mode(iox2.SignalHandlingMode.Disabled)
                               .create(iox2.ServiceType.Ipc))
                    fd_guard = waitset.attach_notification_fd(
                        iox2.FileDescriptor.non_owning_new(self._fd))
                    guards = [(waitset.attach_notification(sub.listener), sub) for sub in subs]
                fired, _ = waitset.wait_and_process_with_timeout(timeout)
                with contextlib.suppress(BlockingIOError):
                    os.eventfd_read(self._fd)
                for guard, sub in guards:
                    if any(event.has_event_from(guard) for event in fired):
                        sub.listener.try_wait()  # consumed, or the WaitSet wakes at once again
                        self._executor.post(sub.drain)
        finally:
            del guards, fd_guard, waitset  # the WaitSet before the listeners it holds
            with self._lock:
                retired, self._retired = self._retired, []
            for listener in retired:
                with contextlib.suppress(Exception):
                    listener.delete()
