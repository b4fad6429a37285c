"""Serve a :class:`~humanoid_sim.dynamixel.bus.Bus` on a pseudo-terminal.

The driver opens :attr:`PtyBus.port` (e.g. ``/dev/pts/5``) where it would open
/dev/ttyUSB0; dynamixel-sdk's PortHandler runs unchanged. The emulator reads the master
side in a thread of its own and answers like the servos on the bus; malformed bytes are
skipped until the next header, a packet cut short is dropped after
:data:`PACKET_TIMEOUT_S`, and nothing a driver sends can stop the thread.

A write the driver does not wait on (sync write has no reply) reaches the emulator some
time later: the kernel moves pty data through a work queue. A lockstep simulation must not
step physics before such a write is applied, so :meth:`PtyBus.sync` sends a marker through
the same slave-to-master queue and waits until the emulator has reached it: everything
written before it has then been handled, whatever the machine's load.

A driver in the simulator's own process on a manual clock (lockstep) need not go through
the kernel at all: :meth:`PtyBus.direct_port` is dynamixel-sdk's PortHandler with the
emulator at the other end of the wire, answering each write in the writer's thread before
the write returns (:class:`DirectPortHandler`). The SDK's packet building, CRCs, parsing
and timeouts are unchanged, and the bytes either way are those the pty would carry, line
noise included; only the device file and the emulator's thread are left out, which cost a
lockstep robot a fifth of its time (two pty round trips and two thread hand-overs every
10 ms step) and carried nothing a test asserts on: the drivers of real-time runs and of
the match's robot processes still open the pty.
"""

from __future__ import annotations

import dataclasses
import itertools
import os
import random
import select
import threading
import time
import tty
from contextlib import suppress

from dynamixel_sdk import PortHandler

from efficient_comm import Closing

from ..errors import SimConfigError
from .bus import Bus
from .protocol import BROADCAST_ID, Packet, Parser, encode

#: Not a Protocol 2.0 instruction: the emulator's own in-band marker for :meth:`PtyBus.sync`
#: (a real bus would ignore it: broadcast packets of unknown instructions get no status).
SYNC_INSTRUCTION = 0x7F
#: A packet not complete this long after its first bytes is dropped (long enough that a
#: loaded machine never splits one write of the driver's by that much).
PACKET_TIMEOUT_S = 0.5


def make_port_link(port: str, link: str) -> None:
    """Point ``link`` at ``port`` (a pty), where a driver in another process opens it. Only
    a symlink (a stale one from an earlier run) is replaced, never a file or device someone
    else owns; SimConfigError if it cannot be made."""
    if os.path.lexists(link) and not os.path.islink(link):
        raise SimConfigError(f"port_link {link!r} exists and is not a symlink")
    staging = f"{link}.{os.getpid()}.new"
    try:
        os.symlink(port, staging)
        os.replace(staging, link)  # atomic: a driver never sees the link missing
    except OSError as exc:
        with suppress(OSError):
            os.unlink(staging)
        raise SimConfigError(f"cannot make port_link {link!r}: {exc}") from exc


def remove_port_link(port: str, link: str) -> None:
    """Remove ``link`` if it still points at ``port`` (a newer simulator may have taken the
    path)."""
    with suppress(OSError):
        if os.readlink(link) == port:
            os.unlink(link)


