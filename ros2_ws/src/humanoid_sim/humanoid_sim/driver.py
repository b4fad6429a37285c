"""The servo driver: every cycle, one sync read of all servos and one sync write of all goals.

A component (it takes an efficient_comm node handle) that talks to the bus with
dynamixel-sdk exactly as on the robot; only ``port`` differs (the emulator's pty instead of
/dev/ttyUSB0). It publishes ``joint_states`` (position and velocity of every servo that
answered), takes ``joint_commands`` (JointState with names and positions), and reports each
servo on ``/diagnostics``: OK, or ERROR while it does not answer. A missing port, missing
servos and garbled replies are reported and survived: the driver keeps cycling; a servo
that failed :data:`MISSING_AFTER` reads in a row is reported missing, pinged once a second
and taken back when it answers again.
"""

from __future__ import annotations

import math
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from dynamixel_sdk import (
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
ADDR_GOAL = ct.BY_NAME["goal_position"].address
ADDR_VELOCITY = ct.BY_NAME["present_velocity"].address  # velocity then position: 8 bytes
READ_LENGTH = 8
RETRY_NS = 1_000_000_000
#: Consecutive failed reads after which a servo counts as missing (a garbled reply or two
#: on a noisy line must not take a joint away).
MISSING_AFTER = 10


def _signed32(value: int) -> int:
    return value - (1 << 32) if value >= 1 << 31 else value


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
        rate = node.declare_parameter("rate_hz", 100.0)
        # The SDK derives its reply timeouts from the USB-serial adapter's latency timer
        # (16 ms on a stock FTDI adapter, 1 ms when tuned); it is one setting per process.
        latency = node.declare_parameter("latency_timer_ms", float(port_handler.LATENCY_TIMER))
        if latency <= 0:
            raise SimConfigError(f"latency_timer_ms must be > 0, got {latency}")
        port_handler.LATENCY_TIMER = latency
        self.state_pub = node.create_publisher(JointState, "joint_states", qos=10)
        self.diag_pub = node.create_publisher(DiagnosticArray, "/diagnostics", qos=10)
        node.create_subscription(JointState, "joint_commands", self._on_command, qos=10)
        self.goals: dict[int, int] = {}
        self.present: set[int] = set()
        self._misses: dict[int, int] = {}
        self.cycles = 0
        self.comm_errors = 0
        self._port: PortHandler | None = None
        self._packets = PacketHandler(2.0)
        self._last_retry_ns = -RETRY_NS
        self._last_diag_ns = -RETRY_NS
        node.create_timer(1.0 / rate, self.cycle)

    # -- connection -----------------------------------------------------------------------

    def _connect(self) -> None:
        port = PortHandler(self.port_name)
        try:
            opened = port.openPort() and port.setBaudRate(self.baud)
        except Exception as exc:  # pyserial raises for a missing device
            self.node.logger.error(f"cannot open {self.port_name}: {exc}")
            return
        if opened:
            self._port = port
            self.node.logger.info(f"opened {self.port_name} at {self.baud} baud")

    def _adopt_missing(self) -> None:
        assert self._port is not None
        for dxl_id in self.ids:
            if dxl_id in self.present:
                continue
            _, result, _ = self._packets.ping(self._port, dxl_id)
            if result == COMM_SUCCESS:
                self._packets.write1ByteTxRx(self._port, dxl_id, ADDR_TORQUE, 1)
                self.present.add(dxl_id)
                self._misses[dxl_id] = 0
                self.node.logger.info(f"servo {dxl_id} answers; torque on")

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
        if now - self._last_retry_ns >= RETRY_NS:
            self._last_retry_ns = now
            if self._port is None:
                self._connect()
            if self._port is not None:
                self._adopt_missing()
        if self._port is not None and self.present:
            self._read(now)
            self._write()
        if now - self._last_diag_ns >= RETRY_NS:
            self._last_diag_ns = now
            self._publish_diagnostics(now)

    def _read(self, now: int) -> None:
        assert self._port is not None
        reader = GroupSyncRead(self._port, self._packets, ADDR_VELOCITY, READ_LENGTH)
        for dxl_id in sorted(self.present):
            reader.addParam(dxl_id)
        if reader.txRxPacket() != COMM_SUCCESS:
            self.comm_errors += 1
        msg = JointState()
        msg.header.stamp = to_msg(now)
        for dxl_id in sorted(self.present):
            if not reader.isAvailable(dxl_id, ADDR_VELOCITY, READ_LENGTH):
                misses = self._misses[dxl_id] = self._misses.get(dxl_id, 0) + 1
                if misses >= MISSING_AFTER:
                    self.present.discard(dxl_id)  # pinged again within a second
                    self.node.logger.warning(
                        f"servo {dxl_id} did not answer {misses} times in a row"
                    )
                continue
            self._misses[dxl_id] = 0
            velocity = _signed32(reader.getData(dxl_id, ADDR_VELOCITY, 4))
            position = _signed32(reader.getData(dxl_id, ADDR_VELOCITY + 4, 4))
            msg.name.append(self.names[self.ids.index(dxl_id)])
            msg.position.append((position - ct.CENTER_TICKS) / ct.TICKS_PER_RAD)
            msg.velocity.append(velocity * ct.RPM_PER_UNIT * 2 * math.pi / 60)
        self.state_pub.publish(msg)

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

    def _publish_diagnostics(self, now: int) -> None:
        array = DiagnosticArray()
        array.header.stamp = to_msg(now)
        for dxl_id, name in zip(self.ids, self.names, strict=True):
            ok = self._port is not None and dxl_id in self.present
            array.status.append(DiagnosticStatus(
                level=DiagnosticStatus.OK if ok else DiagnosticStatus.ERROR,
                name=f"{self.node.name}: servo {dxl_id} ({name})",
                message="ok" if ok else (
                    "port not open" if self._port is None else "not answering"
                ),
                hardware_id=f"dynamixel:{self.port_name}:{dxl_id}",
                values=[KeyValue(key="comm_errors", value=str(self.comm_errors))],
            ))
        self.diag_pub.publish(array)

    def close(self) -> None:
        if self._port is not None:
            self._port.closePort()

    def status(self) -> dict[str, Any]:
        return {"present": sorted(self.present), "comm_errors": self.comm_errors}


#: ``ros2 run humanoid_sim servo_driver --ros-args -p port:=/dev/ttyUSB0 -p ids:=[1,2]``.
main = standalone_main(ServoDriver, name="servo_driver")
