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
written before it has then been handled, whatever the machine's load. The lockstep port
(:class:`IdlePortHandler`) does so after every write, so no packet is still on its way
when the driver's cycle returns: what the emulator has counted, and the servos' state,
are then the same whenever someone looks.
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
from .protocol import BROADCAST_ID, Parser, encode

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
                if self._noisy():  # a flipped bit on the way in: the servos' CRC check fails
                    packet = dataclasses.replace(packet, crc_ok=False)
                try:
                    with self._lock:
                        reply = self.bus.handle(packet)
                except Exception as exc:  # never let one packet stop the bus
                    self.errors.append(exc)
                    continue
                if reply:
                    if self._noisy():
                        noisy = bytearray(reply)
                        noisy[self._rng.randrange(len(noisy))] ^= 1 << self._rng.randrange(8)
                        reply = bytes(noisy)
                    self._send(reply)

    def sync(self) -> bool:
        """Wait until every byte written to the port before this call has been handled.

        However long that takes: a wall-clock limit would make a lockstep run depend on the
        machine's load (beside busy processes the emulator's thread may wait seconds for
        the CPU). False only if the emulator has stopped (closed, or its pty failed).
        """
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

    def idle_port(self, port_name: str) -> PortHandler:
        """A dynamixel-sdk port on this bus whose reply timeout is the emulator being done,
        not the wall clock: for lockstep runs (see :class:`IdlePortHandler`)."""
        return IdlePortHandler(port_name, self)

    def close(self) -> None:
        """Stop answering and close the pty; a second call does nothing."""
        if self._closed:
            return
        self._closed = True
        self._stop.set()
        self._thread.join(timeout=2)
        os.close(self._master)
        os.close(self._slave)


class IdlePortHandler(PortHandler):  # type: ignore[misc]  # the SDK is untyped
    """dynamixel-sdk's PortHandler, except when a reply has timed out.

    The SDK gives up on a reply after a wall-clock timeout. On a loaded machine the
    emulator's thread may not get to answer in time, so a lockstep run (the same for a seed
    whatever the load) would see a missing reply where an idle machine sees none. Here
    every write waits until the emulator has handled it (:meth:`PtyBus.sync`), and a reply
    has timed out when it can no longer come: every byte the emulator sent has reached this
    side of the pty, and still the SDK lacks bytes (a silent servo, a garbled length). That
    takes as long as the emulator needs, and gives the same answer at any load. Likewise
    ``clearPort`` (the SDK's discarding of stale input before each request) discards
    every byte the emulator sent so far, never just those that happened to have arrived.

    Waiting after writes the SDK does not wait on (sync write, which has no reply) is what
    makes the emulator's state the same at any load whenever the driver is not inside a
    call: without it, the last sync write of a run was still on its way, or not, when the
    run's figures were read (beside CPU hogs a run counted 394 packets, idle 393).
    """

    def __init__(self, port_name: str, bus: PtyBus) -> None:
        super().__init__(port_name)
        self._bus = bus
        self._read = 0  # bytes read from the port, or discarded when it was set up

    def setupPort(self, cflag_baud: int) -> bool:  # noqa: N802 (the SDK's name)
        ready = bool(super().setupPort(cflag_baud))
        self._read = self._bus.sent_bytes  # the set-up discarded what had arrived
        return ready

    def readPort(self, length: int) -> bytes:  # noqa: N802
        data = bytes(super().readPort(length))
        self._read += len(data)
        return data

    def writePort(self, packet: list[int]) -> int:  # noqa: N802
        written = int(super().writePort(packet))
        self._bus.sync()  # handled, and its reply (if any) sent, before the SDK goes on
        return written

    def _all_arrived(self) -> None:
        """Wait until every byte the emulator sent has reached this side (the kernel hands
        pty data over through a work queue); every write was handled already (writePort)."""
        while (self._read + self.ser.in_waiting < self._bus.sent_bytes
               and not self._bus.closed):
            select.select([self.ser.fileno()], [], [], 0.01)

    def clearPort(self) -> None:  # noqa: N802
        # The SDK discards what has arrived before each request: on a wall clock that
        # depends on how far a late reply got. Here it is always every byte sent so far.
        self._all_arrived()
        super().clearPort()
        self._read = self._bus.sent_bytes

    def isPacketTimeout(self) -> bool:  # noqa: N802
        if not self.ser.in_waiting:
            self._all_arrived()
        if self.ser.in_waiting:
            return False  # bytes to read first: the SDK reads them and asks again
        self.packet_timeout = 0
        return True
