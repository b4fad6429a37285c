"""The driver's port waits for the line instead of spinning while a reply is on its way."""

from __future__ import annotations

import os
import threading
import tty

from dynamixel_sdk import PortHandler

from efficient_comm.testing import TestHandle
from humanoid_sim.driver import ServoDriver, WaitingPortHandler


def _reads_until_timeout(port: PortHandler, *, timeout_ms: float) -> tuple[int, bytes]:
    """dynamixel-sdk's ``rxPacket`` loop: read, and ask whether the reply timed out."""
    port.setPacketTimeoutMillis(timeout_ms)
    reads, got = 0, b""
    while True:
        got += bytes(port.readPort(4 - len(got)))
        reads += 1
        if len(got) == 4 or port.isPacketTimeout():
            return reads, got


def test_a_silent_line_is_waited_on_not_polled() -> None:
    master, slave = os.openpty()
    tty.setraw(master)
    port = WaitingPortHandler(os.ttyname(slave))
    try:
        assert port.openPort()
        reads, got = _reads_until_timeout(port, timeout_ms=100)
        assert got == b""
        # The SDK's PortHandler returns at once and is asked again: thousands of reads in
        # 100 ms. Waiting on the port, a read ends when the timeout is due.
        assert reads <= 3, reads
        os.write(master, b"\x01\x02\x03\x04")  # bytes that are there are read at once
        assert _reads_until_timeout(port, timeout_ms=100) == (1, b"\x01\x02\x03\x04")
    finally:
        port.closePort()
        os.close(master)
        os.close(slave)


def test_the_driver_opens_a_waiting_port_by_default() -> None:
    driver = ServoDriver(TestHandle("driver", parameters={"port": "/dev/does_not_exist",
                                                          "ids": [1]}))
    assert driver.port_factory is WaitingPortHandler


def test_the_lockstep_port_waits_on_the_line_for_a_late_reply() -> None:
    """In lockstep a reply comes when the world's bus thread, in another process, gets the
    CPU; the match robot's port waits for it on the line, with its long bound kept."""
    from humanoid_sim.match_robot import LOCKSTEP_REPLY_MS, LockstepPort

    master, slave = os.openpty()
    tty.setraw(master)
    port = LockstepPort(os.ttyname(slave))
    reply = threading.Timer(0.05, os.write, (master, b"\x01\x02\x03\x04"))
    try:
        assert port.openPort()
        port.setPacketTimeoutMillis(10)
        assert port.packet_timeout >= LOCKSTEP_REPLY_MS  # the bound the SDK asked is raised
        reply.start()
        # Polled, the 50 ms before the reply would be thousands of empty reads.
        reads, got = _reads_until_timeout(port, timeout_ms=10)
        assert got == b"\x01\x02\x03\x04"
        assert reads <= 3, reads
    finally:
        reply.cancel()
        port.closePort()
        os.close(master)
        os.close(slave)
