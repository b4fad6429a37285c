"""TCPROS, the ROS 1 data connection: headers, frames, and the two ends the bridge needs.

A connection starts with a header (length-prefixed ``key=value`` fields) from each side,
then carries length-prefixed messages from publisher to subscriber. Everything read from a
peer is checked against limits before anything is allocated for it.

* :class:`OutboundConnection`: the bridge publishes to one ROS 1 subscriber. Sends go
  straight to the socket when it takes them (no thread hand-off on the fast path), else a
  writer thread finishes them. A peer that stops reading is treated as rospy treats it:
  its queue keeps the newest ``queue_size`` messages (older ones dropped and counted) and
  it gets data again as soon as it reads; only a peer that is gone is dropped.
* :class:`InboundLink`: the bridge subscribes to one ROS 1 publisher, reconnecting while the
  master still lists it.
"""

from __future__ import annotations

import collections
import contextlib
import select
import socket
import struct
import threading
from collections.abc import Callable, Mapping

from ..._log import RateLimitedLog
from ...errors import LinkError, OversizeError, ProtocolError

MAX_HEADER_BYTES = 1 << 16
_U32 = struct.Struct("<I")


def encode_header(fields: Mapping[str, str]) -> bytes:
    parts = []
    for key, value in fields.items():
        item = f"{key}={value}".encode()
        parts.append(_U32.pack(len(item)) + item)
    body = b"".join(parts)
    return _U32.pack(len(body)) + body


def decode_header(body: bytes) -> dict[str, str]:
    """Fields of a header body; raises ProtocolError on anything malformed."""
    fields: dict[str, str] = {}
    off = 0
    while off < len(body):
        if off + 4 > len(body):
            raise ProtocolError("malformed TCPROS header: truncated field length")
        (n,) = _U32.unpack_from(body, off)
        off += 4
        if off + n > len(body):
            raise ProtocolError(f"malformed TCPROS header: field of {n} bytes overruns the header")
        item = body[off : off + n]
        off += n
        key, sep, value = item.partition(b"=")
        if not sep or not key:
            raise ProtocolError(f"malformed TCPROS header: field without 'key=': {item[:40]!r}")
        try:
            fields[key.decode()] = value.decode()
        except UnicodeDecodeError:
            raise ProtocolError("malformed TCPROS header: field is not UTF-8") from None
    return fields


def recv_exact(sock: socket.socket, n: int) -> bytes:
    buf = bytearray(n)
    view = memoryview(buf)
    got = 0
    while got < n:
        k = sock.recv_into(view[got:], n - got)
        if k == 0:
            raise LinkError(f"connection closed by peer after {got} of {n} bytes")
        got += k
    return bytes(buf)


def read_header(sock: socket.socket) -> dict[str, str]:
    (n,) = _U32.unpack(recv_exact(sock, 4))
    if n > MAX_HEADER_BYTES:
        raise ProtocolError(f"malformed TCPROS header: length {n} > {MAX_HEADER_BYTES}")
    return decode_header(recv_exact(sock, n))


def read_frame(sock: socket.socket, max_bytes: int) -> bytes:
    (n,) = _U32.unpack(recv_exact(sock, 4))
    if n > max_bytes:
        raise OversizeError(f"message of {n} bytes exceeds the limit of {max_bytes} bytes")
    return recv_exact(sock, n)


def frame(payload: bytes) -> bytes:
    return _U32.pack(len(payload)) + payload


Counter = Callable[[str, int], None]  # (reason, messages) for undelivered messages


