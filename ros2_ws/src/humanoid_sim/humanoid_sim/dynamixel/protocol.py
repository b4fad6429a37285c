"""Protocol 2.0 packets: header, length, instruction, parameters, CRC-16, byte stuffing.

Packet: ``FF FF FD 00 | ID | LEN_L LEN_H | INST | PARAMS... | CRC_L CRC_H``. LEN counts
the bytes after it (instruction, stuffed parameters, CRC). Inside instruction and
parameters, every ``FF FF FD`` is followed by a stuffing ``FD`` so that no header appears
inside a packet. The CRC is CRC-16 (polynomial 0x8005, initial 0, not reflected) over
everything before it, header included, after stuffing.

The one exception is the status of Fast Sync Read and Fast Bulk Read (:func:`fast_status`):
one packet that every servo read contributes a block to, neither stuffed nor checked as a
whole by the servos, see there.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum

HEADER = b"\xff\xff\xfd\x00"
BROADCAST_ID = 0xFE


class Instruction(IntEnum):
    PING = 0x01
    READ = 0x02
    WRITE = 0x03
    REG_WRITE = 0x04
    ACTION = 0x05
    FACTORY_RESET = 0x06
    REBOOT = 0x08
    CLEAR = 0x10
    STATUS = 0x55
    SYNC_READ = 0x82
    SYNC_WRITE = 0x83
    FAST_SYNC_READ = 0x8A
    BULK_READ = 0x92
    BULK_WRITE = 0x93
    FAST_BULK_READ = 0x9A


class Error(IntEnum):
    """The status packet's error field (bit 7, ALERT, flags a hardware error)."""

    NONE = 0x00
    RESULT_FAIL = 0x01
    INSTRUCTION = 0x02
    CRC = 0x03
    DATA_RANGE = 0x04
    DATA_LENGTH = 0x05
    DATA_LIMIT = 0x06
    ACCESS = 0x07


ALERT = 0x80


def _crc_table() -> list[int]:
    table = []
    for byte in range(256):
        crc = byte << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x8005) if crc & 0x8000 else crc << 1
        table.append(crc & 0xFFFF)
    return table


_TABLE = _crc_table()


def crc16(data: bytes, crc: int = 0) -> int:
    """CRC-16 of ``data``; ``crc``: the CRC of the bytes before it, to continue a running one."""
    for byte in data:
        crc = ((crc << 8) ^ _TABLE[((crc >> 8) ^ byte) & 0xFF]) & 0xFFFF
    return crc


def stuff(body: bytes) -> bytes:
    out = bytearray()
    for byte in body:
        out.append(byte)
        if byte == 0xFD and out[-3:] == b"\xff\xff\xfd":
            out.append(0xFD)
    return bytes(out)


def unstuff(body: bytes) -> bytes:
    out = bytearray()
    i = 0
    while i < len(body):
        out.append(body[i])
        if body[i] == 0xFD and out[-3:] == b"\xff\xff\xfd" and body[i + 1 : i + 2] == b"\xfd":
            i += 1  # drop the stuffing byte
        i += 1
    return bytes(out)


def encode(dxl_id: int, instruction: int, params: bytes = b"") -> bytes:
    body = stuff(bytes([instruction]) + params)
    head = HEADER + bytes([dxl_id]) + (len(body) + 2).to_bytes(2, "little")
    packet = head + body
    return packet + crc16(packet).to_bytes(2, "little")


def status(dxl_id: int, error: int, params: bytes = b"") -> bytes:
    return encode(dxl_id, Instruction.STATUS, bytes([error]) + params)


def fast_status(blocks: list[tuple[int, int, bytes]], *, length: int) -> bytes:
    """The one status packet of a Fast Sync/Bulk Read, of ``(id, error, data)`` blocks.

    e-Manual, Protocol 2.0, Fast Sync Read: ``FF FF FD 00 FE LEN 55`` then, per servo in
    the order the instruction listed them, ``ERR ID DATA... CRC_L CRC_H``. The first servo
    sends the header with the length of the whole packet (``length``, the LEN field);
    each servo's CRC covers every byte on the wire before it (header and earlier blocks,
    CRCs included), so the last one is the packet's CRC. Not byte-stuffed. Fewer
    ``blocks`` than announced is the packet cut short where a servo did not answer.
    """
    if not blocks:
        return b""
    out = bytearray(HEADER) + bytes([BROADCAST_ID]) + length.to_bytes(2, "little")
    out.append(Instruction.STATUS)
    crc = crc16(bytes(out))
    for dxl_id, error, data in blocks:
        block = bytes([error, dxl_id]) + data
        crc = crc16(block, crc)
        out += block + crc.to_bytes(2, "little")
        crc = crc16(bytes(out[-2:]), crc)
    return bytes(out)


@dataclass(frozen=True)
class Packet:
    dxl_id: int
    instruction: int
    params: bytes
    crc_ok: bool = True


class Parser:
    """Feed bytes as they arrive; get whole packets. Garbage before a header is skipped."""

    #: Longer packets are treated as noise (a real servo's receive buffer is small too).
    MAX_LENGTH = 1024

    def __init__(self) -> None:
        self._buf = bytearray()

    def feed(self, data: bytes) -> list[Packet]:
        self._buf += data
        packets: list[Packet] = []
        while True:
            start = self._buf.find(HEADER)
            if start < 0:
                del self._buf[: max(0, len(self._buf) - 3)]  # keep a possible partial header
                return packets
            del self._buf[:start]
            if len(self._buf) < 7:
                return packets
            length = int.from_bytes(self._buf[5:7], "little")
            if length < 3 or length > self.MAX_LENGTH:
                del self._buf[:4]  # not a packet after all: resync after this header
                continue
            end = 7 + length
            if len(self._buf) < end:
                return packets
            raw = bytes(self._buf[:end])
            del self._buf[:end]
            crc_ok = crc16(raw[:-2]) == int.from_bytes(raw[-2:], "little")
            body = unstuff(raw[7:-2])
            packets.append(Packet(raw[4], body[0], bytes(body[1:]), crc_ok))

    @property
    def pending(self) -> bool:
        """Whether bytes of an incomplete packet (or of a header) are waiting."""
        return bool(self._buf)

    def discard(self) -> int:
        """Drop a packet cut short; the number of bytes dropped."""
        dropped = len(self._buf)
        self._buf.clear()
        return dropped
