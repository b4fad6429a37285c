"""The servo driver: every cycle, one (fast) sync read of all servos and one sync write of goals.

A component (it takes an efficient_comm node handle) that talks to the bus with
dynamixel-sdk exactly as on the robot; only ``port`` differs (the emulator's pty instead of
/dev/ttyUSB0). It publishes ``joint_states`` (position and velocity of every servo that
answered), takes ``joint_commands`` (JointState with names and positions), and reports each
servo on ``/diagnostics`` once a second: OK; ERROR while it does not answer; ERROR with the
Hardware Error Status while its replies carry the alert bit (overload, overheating, ...).
A missing or vanishing port, missing servos and garbled replies are reported and survived:
the driver keeps cycling; a servo that failed :data:`MISSING_AFTER` reads in a row is
reported missing, pinged once a second and taken back (torque on) when it answers again.

Fast Sync Read (instruction 0x8A) is used for the servos that support it (XM430 and its
kin from firmware 45, see :data:`FAST_SYNC_READ_FIRMWARE`; parameter ``fast_sync_read``):
the servos answer with one status packet together instead of one each, which saves the
bus most of a cycle's overhead. Its weakness is that it is all or nothing: dynamixel-sdk
drops the whole packet if one byte is garbled or one servo is silent (the servos after a
silent one cannot continue the packet), and the SDK keeps nothing of it. So the driver
reads only the servos that answered last time with it; when it fails, the same cycle reads
them again with plain Sync Read, which tells which servo failed; servos that failed are
read with plain Sync Read until they answer. A bus on which Fast Sync Read keeps failing
while Sync Read works gets plain Sync Read from then on.

dynamixel-sdk stops reading a plain sync read's replies at the first servo that fails, so a
silent servo would hide every servo after it. The driver therefore reads the servos that
failed last time at the end of the sync read, and counts a miss only for the servo that
actually failed: one unplugged servo costs the others at most one cycle.
"""

from __future__ import annotations

import contextlib
import math
import select
import termios
from collections.abc import Callable
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from dynamixel_sdk import (
    COMM_RX_CORRUPT,
    COMM_SUCCESS,
    GroupSyncRead,
    GroupSyncWrite,
    PacketHandler,
    PortHandler,
    port_handler,
)
from sensor_msgs.msg import JointState

from efficient_comm import to_msg
from efficient_comm.handle import NodeHandle
from efficient_comm.standalone import standalone_main

from .dynamixel import control_table as ct
from .errors import SimConfigError

ADDR_TORQUE = ct.BY_NAME["torque_enable"].address
ADDR_FIRMWARE = ct.BY_NAME["firmware_version"].address
ADDR_HARDWARE_ERROR = ct.BY_NAME["hardware_error_status"].address
ADDR_GOAL = ct.BY_NAME["goal_position"].address
ADDR_VELOCITY = ct.BY_NAME["present_velocity"].address  # velocity then position: 8 bytes
READ_LENGTH = 8
RETRY_NS = 1_000_000_000
ALERT = 0x80  # the status error byte's hardware error bit (the rest is the error number)
#: Consecutive failed reads after which a servo counts as missing (a garbled reply or two
#: on a noisy line must not take a joint away).
MISSING_AFTER = 10
#: Tries of each exchange while adopting a servo (ping, firmware read, torque on and its
#: read-back) within one cycle; a servo that answered its ping but was not adopted is tried
#: again next cycle, one that did not answer within a second.
ADOPT_TRIES = 5
#: Model number -> the first firmware with Fast Sync Read (e-Manual, Protocol 2.0: "X430/540
#: Series (Fw v45 or above, 2XL/2XC Not Supported)", "X330 (Fw v46 or above)"; model numbers
#: as in dynamixel-sdk's model list). Servos not listed get plain Sync Read.
FAST_SYNC_READ_FIRMWARE = {
    **dict.fromkeys((1000, 1001, 1010, 1011, 1020, 1030, 1040, 1050, 1060, 1070, 1080), 45),
    **dict.fromkeys((1100, 1101, 1110, 1111, 1120, 1130, 1140, 1150, 1170, 1180), 45),
    **dict.fromkeys((1190, 1200, 1210, 1220, 1230, 1240), 46),  # X330
}
#: Failed Fast Sync Reads in a row, each followed by a plain Sync Read that every servo
#: answered, after which the bus is taken not to support it (a servo or adapter in the way).
FAST_GIVE_UP = 10
SDK_LATENCY_TIMER_MS = float(port_handler.LATENCY_TIMER)  # before any driver changed it
#: What the port raises when the device goes away: pyserial's SerialException (an OSError),
#: or termios.error from flushing a pty whose other side has closed.
PORT_GONE = (OSError, termios.error)