class OutboundConnection:
    """One ROS 1 subscriber of a topic the bridge publishes."""

    #: How often the writer thread, waiting for a peer that does not read, checks whether
    #: the connection was closed meanwhile.
    POLL_S = 0.5

    def __init__(
        self,
        sock: socket.socket,
        *,
        peer: str,
        topic: str,
        queue_size: int,
        on_undelivered: Counter,
        on_closed: Callable[[OutboundConnection], None],
        log: RateLimitedLog,
    ) -> None:
        self.peer = peer
        self.topic = topic
        self.sock = sock
        sock.setblocking(False)
        self._queue: collections.deque[memoryview] = collections.deque()
        self._head_started = False  # part of the queue's first message is on the wire
        self._queue_size = queue_size
        self._undelivered = on_undelivered
        self._on_closed = on_closed
        self._log = log
        self._cond = threading.Condition()
        self._closed = False
        self._dropping = 0  # messages dropped since the peer last kept up
        self.sent = 0
        self.thread = threading.Thread(target=self._writer, name=f"tcpros-out {topic}", daemon=True)
        self.thread.start()

    @property
    def closed(self) -> bool:
        return self._closed

    def send(self, data: bytes) -> None:
        """Queue one framed message; never blocks the caller."""
        with self._cond:
            if self._closed:
                self._undelivered("connection_closed", 1)
                return
            if not self._queue and _peer_closed(self.sock):
                self._close_locked("peer closed the connection", pending=1)
                return
            if self._queue:
                if len(self._queue) >= self._queue_size:
                    self._drop_oldest_locked()
                self._queue.append(memoryview(data))
                self._cond.notify()
                return
            try:
                n = self.sock.send(data)
            except BlockingIOError:
                n = 0
            except OSError as exc:
                self._close_locked(f"send failed: {exc}", pending=1)
                return
            if n < len(data):
                self._queue.append(memoryview(data)[n:])
                self._head_started = n > 0
                self._cond.notify()
            else:
                self.sent += 1

    def _drop_oldest_locked(self) -> None:
        """The oldest whole message makes room (one already partly sent must be finished,
        or the stream would be corrupt)."""
        if self._head_started and len(self._queue) > 1:
            del self._queue[1]
        else:
            self._queue.popleft()
            self._head_started = False
        self._undelivered("queue_full", 1)
        if not self._dropping:
            self._log.warning(
                f"ROS 1 subscriber {self.peer} on {self.topic} is not keeping up: keeping its "
                f"newest {self._queue_size} message(s), dropping older ones"
            )
        self._dropping += 1

    def _writer(self) -> None:
        while True:
            with self._cond:
                while not self._queue and not self._closed:
                    self._cond.wait()
                if self._closed:
                    return
                head = self._queue[0]
            try:
                _, writable, _ = select.select([], [self.sock], [], self.POLL_S)
            except (OSError, ValueError):
                writable = []
            with self._cond:
                if self._is_closed():  # closed by send() or close() meanwhile
                    return
                if not writable or self._queue[0] is not head:
                    continue  # not reading (yet), or the head was dropped meanwhile
                try:
                    n = self.sock.send(head)
                except BlockingIOError:
                    continue
                except OSError as exc:
                    self._close_locked(f"send failed: {exc}", pending=0)
                    return
                if n == len(head):
                    self._queue.popleft()
                    self._head_started = False
                    self.sent += 1
                    if not self._queue and self._dropping:
                        self._log.info(
                            f"ROS 1 subscriber {self.peer} on {self.topic} caught up; "
                            f"{self._dropping} message(s) were dropped while it was not reading"
                        )
                        self._dropping = 0
                else:
                    self._queue[0] = head[n:]
                    self._head_started = True

    def _is_closed(self) -> bool:
        return self._closed

    def _close_locked(self, reason: str, *, pending: int) -> None:
        """The peer failed: drop the connection, count what it did not get, tell the owner."""
        lost = self._shut_locked(pending=pending, counted_as="connection_dropped")
        self._log.warning(
            f"dropping TCPROS connection to {self.peer} on {self.topic}: {reason}; "
            f"{lost} message(s) undelivered"
        )
        threading.Thread(target=self._on_closed, args=(self,), daemon=True).start()

    def close(self) -> None:
        """The bridge is closing: queued messages are counted as ``connection_closed``."""
        with self._cond:
            if not self._closed:
                self._shut_locked(pending=0, counted_as="connection_closed")

    def _shut_locked(self, *, pending: int, counted_as: str) -> int:
        lost = pending + len(self._queue)
        self._queue.clear()
        self._closed = True
        self._cond.notify_all()
        with contextlib.suppress(OSError):
            self.sock.close()
        if lost:
            self._undelivered(counted_as, lost)
        return lost


def _peer_closed(sock: socket.socket) -> bool:
    """Subscribers never send after the header, so a readable EOF means they are gone; checking
    before each send counts a message for a dead peer instead of losing it in the kernel."""
    try:
        return sock.recv(1, socket.MSG_PEEK | socket.MSG_DONTWAIT) == b""
    except BlockingIOError:
        return False
    except OSError:
        return True


class InboundLink:
    """Subscribes to one ROS 1 publisher; reconnects until :meth:`stop`.

    ``connect`` returns (host, port) from the publisher's requestTopic, or raises.
    ``on_header`` sees the publisher's header (to learn the type) and may raise to refuse;
    ``on_frame`` gets every message payload.
    """

    def __init__(
        self,
        *,
        publisher_uri: str,
        topic: str,
        request: Callable[[], tuple[str, int]],
        header: Mapping[str, str],
        max_bytes: int,
        on_header: Callable[[dict[str, str]], None],
        on_frame: Callable[[bytes], None],
        on_oversize: Callable[[], None],
        log: RateLimitedLog,
        retry_s: float = 0.5,
    ) -> None:
        self.publisher_uri = publisher_uri
        self.topic = topic
        self._request = request
        self._header = encode_header(header)
        self._max_bytes = max_bytes
        self._on_header = on_header
        self._on_frame = on_frame
        self._on_oversize = on_oversize
        self._log = log
        self._retry_s = retry_s
        self._stop = threading.Event()
        self._sock: socket.socket | None = None
        self.connected = threading.Event()
        self.thread = threading.Thread(target=self._run, name=f"tcpros-in {topic}", daemon=True)
        self.thread.start()

    def stop(self) -> None:
        self._stop.set()
        sock = self._sock
        if sock is not None:
            with contextlib.suppress(OSError):
                sock.shutdown(socket.SHUT_RDWR)

    def _run(self) -> None:
        while not self._stop.is_set():
            try:
                self._session()
            except OversizeError as exc:
                self._on_oversize()
                self._log.warning(
                    f"dropping TCPROS connection from {self.publisher_uri} on {self.topic}: "
                    f"{exc}; reconnecting"
                )
            except (OSError, LinkError, ProtocolError) as exc:
                if not self._stop.is_set():
                    self._log.warning(
                        f"dropping TCPROS connection from {self.publisher_uri} on {self.topic}: "
                        f"{exc}; reconnecting"
                    )
            except Exception as exc:  # a translator or callback bug must not kill the link
                self._log.error(f"TCPROS link {self.publisher_uri} on {self.topic}: {exc!r}")
            finally:
                self.connected.clear()
                sock, self._sock = self._sock, None
                if sock is not None:
                    sock.close()
            self._stop.wait(self._retry_s)

    def _session(self) -> None:
        host, port = self._request()
        sock = socket.create_connection((host, port), timeout=5.0)
        self._sock = sock
        if self._stop.is_set():
            return
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        sock.sendall(self._header)
        reply = read_header(sock)
        if "error" in reply:
            raise LinkError(f"publisher refused: {reply['error']}")
        self._on_header(reply)
        sock.settimeout(None)
        self.connected.set()
        while not self._stop.is_set():
            payload = read_frame(sock, self._max_bytes)
            self._on_frame(payload)