class PtyBus(Closing):
    """A context manager: the bus answers on a pty until closed."""

    def __init__(self, bus: Bus, *, corrupt: float = 0.0, seed: int = 0,
                 packet_timeout_s: float | None = PACKET_TIMEOUT_S,
                 lock: threading.Lock | None = None) -> None:
        """``corrupt``: line noise, the share of packets either way with one bit flipped.

        ``packet_timeout_s``: drop a packet not complete this long (wall time) after its
        first bytes; None never does (lockstep: a loaded machine may split a write by any
        time, and the run must not change with the load).

        ``lock``: the lock the emulator holds while it handles a packet (default: one of its
        own). Robots of one world share theirs, since every bus reads the world that the
        simulator steps under that lock.
        """
        self.bus = bus
        self.packet_timeout_s = packet_timeout_s
        self.corrupt = corrupt
        self._rng = random.Random(seed)
        self._master, self._slave = os.openpty()
        try:
            tty.setraw(self._master)
            tty.setraw(self._slave)
            # Replies nobody reads must not block the emulator: they are dropped and counted.
            os.set_blocking(self._master, False)
            self.port = os.ttyname(self._slave)
        except BaseException:
            os.close(self._master)
            os.close(self._slave)
            raise
        self.errors: list[BaseException] = []
        #: Bytes of packets that did not complete within :data:`PACKET_TIMEOUT_S`.
        self.discarded_bytes = 0
        #: Replies, or their tails, that did not fit into the pty (nobody was reading).
        self.dropped_replies = 0
        #: Bytes of replies written to the pty (what a reader on the port can receive).
        self.sent_bytes = 0
        self._closed = False
        self._lock = lock or threading.Lock()
        self._synced = threading.Condition()
        self._sync_sent = itertools.count(1)
        self._sync_seen = 0
        self._serving = True  # False once the thread has ended: no sync can succeed then
        self._stop = threading.Event()
        self._direct_ports = 0  # open direct ports (sync has nothing to wait for then)
        self._thread = threading.Thread(target=self._serve, name="dynamixel-bus", daemon=True)
        self._thread.start()

    @property
    def closed(self) -> bool:
        return self._closed

    @property
    def thread_id(self) -> int | None:
        """The emulator thread's native id (its CPU is the bus emulation's cost)."""
        return self._thread.native_id

    @property
    def lock(self) -> threading.Lock:
        """Hold it to change servos or step the plant while the bus may be answering."""
        return self._lock

    def _serve(self) -> None:
        try:
            self._serve_packets()
        finally:
            with self._synced:  # whoever waits for a sync learns that none will come
                self._serving = False
                self._synced.notify_all()

    def _serve_packets(self) -> None:
        parser = Parser()
        partial_since: float | None = None
        while not self._stop.is_set():
            ready, _, _ = select.select([self._master], [], [], 0.05)
            # A servo drops a packet that does not complete in time rather than wait for
            # the rest forever: a corrupted length must not swallow the packets after it.
            if not parser.pending:
                partial_since = None
            elif partial_since is None:
                partial_since = time.monotonic()
            elif (self.packet_timeout_s is not None
                  and time.monotonic() - partial_since > self.packet_timeout_s):
                self.discarded_bytes += parser.discard()
                partial_since = None
            if not ready:
                continue
            try:
                data = os.read(self._master, 4096)
            except OSError:
                return
            for packet in parser.feed(data):
                if packet.dxl_id == BROADCAST_ID and packet.instruction == SYNC_INSTRUCTION:
                    with self._synced:
                        self._sync_seen = int.from_bytes(packet.params, "little")
                        self._synced.notify_all()
                    continue
                reply = self.answer(packet)
                if reply:
                    self._send(reply)

    def answer(self, packet: Packet) -> bytes:
        """The bytes the servos answer ``packet`` with, line noise applied both ways (in
        bus order, so a lockstep run stays exact); errors are kept in :attr:`errors`, never
        raised: one packet must not stop the bus."""
        if self._noisy():  # a flipped bit on the way in: the servos' CRC check fails
            packet = dataclasses.replace(packet, crc_ok=False)
        try:
            with self._lock:
                reply = self.bus.handle(packet)
        except Exception as exc:
            self.errors.append(exc)
            return b""
        if reply and self._noisy():
            noisy = bytearray(reply)
            noisy[self._rng.randrange(len(noisy))] ^= 1 << self._rng.randrange(8)
            reply = bytes(noisy)
        return reply

    def sync(self) -> bool:
        """Wait until every byte written to the port before this call has been handled.

        However long that takes: a wall-clock limit would make a lockstep run depend on the
        machine's load (beside busy processes the emulator's thread may wait seconds for
        the CPU). False only if the emulator has stopped (closed, or its pty failed).

        While a :meth:`direct_port` is open nothing is waited for: the lockstep driver's
        writes were answered before they returned, and the pty carries no driver's.
        """
        if self._direct_ports:
            return not self._closed
        number = next(self._sync_sent)
        with self._synced:
            if self._closed or not self._serving:
                return False
        try:
            os.write(self._slave,
                     encode(BROADCAST_ID, SYNC_INSTRUCTION, number.to_bytes(8, "little")))
        except OSError:  # closed meanwhile
            return False
        with self._synced:
            self._synced.wait_for(lambda: self._sync_seen >= number or not self._serving)
            return self._sync_seen >= number

    def _noisy(self) -> bool:
        """Whether line noise hits this packet (drawn in bus order: lockstep stays exact)."""
        return bool(self.corrupt) and self._rng.random() < self.corrupt

    def _send(self, reply: bytes) -> None:
        try:
            written = os.write(self._master, reply)
        except BlockingIOError:
            written = 0
        self.sent_bytes += written
        if written < len(reply):
            self.dropped_replies += 1

    def direct_port(self, port_name: str) -> PortHandler:
        """A dynamixel-sdk port wired straight to this bus, for a driver in this process on
        a manual clock (see :class:`DirectPortHandler`); ``port_name`` is what the driver
        was told to open (it is only reported)."""
        return DirectPortHandler(port_name, self)

    def close(self) -> None:
        """Stop answering and close the pty; a second call does nothing."""
        if self._closed:
            return
        self._closed = True
        self._stop.set()
        self._thread.join(timeout=2)
        os.close(self._master)
        os.close(self._slave)


