"""The instructions of Protocol 2.0, answered the way servos on one bus answer them.

Broadcast rules (e-Manual, Protocol 2.0): a broadcast PING is answered by every servo, in
ID order; other broadcasts (WRITE, REG_WRITE, ACTION, REBOOT, SYNC_WRITE, BULK_WRITE, and
FACTORY_RESET unless it would reset the IDs too) are obeyed silently; a broadcast READ is
ignored. SYNC_READ and BULK_READ are answered by each listed servo in the order listed.
FAST_SYNC_READ and FAST_BULK_READ are answered with one status packet that the listed
servos build together (see :func:`.protocol.fast_status`): servos with firmware older than
45 do not know them, and the packet stops at the first listed servo that does not answer
(unplugged, status return level 0, too old), because the servos after it would continue a
CRC over bytes they never received. A servo whose read fails (an undefined address) still
fills its block, with the error and zeros, so the blocks after it stay where the driver
expects them. A packet with a bad CRC gets a CRC error from the servo it names (none for
broadcasts); an unknown instruction, or ACTION with nothing registered, gets
an instruction error. Status return level 0 answers only PING, 1 also the reads, 2
everything. Unplugged servos never answer. Servos are addressed by the ID in their control
table, so a written ID takes effect at once.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterable

from . import control_table as ct
from .plant import Plant
from .protocol import BROADCAST_ID, Error, Instruction, Packet, fast_status, status
from .servo import Servo

_READS = {Instruction.READ, Instruction.SYNC_READ, Instruction.BULK_READ,
          Instruction.FAST_SYNC_READ, Instruction.FAST_BULK_READ}
#: CLEAR's only defined option: reset the multi-turn count (parameters fixed by the e-Manual).
_CLEAR_MULTI_TURN = b"\x01\x44\x58\x4c\x22"
_FACTORY_RESET_KEEP = {0xFF: (), 0x01: ("id",), 0x02: ("id", "baud_rate")}
_REGISTERED = ct.BY_NAME["registered_instruction"].address


class Bus:
    def __init__(self, ids: Iterable[int], plant: Plant, *,
                 firmware_version: int = ct.FIRMWARE_VERSION) -> None:
        """``firmware_version``: of every servo; below 45 they know no Fast Sync Read."""
        #: The servos by the ID they left the factory with (their place on the robot).
        self.servos = {i: Servo(i, plant, firmware_version=firmware_version) for i in ids}
        self.packets = 0
        self.crc_errors = 0
        #: Packets received, by instruction (garbled ones included): what a driver sends.
        self.instructions: Counter[int] = Counter()

    def _present(self, dxl_id: int) -> Servo | None:
        return self._by_id().get(dxl_id)

    def _by_id(self) -> dict[int, Servo]:
        """The connected servos by the ID in their tables now (the first of a shared ID).

        Taken once for a packet that addresses many servos: each servo on a real bus
        reads the packet with the ID it has when the packet arrives, so a sync write of
        new IDs renumbers the servos after the packet, not in the middle of it.
        """
        servos: dict[int, Servo] = {}
        for servo in self.servos.values():
            if servo.connected:
                servos.setdefault(servo.dxl_id, servo)
        return servos

    @staticmethod
    def _reply(servo: Servo, instruction: int, error: int, params: bytes = b"") -> bytes:
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
        self.instructions[inst] += 1
        if not packet.crc_ok:
            self.crc_errors += 1
            servo = self._present(packet.dxl_id)
            return status(servo.dxl_id, Error.CRC) if servo is not None else b""
        if packet.dxl_id == BROADCAST_ID:
            return self._broadcast(inst, p)
        servo = self._present(packet.dxl_id)
        if servo is None:
            return b""
        return self._reply(servo, inst, *self._unicast(servo, inst, p))

    def _unicast(self, servo: Servo, inst: int, p: bytes) -> tuple[int, bytes]:
        """(error, parameters) of the status ``servo`` answers ``inst`` with."""
        if inst == Instruction.PING:
            return Error.NONE, self._ping_params(servo)
        if inst == Instruction.READ:
            if len(p) != 4:
                return Error.DATA_LENGTH, b""
            return servo.read(int.from_bytes(p[:2], "little"), int.from_bytes(p[2:4], "little"))
        if inst in (Instruction.WRITE, Instruction.REG_WRITE):
            if len(p) < 3:
                return Error.DATA_LENGTH, b""
            address, data = int.from_bytes(p[:2], "little"), p[2:]
            if inst == Instruction.WRITE:
                return servo.write(address, data), b""
            return self._register(servo, address, data), b""
        if inst == Instruction.ACTION:
            return self._action(servo), b""
        if inst == Instruction.REBOOT:
            servo.reset(keep=(), ram_only=True)  # clears hardware errors; torque goes off
            return Error.NONE, b""
        if inst == Instruction.FACTORY_RESET:
            keep = _FACTORY_RESET_KEEP.get(p[0]) if len(p) == 1 else None
            if keep is None:
                return Error.DATA_RANGE, b""
            servo.reset(keep=keep)
            return Error.NONE, b""
        if inst == Instruction.CLEAR:
            if p != _CLEAR_MULTI_TURN:
                return Error.DATA_RANGE, b""
            # Single-turn position control has no turn count to clear; a moving servo refuses.
            return (Error.RESULT_FAIL if servo.read(ct.BY_NAME["moving"].address, 1)[1] != b"\0"
                    else Error.NONE), b""
        return Error.INSTRUCTION, b""

    @staticmethod
    def _register(servo: Servo, address: int, data: bytes) -> int:
        error = servo.check_write(address, data)
        if not error:
            servo.registered = (address, data)
            servo.table[_REGISTERED] = 1
        return error

    @staticmethod
    def _action(servo: Servo) -> int:
        if servo.registered is None:
            return Error.INSTRUCTION  # e-Manual: ACTION without REG_WRITE
        address, data = servo.registered
        servo.registered = None
        servo.table[_REGISTERED] = 0
        return servo.write(address, data)

    @staticmethod
    def _ping_params(servo: Servo) -> bytes:
        model, firmware = ct.BY_NAME["model_number"], ct.BY_NAME["firmware_version"]
        return (bytes(servo.table[model.address : model.address + model.size])
                + bytes(servo.table[firmware.address : firmware.address + 1]))

    def _broadcast(self, inst: int, p: bytes) -> bytes:
        present = sorted((s for s in self.servos.values() if s.connected),
                         key=lambda s: s.dxl_id)
        if inst == Instruction.PING:
            return b"".join(status(s.dxl_id, s.alert(), self._ping_params(s)) for s in present)
        if inst in (Instruction.WRITE, Instruction.REG_WRITE) and len(p) >= 3:
            address, data = int.from_bytes(p[:2], "little"), p[2:]
            for s in present:
                if inst == Instruction.WRITE:
                    s.write(address, data)
                else:
                    self._register(s, address, data)
        elif inst == Instruction.ACTION:
            for s in present:
                if s.registered is not None:
                    self._action(s)
        elif inst == Instruction.REBOOT:
            for s in present:
                s.reset(keep=(), ram_only=True)
        elif inst == Instruction.FACTORY_RESET and len(p) == 1 and p[0] in (0x01, 0x02):
            for s in present:  # "reset all" (0xFF) is refused by broadcast: IDs would clash
                s.reset(keep=_FACTORY_RESET_KEEP[p[0]])
        elif inst == Instruction.SYNC_WRITE and len(p) >= 4:
            address, size = int.from_bytes(p[:2], "little"), int.from_bytes(p[2:4], "little")
            by_id = self._by_id()
            for i in range(4, len(p) - size, size + 1):
                servo = by_id.get(p[i])
                if servo is not None:
                    servo.write(address, p[i + 1 : i + 1 + size])
        elif inst == Instruction.BULK_WRITE:
            i = 0
            by_id = self._by_id()
            while i + 5 <= len(p):
                address = int.from_bytes(p[i + 1 : i + 3], "little")
                size = int.from_bytes(p[i + 3 : i + 5], "little")
                servo = by_id.get(p[i])
                if servo is not None:
                    servo.write(address, p[i + 5 : i + 5 + size])
                i += 5 + size
        elif inst in (Instruction.SYNC_READ, Instruction.FAST_SYNC_READ) and len(p) >= 4:
            address, size = int.from_bytes(p[:2], "little"), int.from_bytes(p[2:4], "little")
            return self._reads(inst, [(dxl_id, address, size) for dxl_id in p[4:]])
        elif inst in (Instruction.BULK_READ, Instruction.FAST_BULK_READ):
            return self._reads(inst, [
                (p[i], int.from_bytes(p[i + 1 : i + 3], "little"),
                 int.from_bytes(p[i + 3 : i + 5], "little"))
                for i in range(0, len(p) - 4, 5)
            ])
        return b""

    def _reads(self, inst: int, reads: list[tuple[int, int, int]]) -> bytes:
        """The answer to a sync or bulk read of ``(id, address, size)``, plain or fast."""
        by_id = self._by_id()
        if inst in (Instruction.SYNC_READ, Instruction.BULK_READ):
            return b"".join(self._read_status(by_id.get(read[0]), *read[1:], inst)
                            for read in reads)
        blocks = []
        for dxl_id, address, size in reads:
            servo = by_id.get(dxl_id)
            if servo is None or not servo.fast_read or not servo.get("status_return_level"):
                break  # the servos after it wait for its block in vain
            error, data = servo.read(address, size)
            blocks.append((dxl_id, error | servo.alert(), data.ljust(size, b"\0")))
        return fast_status(blocks, length=1 + sum(size + 4 for _, _, size in reads))

    def _read_status(self, servo: Servo | None, address: int, size: int, inst: int) -> bytes:
        if servo is None:
            return b""
        return self._reply(servo, inst, *servo.read(address, size))
