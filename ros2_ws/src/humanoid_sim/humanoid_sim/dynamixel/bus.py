"""The instructions of Protocol 2.0, answered the way servos on one bus answer them.

Broadcast rules: a broadcast PING is answered by every servo, in ID order; other
broadcasts (WRITE, REG_WRITE, ACTION, SYNC_WRITE, BULK_WRITE) are obeyed silently; a
broadcast READ is ignored. SYNC_READ and BULK_READ are answered by each listed servo in the
order listed. A packet with a bad CRC gets a CRC error from the servo it names (none for
broadcasts); an unknown instruction gets an instruction error. Status return level 0
answers only PING, 1 also READs, 2 everything. Unplugged servos never answer.
"""

from __future__ import annotations

from collections.abc import Iterable

from .plant import Plant
from .protocol import BROADCAST_ID, Error, Instruction, Packet, status
from .servo import Servo

_READS = {Instruction.READ, Instruction.SYNC_READ, Instruction.BULK_READ}


class Bus:
    def __init__(self, ids: Iterable[int], plant: Plant) -> None:
        self.servos = {i: Servo(i, plant) for i in ids}
        self.packets = 0
        self.crc_errors = 0

    def _present(self, dxl_id: int) -> Servo | None:
        servo = self.servos.get(dxl_id)
        return servo if servo is not None and servo.connected else None

    def _reply(self, servo: Servo, instruction: int, error: int, params: bytes = b"") -> bytes:
        level = servo.get("status_return_level")
        if instruction != Instruction.PING and (
            level == 0 or (level == 1 and instruction not in _READS)
        ):
            return b""
        return status(servo.dxl_id, error | servo.alert(), params)

    def handle(self, packet: Packet) -> bytes:
        """The bytes the bus answers ``packet`` with (possibly none)."""
        self.packets += 1
        inst, p = packet.instruction, packet.params
        if not packet.crc_ok:
            self.crc_errors += 1
            servo = self._present(packet.dxl_id)
            return status(servo.dxl_id, Error.CRC) if servo is not None else b""
        if packet.dxl_id == BROADCAST_ID:
            return self._broadcast(inst, p)
        servo = self._present(packet.dxl_id)
        if servo is None:
            return b""
        return self._unicast(servo, inst, p)

    def _unicast(self, servo: Servo, inst: int, p: bytes) -> bytes:
        if inst == Instruction.PING:
            return self._reply(servo, inst, Error.NONE, self._ping_params(servo))
        if inst == Instruction.READ:
            if len(p) != 4:
                return self._reply(servo, inst, Error.DATA_LENGTH)
            error, data = servo.read(int.from_bytes(p[:2], "little"),
                                     int.from_bytes(p[2:4], "little"))
            return self._reply(servo, inst, error, data)
        if inst in (Instruction.WRITE, Instruction.REG_WRITE):
            if len(p) < 3:
                return self._reply(servo, inst, Error.DATA_LENGTH)
            address, data = int.from_bytes(p[:2], "little"), p[2:]
            if inst == Instruction.WRITE:
                return self._reply(servo, inst, servo.write(address, data))
            error = servo.check_write(address, data)
            if not error:
                servo.registered = (address, data)
                servo.table[69] = 1
            return self._reply(servo, inst, error)
        if inst == Instruction.ACTION:
            return self._reply(servo, inst, self._action(servo))
        if inst == Instruction.REBOOT:
            servo.table[70] = 0  # clears hardware errors; torque goes off
            servo.write(64, b"\x00")
            return self._reply(servo, inst, Error.NONE)
        return self._reply(servo, inst, Error.INSTRUCTION)

    def _action(self, servo: Servo) -> int:
        if servo.registered is None:
            return Error.RESULT_FAIL
        address, data = servo.registered
        servo.registered = None
        servo.table[69] = 0
        return servo.write(address, data)

    @staticmethod
    def _ping_params(servo: Servo) -> bytes:
        return bytes(servo.table[0:2]) + bytes(servo.table[6:7])

    def _broadcast(self, inst: int, p: bytes) -> bytes:
        present = [s for _, s in sorted(self.servos.items()) if s.connected]
        if inst == Instruction.PING:
            return b"".join(status(s.dxl_id, s.alert(), self._ping_params(s)) for s in present)
        if inst == Instruction.WRITE and len(p) >= 3:
            for s in present:
                s.write(int.from_bytes(p[:2], "little"), p[2:])
        elif inst == Instruction.ACTION:
            for s in present:
                if s.registered is not None:
                    self._action(s)
        elif inst == Instruction.SYNC_WRITE and len(p) >= 4:
            address, size = int.from_bytes(p[:2], "little"), int.from_bytes(p[2:4], "little")
            for i in range(4, len(p) - size, size + 1):
                servo = self._present(p[i])
                if servo is not None:
                    servo.write(address, p[i + 1 : i + 1 + size])
        elif inst == Instruction.BULK_WRITE:
            i = 0
            while i + 5 <= len(p):
                address = int.from_bytes(p[i + 1 : i + 3], "little")
                size = int.from_bytes(p[i + 3 : i + 5], "little")
                servo = self._present(p[i])
                if servo is not None:
                    servo.write(address, p[i + 5 : i + 5 + size])
                i += 5 + size
        elif inst == Instruction.SYNC_READ and len(p) >= 4:
            address, size = int.from_bytes(p[:2], "little"), int.from_bytes(p[2:4], "little")
            out = b""
            for dxl_id in p[4:]:
                servo = self._present(dxl_id)
                if servo is not None:
                    error, data = servo.read(address, size)
                    out += status(dxl_id, error | servo.alert(), data)
            return out
        elif inst == Instruction.BULK_READ:
            out = b""
            for i in range(0, len(p) - 4, 5):
                servo = self._present(p[i])
                if servo is not None:
                    error, data = servo.read(int.from_bytes(p[i + 1 : i + 3], "little"),
                                             int.from_bytes(p[i + 3 : i + 5], "little"))
                    out += status(p[i], error | servo.alert(), data)
            return out
        return b""