class DirectPortHandler(PortHandler):  # type: ignore[misc]  # the SDK is untyped
    """dynamixel-sdk's PortHandler with the emulator at the other end of the wire, in the
    writer's thread: a write is answered (:meth:`PtyBus.answer`) before it returns, and the
    answer waits here for the SDK to read it.

    So a reply has timed out exactly when it can no longer come: every byte the servos sent
    has been read and the SDK still lacks bytes (a silent servo, a garbled length). That is
    what a real bus's timeout means, without the wall clock, so a lockstep run is the same
    at any load; and no write is ever on its way when the driver's cycle returns, so the
    servos' state is the same whenever someone looks. ``clearPort`` (the SDK's discarding
    of stale input before each request) discards every byte the servos sent so far.
    """

    def __init__(self, port_name: str, bus: PtyBus) -> None:
        super().__init__(port_name)
        self.is_open: bool = False
        self._bus = bus
        self._parser = Parser()
        self._input = bytearray()  # what the servos sent that the SDK has not read yet

    def setupPort(self, cflag_baud: int) -> bool:  # noqa: N802 (the SDK's name)
        if not self.is_open:
            self._bus._direct_ports += 1
        self.is_open = True
        self.tx_time_per_byte = (1000.0 / self.baudrate) * 10.0
        self._input.clear()
        return True

    def closePort(self) -> None:  # noqa: N802
        if self.is_open:
            self._bus._direct_ports -= 1
        self.is_open = False

    def clearPort(self) -> None:  # noqa: N802
        self._input.clear()

    def getBytesAvailable(self) -> int:  # noqa: N802
        return len(self._input)

    def readPort(self, length: int) -> bytes:  # noqa: N802
        data = bytes(self._input[:length])
        del self._input[:length]
        return data

    def writePort(self, packet: list[int]) -> int:  # noqa: N802
        if not self.is_open or self._bus.closed:
            return 0  # as a port whose device is gone: the SDK reports a TX failure
        for received in self._parser.feed(bytes(packet)):
            self._input += self._bus.answer(received)
        return len(packet)

    def isPacketTimeout(self) -> bool:  # noqa: N802
        if self._input:
            return False  # bytes to read first: the SDK reads them and asks again
        self.packet_timeout = 0
        return True