class WaitingPortHandler(PortHandler):  # type: ignore[misc]  # the SDK is untyped
    """dynamixel-sdk's PortHandler, except that a read with nothing to read waits for the
    line (at most until the reply's timeout) instead of returning at once.

    The SDK opens the port non-blocking and, waiting for a reply, calls ``readPort`` in a
    loop until the reply is complete or its timeout passed: a core spins for the whole
    time a reply takes. In the team match a reply comes from the world process, which that
    spinning starves: a robot process spent 40 % of its main thread's time in 280 000 empty
    reads a minute. Timeouts and bytes read are the SDK's, unchanged; only the idle spin is
    gone (``select`` on the port until a byte arrives or the timeout is due).
    """

    def readPort(self, length: int) -> bytes:  # noqa: N802 (the SDK's name)
        if self.ser is not None and not self.ser.in_waiting and self.packet_timeout > 0:
            left_ms = self.packet_timeout - self.getTimeSinceStart()
            if left_ms > 0:
                select.select([self.ser.fileno()], [], [], left_ms / 1000.0)
        return bytes(super().readPort(length))


class ServoDriver:
    def __init__(self, node: NodeHandle) -> None:
        self.node = node
        self.port_name = node.declare_parameter("port", "/dev/ttyUSB0")
        self.baud = node.declare_parameter("baud_rate", 1_000_000)
        self.ids = node.declare_parameter("ids", [1])
        names = node.declare_parameter("joint_names", [""])
        self.names = names if names != [""] else [f"joint_{i}" for i in self.ids]
        if len(self.names) != len(self.ids):
            raise SimConfigError(f"{len(self.ids)} ids but {len(self.names)} joint_names")
        if len(set(self.ids)) != len(self.ids) or not all(0 <= i <= 252 for i in self.ids):
            raise SimConfigError(f"ids must be distinct servo IDs 0..252, got {self.ids}")
        if len(set(self.names)) != len(self.names):
            raise SimConfigError(f"joint_names must be distinct, got {self.names}")
        rate = node.declare_parameter("rate_hz", 100.0)
        # The SDK derives its reply timeouts from the USB-serial adapter's latency timer
        # (16 ms on a stock FTDI adapter, 1 ms when tuned); it is one setting per process,
        # so every driver sets it, to the SDK's stock value unless told otherwise.
        latency = node.declare_parameter("latency_timer_ms", SDK_LATENCY_TIMER_MS)
        if latency <= 0:
            raise SimConfigError(f"latency_timer_ms must be > 0, got {latency}")
        port_handler.LATENCY_TIMER = latency
        #: Use Fast Sync Read for the servos that support it (False: plain Sync Read only).
        self.fast_sync_read = node.declare_parameter("fast_sync_read", True)
        self.state_pub = node.create_publisher(JointState, "joint_states", qos=10)
        self.diag_pub = node.create_publisher(DiagnosticArray, "/diagnostics", qos=10)
        node.create_subscription(JointState, "joint_commands", self._on_command, qos=10)
        self.goals: dict[int, int] = {}
        self.present: set[int] = set()
        self._misses: dict[int, int] = {}
        #: Hardware Error Status (address 70) by servo, read once a second; 0: none.
        self.hardware_errors: dict[int, int] = {}
        #: Servos whose model and firmware answer Fast Sync Read (learnt when adopted).
        self.fast_capable: set[int] = set()
        self._fast_failures = 0
        self.cycles = 0
        self.comm_errors = 0
        self._port: PortHandler | None = None
        #: Makes the port from its name: dynamixel-sdk's PortHandler. The seam through which
        #: a lockstep simulation hands the SDK a port whose reply timeout does not depend on
        #: the wall clock (``PtyBus.direct_port``); on a robot nothing sets it.
        self.port_factory: Callable[[str], PortHandler] = WaitingPortHandler
        self._packets = PacketHandler(2.0)
        self._last_retry_ns = -RETRY_NS
        self._last_diag_ns = -RETRY_NS
        #: Servos that answered a ping but whose adoption (firmware read, torque on read
        #: back) failed: tried again every cycle, so a garbled write never leaves a joint
        #: limp for a second.
        self._adopting: set[int] = set()
        node.create_timer(1.0 / rate, self.cycle)

    # -- connection -----------------------------------------------------------------------

    def _connect(self) -> None:
        port = self.port_factory(self.port_name)
        try:
            opened = port.openPort() and port.setBaudRate(self.baud)
        except Exception as exc:  # pyserial raises for a missing device
            self.node.logger.error(f"cannot open {self.port_name}: {exc}")
            return
        if not opened:
            self.node.logger.error(f"cannot open {self.port_name} at {self.baud} baud")
            if port.is_open:
                port.closePort()
            return
        self._port = port
        self.node.logger.info(f"opened {self.port_name} at {self.baud} baud")

    def _adopt_missing(self, ids: list[int] | None = None) -> None:
        """Ping each servo of ``ids`` (default: every servo not present), read its firmware
        and turn its torque on, verified by reading Torque Enable back: a garbled write
        (its reply lost, or the request refused for a bad CRC) must not leave it limp."""
        assert self._port is not None
        for dxl_id in self.ids if ids is None else ids:
            if dxl_id in self.present:
                continue
            for _ in range(ADOPT_TRIES):  # line noise either way: asking again is harmless
                model, result, _ = self._packets.ping(self._port, dxl_id)
                if result == COMM_SUCCESS:
                    break
            if result != COMM_SUCCESS:
                self._adopting.discard(dxl_id)  # silent: pinged again within a second
                continue
            self._adopting.add(dxl_id)  # answers: tried every cycle until adopted
            for _ in range(ADOPT_TRIES):
                firmware, result, _ = self._packets.read1ByteTxRx(self._port, dxl_id,
                                                                  ADDR_FIRMWARE)
                if result == COMM_SUCCESS:
                    break
            if result != COMM_SUCCESS:
                self.comm_errors += 1
                continue
            if firmware >= FAST_SYNC_READ_FIRMWARE.get(model, 256):
                self.fast_capable.add(dxl_id)
            else:
                self.fast_capable.discard(dxl_id)
            if not self._torque_on(dxl_id):
                self.comm_errors += 1
                continue
            self._adopting.discard(dxl_id)
            self.present.add(dxl_id)
            self._misses[dxl_id] = 0
            self.node.logger.info(f"servo {dxl_id} answers; torque on")

    def _torque_on(self, dxl_id: int) -> bool:
        """Write Torque Enable 1 and read it back; True once the servo says it is on."""
        assert self._port is not None
        result, error = COMM_SUCCESS, 0
        for _ in range(ADOPT_TRIES):
            # The write's own reply does not matter: a garbled reply hides a write that
            # happened, a garbled request is refused; the read-back tells which.
            self._packets.write1ByteTxRx(self._port, dxl_id, ADDR_TORQUE, 1)
            value, result, error = self._packets.read1ByteTxRx(self._port, dxl_id, ADDR_TORQUE)
            if result == COMM_SUCCESS and value == 1:
                return True
        self.node.logger.warning(f"servo {dxl_id} answers but torque on failed "
                                 f"({self._packets.getTxRxResult(result)}, error {error:#04x})"
                                 f"; trying again next cycle")
        return False

    # -- the cycle ----------------------------------------------------------------------

    def _on_command(self, msg: JointState) -> None:
        for name, position in zip(msg.name, msg.position, strict=False):
            if name in self.names and math.isfinite(position):
                dxl_id = self.ids[self.names.index(name)]
                ticks = round(position * ct.TICKS_PER_RAD) + ct.CENTER_TICKS
                self.goals[dxl_id] = max(0, min(4095, ticks))

    def cycle(self) -> None:
        now = self.node.clock.now_ns()
        self.cycles += 1
        try:
            if now - self._last_retry_ns >= RETRY_NS:
                self._last_retry_ns = now
                if self._port is None:
                    self._connect()
                if self._port is not None:
                    self._adopt_missing()
            elif self._port is not None and self._adopting:
                self._adopt_missing(sorted(self._adopting))
            if self._port is not None and self.present:
                self._read(now)
                self._write()
        except PORT_GONE as exc:
            self._lose_port(exc)
        if now - self._last_diag_ns >= RETRY_NS:
            self._last_diag_ns = now
            try:
                if self._port is not None and self.present:
                    self._read_hardware_errors()
            except PORT_GONE as exc:
                self._lose_port(exc)
            self._publish_diagnostics(now)

    def _lose_port(self, exc: Exception) -> None:
        self.node.logger.error(f"lost {self.port_name}: {exc}; reopening within a second")
        self.comm_errors += 1
        port, self._port = self._port, None
        self.present.clear()
        self._adopting.clear()
        if port is not None:
            with contextlib.suppress(*PORT_GONE):
                port.closePort()

    def _sync_read(self, address: int, length: int, order: list[int]
                   ) -> tuple[dict[int, bytes], int | None]:
        """One sync read: what each servo sent, and the servo that failed (if one did)."""
        assert self._port is not None
        reader = GroupSyncRead(self._port, self._packets, address, length)
        for dxl_id in order:
            reader.addParam(dxl_id)
        if reader.txRxPacket() != COMM_SUCCESS:
            self.comm_errors += 1
        got: dict[int, bytes] = {}
        for dxl_id in order:
            # After a failure the SDK keeps what the servos before the failed one sent
            # (isAvailable() then says no for all of them).
            data = bytes(reader.data_dict.get(dxl_id) or b"")
            if len(data) != length:
                return got, dxl_id  # the servos after it were not read
            got[dxl_id] = data
        return got, None

    def _fast_sync_read(self, address: int, length: int, ids: list[int]
                        ) -> dict[int, bytes] | None:
        """One Fast Sync Read: what each servo sent, or None if the packet was lost."""
        assert self._port is not None
        reader = GroupSyncRead(self._port, self._packets, address, length)
        for dxl_id in ids:
            reader.addParam(dxl_id)
        try:
            result = reader.fastSyncRead()
        except IndexError:  # a packet shorter than its servos' blocks (garbled length)
            result = COMM_RX_CORRUPT
        got = {i: bytes(reader.data_dict.get(i) or b"") for i in ids}
        if result != COMM_SUCCESS or any(len(data) != length for data in got.values()):
            self.comm_errors += 1
            return None
        return got

    def _read_all(self, address: int, length: int) -> tuple[dict[int, bytes], int | None]:
        """Read every present servo; the servo that failed, if one did.

        Fast Sync Read for the capable servos that answered last time, plain Sync Read for
        the others (the ones that failed last) and, in the same cycle, for all of them if
        the fast read was lost.
        """
        order = sorted(self.present, key=lambda i: (self._misses.get(i, 0) > 0, i))
        fast = [i for i in order if self._use_fast(i)]
        got: dict[int, bytes] = {}
        if fast:
            answer = self._fast_sync_read(address, length, fast)
            if answer is not None:
                self._fast_failures = 0
                got = answer
                order = [i for i in order if i not in answer]
        if not order:
            return got, None
        more, failed = self._sync_read(address, length, order)
        if fast and not got and failed is None:
            self._fast_lost_but_sync_worked()
        return got | more, failed

    def _use_fast(self, dxl_id: int) -> bool:
        return (self.fast_sync_read and self._fast_failures < FAST_GIVE_UP
                and dxl_id in self.fast_capable and not self._misses.get(dxl_id, 0))

    def _fast_lost_but_sync_worked(self) -> None:
        self._fast_failures += 1
        if self._fast_failures == FAST_GIVE_UP:
            self.node.logger.warning(
                f"fast sync read failed {FAST_GIVE_UP} times in a row while sync read "
                "worked: using sync read")

    def _read(self, now: int) -> None:
        got, failed = self._read_all(ADDR_VELOCITY, READ_LENGTH)
        if failed is not None:
            self._missed(failed)
        msg = JointState()
        msg.header.stamp = to_msg(now)
        for dxl_id in sorted(got):
            self._misses[dxl_id] = 0
            velocity = int.from_bytes(got[dxl_id][:4], "little", signed=True)
            position = int.from_bytes(got[dxl_id][4:], "little", signed=True)
            msg.name.append(self.names[self.ids.index(dxl_id)])
            msg.position.append((position - ct.CENTER_TICKS) / ct.TICKS_PER_RAD)
            msg.velocity.append(velocity * ct.RPM_PER_UNIT * 2 * math.pi / 60)
        self.state_pub.publish(msg)

    def _read_hardware_errors(self) -> None:
        """Hardware Error Status of every servo (once a second, with the diagnostics)."""
        got, _ = self._read_all(ADDR_HARDWARE_ERROR, 1)
        for dxl_id, data in got.items():
            self.hardware_errors[dxl_id] = data[0]

    def _missed(self, dxl_id: int) -> None:
        misses = self._misses[dxl_id] = self._misses.get(dxl_id, 0) + 1
        if misses >= MISSING_AFTER:
            self.present.discard(dxl_id)  # pinged again within a second
            self.node.logger.warning(f"servo {dxl_id} did not answer {misses} times in a row")

    def _write(self) -> None:
        assert self._port is not None
        goals = {i: g for i, g in self.goals.items() if i in self.present}
        if not goals:
            return
        writer = GroupSyncWrite(self._port, self._packets, ADDR_GOAL, 4)
        for dxl_id, ticks in goals.items():
            writer.addParam(dxl_id, list(ticks.to_bytes(4, "little")))
        if writer.txPacket() != COMM_SUCCESS:
            self.comm_errors += 1

    def _servo_status(self, dxl_id: int) -> tuple[bytes, str]:
        """(diagnostic level, message) of one servo."""
        if self._port is None:
            return DiagnosticStatus.ERROR, "port not open"
        if dxl_id not in self.present:
            return DiagnosticStatus.ERROR, "not answering"
        if hardware_error := self.hardware_errors.get(dxl_id, 0):
            return DiagnosticStatus.ERROR, f"hardware error status {hardware_error:#04x}"
        return DiagnosticStatus.OK, "ok"

    def _publish_diagnostics(self, now: int) -> None:
        array = DiagnosticArray()
        array.header.stamp = to_msg(now)
        for dxl_id, name in zip(self.ids, self.names, strict=True):
            level, message = self._servo_status(dxl_id)
            array.status.append(DiagnosticStatus(
                level=level,
                name=f"{self.node.fully_qualified_name}: servo {dxl_id} ({name})",
                message=message,
                hardware_id=f"dynamixel:{self.port_name}:{dxl_id}",
                values=[KeyValue(key="comm_errors", value=str(self.comm_errors))],
            ))
        self.diag_pub.publish(array)

    def close(self) -> None:
        if self._port is not None:
            self._port.closePort()

    def status(self) -> dict[str, Any]:
        return {"present": sorted(self.present), "comm_errors": self.comm_errors}

    @property
    def fast_servos(self) -> list[int]:
        """The servos the next cycle reads with Fast Sync Read."""
        return sorted(i for i in self.present if self._use_fast(i))


#: ``ros2 run humanoid_sim servo_driver --ros-args -p port:=/dev/ttyUSB0 -p ids:=[1,2]``.
main = standalone_main(ServoDriver, name="servo_driver")
