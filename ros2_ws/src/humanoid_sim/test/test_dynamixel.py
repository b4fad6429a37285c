"""The emulated bus answers dynamixel-sdk, unchanged, as XM430 servos would."""

from __future__ import annotations

import math
import os
import time
from collections.abc import Iterator

import pytest
from dynamixel_sdk import (
    COMM_RX_CORRUPT,
    COMM_SUCCESS,
    COMM_TX_FAIL,
    GroupBulkRead,
    GroupSyncRead,
    GroupSyncWrite,
    PacketHandler,
    PortHandler,
    port_handler,
)

from humanoid_sim.dynamixel import control_table as ct
from humanoid_sim.dynamixel.bus import Bus
from humanoid_sim.dynamixel.plant import IdealPlant
from humanoid_sim.dynamixel.protocol import (
    Error,
    Instruction,
    Packet,
    Parser,
    crc16,
    encode,
    stuff,
    unstuff,
)
from humanoid_sim.dynamixel.pty import PACKET_TIMEOUT_S, PtyBus
from humanoid_sim.soccer.compose import LOCKSTEP_LATENCY_TIMER_MS

IDS = [1, 2, 3]
GOAL, PRESENT, TORQUE = 116, 132, 64


Rig = tuple[PtyBus, IdealPlant, PortHandler, PacketHandler]


@pytest.fixture(params=["pty", "direct"])
def rig(request: pytest.FixtureRequest, monkeypatch: pytest.MonkeyPatch) -> Iterator[Rig]:
    """The bus, its plant, a dynamixel-sdk port on it and a packet handler: every test
    that takes it runs through the pty (the SDK's own PortHandler, as a driver in another
    process) and through the port wired straight to the emulator (lockstep in one
    process)."""
    yield from _rig(monkeypatch, request.param)


@pytest.fixture
def pty_rig(monkeypatch: pytest.MonkeyPatch) -> Iterator[Rig]:
    """The rig through the pty only: for tests that write raw bytes to the device file."""
    yield from _rig(monkeypatch, "pty")


def _rig(monkeypatch: pytest.MonkeyPatch, kind: str) -> Iterator[Rig]:
    # dynamixel-sdk times replies on the wall clock: relaxed as in lockstep, so a loaded
    # machine cannot turn a slow emulator thread into a missing reply.
    monkeypatch.setattr(port_handler, "LATENCY_TIMER", LOCKSTEP_LATENCY_TIMER_MS)
    plant = IdealPlant()
    with PtyBus(Bus(IDS, plant)) as pty:
        port = PortHandler(pty.port) if kind == "pty" else pty.direct_port(pty.port)
        assert port.openPort() and port.setBaudRate(1_000_000)
        try:
            yield pty, plant, port, PacketHandler(2.0)
        finally:
            port.closePort()
        assert pty.errors == []


def test_crc_matches_the_documented_example() -> None:
    # e-Manual Protocol 2.0 ping example for ID 1: FF FF FD 00 01 03 00 01 19 4E
    assert encode(1, Instruction.PING) == bytes.fromhex("FFFFFD0001030001194E")
    assert crc16(bytes.fromhex("FFFFFD0001030001")) == 0x4E19


def test_stuffing_round_trips_and_the_parser_resyncs() -> None:
    body = b"\x03\xff\xff\xfd\x10"
    assert stuff(body) == b"\x03\xff\xff\xfd\xfd\x10" and unstuff(stuff(body)) == body
    packet = encode(7, Instruction.WRITE, b"\x74\x00\xff\xff\xfd\x00")
    parser = Parser()
    got = parser.feed(b"\x00\x17garbage" + packet[:5]) + parser.feed(packet[5:])
    assert len(got) == 1 and got[0].dxl_id == 7 and got[0].params == b"\x74\x00\xff\xff\xfd\x00"


def test_ping_read_write_through_the_sdk(rig) -> None:
    pty, plant, port, ph = rig
    model, result, error = ph.ping(port, 2)
    assert (model, result, error) == (ct.MODEL_NUMBER, COMM_SUCCESS, 0)
    assert ph.write1ByteTxRx(port, 2, TORQUE, 1)[0] == COMM_SUCCESS
    target = 2048 + 512  # +45 degrees
    assert ph.write4ByteTxRx(port, 2, GOAL, target)[0] == COMM_SUCCESS
    with pty.lock:
        plant.step(1.0)
    position, result, error = ph.read4ByteTxRx(port, 2, PRESENT)
    assert result == COMM_SUCCESS and error == 0 and position == target
    assert plant.state(2).position_rad == pytest.approx(math.pi / 4, abs=1e-3)


def test_sync_write_goals_and_sync_read_positions(rig) -> None:
    pty, plant, port, ph = rig
    writer = GroupSyncWrite(port, ph, TORQUE, 1)
    for i in IDS:
        writer.addParam(i, [1])
    assert writer.txPacket() == COMM_SUCCESS
    goals = GroupSyncWrite(port, ph, GOAL, 4)
    for i in IDS:
        goals.addParam(i, list((2048 + 100 * i).to_bytes(4, "little")))
    assert goals.txPacket() == COMM_SUCCESS
    # Sync write has no reply; the bus is ordered, so a ping's reply means it was applied.
    assert ph.ping(port, 1)[1] == COMM_SUCCESS
    with pty.lock:
        plant.step(1.0)
    reader = GroupSyncRead(port, ph, PRESENT, 4)
    for i in IDS:
        reader.addParam(i)
    assert reader.txRxPacket() == COMM_SUCCESS
    assert [reader.getData(i, PRESENT, 4) for i in IDS] == [2148, 2248, 2348]


def test_sync_waits_until_unanswered_writes_are_applied(pty_rig) -> None:
    pty, _, port, ph = pty_rig
    for round_ in range(20):  # without sync, some rounds would read the previous goal
        goals = GroupSyncWrite(port, ph, GOAL, 4)
        for i in IDS:
            goals.addParam(i, list((1000 + round_ + i).to_bytes(4, "little")))
        assert goals.txPacket() == COMM_SUCCESS
        assert pty.sync()
        assert [pty.bus.servos[i].get("goal_position") for i in IDS] == [
            1000 + round_ + i for i in IDS]
    assert pty.bus.packets == 20  # the markers are the emulator's own, not bus traffic


def test_a_direct_port_is_answered_before_the_write_returns() -> None:
    """Lockstep's port: what the driver wrote is applied when its write returns, the pty
    carries nothing to wait for, line noise garbles the same packets as on the pty (drawn
    in bus order from the seed), and a closed bus fails the write as a gone device does."""
    def goals_written(corrupt: float) -> tuple[list[int], int, int]:
        plant = IdealPlant()
        with PtyBus(Bus(IDS, plant), corrupt=corrupt, seed=3, packet_timeout_s=None) as pty:
            port, ph = pty.direct_port(pty.port), PacketHandler(2.0)
            assert port.openPort() and port.setBaudRate(1_000_000)
            results = []
            for round_ in range(30):
                goals = GroupSyncWrite(port, ph, GOAL, 4)
                for i in IDS:
                    goals.addParam(i, list((1000 + round_ + i).to_bytes(4, "little")))
                assert goals.txPacket() == COMM_SUCCESS
                results.append(ph.ping(port, 1)[1])
            # No sync: the last round's goals are the servos' (unless noise garbled it).
            goals_now = [pty.bus.servos[i].get("goal_position") for i in IDS]
            assert pty.sync()
            assert pty.bus.packets == 60  # and nothing went through the pty
            crc_errors = pty.bus.crc_errors
            pty.close()
            assert ph.ping(port, 1)[1] == COMM_TX_FAIL
            return goals_now, crc_errors, results.count(COMM_SUCCESS)

    assert goals_written(0.0) == ([1029 + i for i in IDS], 0, 30)
    noisy = goals_written(0.2)
    assert noisy[1] > 0 and noisy[2] < 30  # garbled requests and replies
    assert goals_written(0.2) == noisy  # the same packets, seed for seed


def test_bulk_read_different_fields(rig) -> None:
    _, _, port, ph = rig
    bulk = GroupBulkRead(port, ph)
    assert bulk.addParam(1, 0, 2) and bulk.addParam(3, 146, 1)
    assert bulk.txRxPacket() == COMM_SUCCESS
    assert bulk.getData(1, 0, 2) == ct.MODEL_NUMBER and bulk.getData(3, 146, 1) == 30


def test_torque_off_is_limp_and_limits_and_eeprom_are_enforced(rig) -> None:
    pty, plant, port, ph = rig
    ph.write4ByteTxRx(port, 1, GOAL, 3000)
    with pty.lock:
        plant.step(1.0)
    assert ph.read4ByteTxRx(port, 1, PRESENT)[0:1] == (2048,)  # torque off: did not move
    ph.write1ByteTxRx(port, 1, TORQUE, 1)
    assert ph.write1ByteTxRx(port, 1, 11, 1)[1] == Error.ACCESS  # EEPROM locked
    assert ph.write4ByteTxRx(port, 1, PRESENT, 5)[1] == Error.ACCESS  # read-only
    ph.write1ByteTxRx(port, 1, TORQUE, 0)
    assert ph.write4ByteTxRx(port, 1, 48, 3000)[1] == 0  # max position limit, torque off
    ph.write1ByteTxRx(port, 1, TORQUE, 1)
    assert ph.write4ByteTxRx(port, 1, GOAL, 3500)[1] == Error.DATA_LIMIT


def test_malformed_packets_get_what_a_servo_gives(pty_rig) -> None:
    pty, _, port, ph = pty_rig
    fd = os.open(pty.port, os.O_RDWR | os.O_NOCTTY)
    try:
        bad = bytearray(encode(1, Instruction.PING))
        bad[-1] ^= 0xFF
        os.write(fd, bytes(bad))
        unknown = encode(2, 0x42)
        os.write(fd, unknown)
        os.write(fd, encode(0xFE, Instruction.READ, b"\x00\x00\x02\x00"))  # ignored
        replies = Parser()
        got: list[Packet] = []
        while len(got) < 2:
            got += replies.feed(os.read(fd, 256))
    finally:
        os.close(fd)
    assert [(p.dxl_id, p.params[0]) for p in got] == [(1, Error.CRC), (2, Error.INSTRUCTION)]
    assert ph.ping(port, 1)[1] == COMM_SUCCESS  # still serving


def test_unplugged_servo_does_not_answer(rig) -> None:
    pty, _, port, ph = rig
    with pty.lock:
        pty.bus.servos[3].connected = False
    assert ph.ping(port, 3)[1] != COMM_SUCCESS
    ids, result = ph.broadcastPing(port)
    assert result == COMM_SUCCESS and sorted(ids) == [1, 2]


def _ask(bus: Bus, dxl_id: int, instruction: int, params: bytes = b"") -> list[Packet]:
    """What the bus answers one packet with, as status packets (no pty needed)."""
    return Parser().feed(bus.handle(Parser().feed(encode(dxl_id, instruction, params))[0]))


def _write(address: int, value: int, size: int) -> bytes:
    return address.to_bytes(2, "little") + value.to_bytes(size, "little", signed=True)


def test_writes_are_checked_like_the_e_manual_says() -> None:
    bus = Bus(IDS, IdealPlant())

    def error(params: bytes, instruction: int = Instruction.WRITE) -> int:
        (reply,) = _ask(bus, 1, instruction, params)
        return reply.params[0]

    assert error(_write(GOAL, 2048, 2)) == Error.DATA_LENGTH  # 2 bytes of a 4-byte item
    assert error(_write(GOAL + 1, 8, 1)) == Error.DATA_LENGTH
    assert error(_write(TORQUE, 2, 1)) == Error.DATA_RANGE  # torque enable is 0 or 1
    assert error(_write(84, 20000, 2)) == Error.DATA_RANGE  # gain beyond 16,383
    assert error(_write(102, 1194, 2)) == Error.DATA_LIMIT  # goal current > current limit
    assert error(_write(104, -201, 4)) == Error.DATA_LIMIT  # |goal velocity| > velocity limit
    assert error(_write(66, 0, 1)) == Error.ACCESS  # reserved address
    assert error(_write(150, 0, 1)) == Error.ACCESS  # reserved, between the areas
    assert error(_write(662, 0, 1)) == Error.ACCESS  # beyond the control table
    assert error(_write(PRESENT, 0, 4)) == Error.ACCESS  # read only
    assert error(b"", Instruction.ACTION) == Error.INSTRUCTION  # nothing registered
    assert error(b"\x00\x00\x02", Instruction.READ) == Error.DATA_LENGTH  # READ needs 4
    assert bus.servos[1].get("goal_position") == 2048  # nothing refused was written
    # Outside position control mode the position limits do not bound the goal.
    assert error(_write(11, 4, 1)) == Error.NONE  # extended position control
    assert error(_write(GOAL, 5000, 4)) == Error.NONE


def test_a_sync_write_of_new_ids_renumbers_every_servo_it_names() -> None:
    # Each servo reads the packet with the ID it had when the packet arrived: 1 -> 2 and
    # 2 -> 3 in one sync write renumber both (servo 1 is not addressed again as "2").
    bus = Bus(IDS, IdealPlant())
    params = b"\x07\x00\x01\x00" + b"\x01\x02" + b"\x02\x03"
    packet = Parser().feed(encode(0xFE, Instruction.SYNC_WRITE, params))[0]
    assert bus.handle(packet) == b""
    assert {i: servo.dxl_id for i, servo in bus.servos.items()} == {1: 2, 2: 3, 3: 3}


def test_homing_offset_is_added_to_the_present_position() -> None:
    plant = IdealPlant()
    bus = Bus(IDS, plant)
    servo = bus.servos[1]
    assert servo.write(20, (100).to_bytes(4, "little")) == Error.NONE
    assert servo.read(PRESENT, 4)[1] == (2148).to_bytes(4, "little")  # actual 2048 + 100
    servo.write(TORQUE, b"\x01")
    servo.write(GOAL, (2148).to_bytes(4, "little"))  # in present-position terms
    plant.step(1.0)
    assert plant.state(1).position_rad == 0.0  # the joint stays at its actual centre


def test_the_realtime_tick_counts_the_plants_time_not_the_wall_clock() -> None:
    # A lockstep run reads the same ticks at any load: milliseconds of simulated time,
    # wrapping at 32767 as on the servo.
    plant = IdealPlant()
    servo = Bus(IDS, plant).servos[1]
    tick = ct.BY_NAME["realtime_tick"].address
    plant.step(0.25)
    assert servo.read(tick, 2) == (Error.NONE, (250).to_bytes(2, "little"))
    plant.step(33.0)
    assert servo.read(tick, 2) == (Error.NONE, (33_250 % 32_768).to_bytes(2, "little"))


def test_reg_write_action_reboot_and_a_new_id() -> None:
    plant = IdealPlant()
    bus = Bus(IDS, plant)
    assert _ask(bus, 0xFE, Instruction.REG_WRITE, _write(TORQUE, 1, 1)) == []  # broadcast
    assert [s.get("registered_instruction") for s in bus.servos.values()] == [1, 1, 1]
    assert _ask(bus, 0xFE, Instruction.ACTION) == []
    assert [s.get("torque_enable") for s in bus.servos.values()] == [1, 1, 1]
    bus.servos[2].set_hardware_error(0x04)  # overheating
    (status,) = _ask(bus, 2, Instruction.PING)
    assert status.params[0] == 0x80 and bus.servos[2].get("torque_enable") == 0
    assert len(_ask(bus, 2, Instruction.REBOOT)) == 1
    assert _ask(bus, 2, Instruction.PING)[0].params[0] == 0  # cleared
    # A new ID takes effect at once; the servo still moves its own joint.
    bus.servos[3].write(TORQUE, b"\x00")
    assert len(_ask(bus, 3, Instruction.WRITE, _write(7, 9, 1))) == 1
    assert _ask(bus, 3, Instruction.PING) == []
    assert _ask(bus, 9, Instruction.PING)[0].dxl_id == 9
    _ask(bus, 9, Instruction.WRITE, _write(TORQUE, 1, 1))
    _ask(bus, 9, Instruction.WRITE, _write(GOAL, 2048 + 512, 4))
    plant.step(1.0)
    assert plant.state(3).position_rad == pytest.approx(math.pi / 4)


def test_status_return_level_silences_replies_but_not_ping() -> None:
    bus = Bus(IDS, IdealPlant())
    bus.servos[1].write(68, b"\x00")
    assert _ask(bus, 1, Instruction.WRITE, _write(TORQUE, 1, 1)) == []
    assert _ask(bus, 1, Instruction.READ, b"\x84\x00\x04\x00") == []
    sync_read = b"\x84\x00\x04\x00\x01\x02"
    assert [p.dxl_id for p in _ask(bus, 0xFE, Instruction.SYNC_READ, sync_read)] == [2]
    assert len(_ask(bus, 1, Instruction.PING)) == 1
    bus.servos[1].write(68, b"\x01")
    assert _ask(bus, 1, Instruction.WRITE, _write(TORQUE, 0, 1)) == []
    assert len(_ask(bus, 1, Instruction.READ, b"\x84\x00\x04\x00")) == 1


@pytest.mark.parametrize("garbage", [
    b"\xff\xff\xfd\x00\x01\xff\xff",  # a header with an absurd length
    b"\xff\xff\xfd\x00\x01\xf4\x01",  # a length of 500 that never arrives
    b"\xff\xff\xfd\x00\x01\x01\x00\x02",  # a length too short for any packet
    encode(1, Instruction.SYNC_WRITE, b"\x74\x00\x04"),  # sync write not broadcast
    encode(0xFE, Instruction.SYNC_WRITE, b"\x74\x00\x04\x00\x01\x00"),  # cut short
    encode(0xFE, Instruction.BULK_READ, b"\x01\x84"),
    encode(0xFE, Instruction.FACTORY_RESET, b"\xff"),
    encode(1, Instruction.FACTORY_RESET, b""),
    bytes(range(256)) * 4,
])
def test_malformed_input_never_stops_the_bus(pty_rig, garbage: bytes) -> None:
    pty, _, port, ph = pty_rig
    fd = os.open(pty.port, os.O_RDWR | os.O_NOCTTY)
    try:
        os.write(fd, garbage)
    finally:
        os.close(fd)
    # The servos answer again at once, or (a packet cut short) once they have dropped it.
    deadline = time.monotonic() + PACKET_TIMEOUT_S + 10 * LOCKSTEP_LATENCY_TIMER_MS / 1000
    while ph.ping(port, 1)[1] != COMM_SUCCESS:
        assert time.monotonic() < deadline, "the bus stopped answering"
        port.clearPort()
    assert pty.errors == []
    assert (pty.discarded_bytes > 0) == garbage.startswith(b"\xff\xff\xfd\x00\x01\xf4")


def test_factory_reset_and_clear() -> None:
    bus = Bus(IDS, IdealPlant())
    servo = bus.servos[2]
    servo.write(36, (500).to_bytes(2, "little"))  # PWM limit
    assert servo.get("pwm_limit") == 500
    (status,) = _ask(bus, 2, Instruction.FACTORY_RESET, b"\x01")  # all but the ID
    assert status.params[0] == Error.NONE
    assert servo.get("pwm_limit") == 885 and servo.dxl_id == 2
    servo.write(36, (500).to_bytes(2, "little"))
    assert _ask(bus, 0xFE, Instruction.FACTORY_RESET, b"\xff") == []  # never by broadcast
    assert servo.get("pwm_limit") == 500
    assert _ask(bus, 0xFE, Instruction.FACTORY_RESET, b"\x02") == []  # but keeping IDs
    assert servo.get("pwm_limit") == 885 and [s.dxl_id for s in bus.servos.values()] == IDS
    assert _ask(bus, 2, Instruction.FACTORY_RESET, b"\x07")[0].params[0] == Error.DATA_RANGE
    clear = b"\x01\x44\x58\x4c\x22"
    assert _ask(bus, 2, Instruction.CLEAR, clear)[0].params[0] == Error.NONE  # standing still
    assert _ask(bus, 2, Instruction.CLEAR, b"\x02")[0].params[0] == Error.DATA_RANGE


# -- Fast Sync Read and Fast Bulk Read -------------------------------------------------------

#: The e-Manual's Fast Sync Read example (Protocol 2.0): present position of IDs 3, 7 and 4.
EMANUAL_FAST_REQUEST = bytes.fromhex("FFFFFD00FE0A008A84000400030704 20F2".replace(" ", ""))
EMANUAL_FAST_STATUS = bytes.fromhex(
    "FFFFFD00FE19005500 03A6000000 8408"  # header and ID 3's block with its CRC
    "0007 1F080000 16CA"  # ID 7: error, ID, data, CRC of everything before
    "0004 FF030000 D19E".replace(" ", "")  # ID 4: the last CRC is the packet's
)


def _emanual_bus() -> Bus:
    """IDs 3, 7 and 4 at present positions 166, 2079 and 1023 (through the homing offset)."""
    bus = Bus([3, 7, 4], IdealPlant())
    for dxl_id, position in ((3, 166), (7, 2079), (4, 1023)):
        bus.servos[dxl_id].write(20, (position - 2048).to_bytes(4, "little", signed=True))
    return bus


def _raw(bus: Bus, request: bytes) -> bytes:
    return bus.handle(Parser().feed(request)[0])


def test_fast_sync_read_answers_the_e_manual_example_byte_for_byte() -> None:
    assert encode(0xFE, Instruction.FAST_SYNC_READ, bytes.fromhex("840004000307 04")
                  .replace(b" ", b"")) == EMANUAL_FAST_REQUEST
    bus = _emanual_bus()
    assert _raw(bus, EMANUAL_FAST_REQUEST) == EMANUAL_FAST_STATUS
    assert bus.instructions[Instruction.FAST_SYNC_READ] == 1


def test_fast_sync_read_stops_at_a_silent_servo() -> None:
    bus = _emanual_bus()
    bus.servos[7].connected = False
    # ID 3 announces the whole packet and sends its block; ID 4 waits for ID 7 in vain.
    assert _raw(bus, EMANUAL_FAST_REQUEST) == EMANUAL_FAST_STATUS[:16]
    bus.servos[7].connected = True
    bus.servos[7].write(68, b"\x00")  # status return level 0: silent too
    assert _raw(bus, EMANUAL_FAST_REQUEST) == EMANUAL_FAST_STATUS[:16]
    bus.servos[3].connected = False  # the first is silent: nobody starts the packet
    assert _raw(bus, EMANUAL_FAST_REQUEST) == b""


def test_fast_sync_read_broadcast_and_error_rules() -> None:
    bus = _emanual_bus()
    # Only by broadcast: addressed to one servo it is an instruction error, like Sync Read.
    (reply,) = _ask(bus, 3, Instruction.FAST_SYNC_READ, b"\x84\x00\x04\x00\x03")
    assert (reply.dxl_id, reply.params[0]) == (3, Error.INSTRUCTION)
    garbled = bytearray(EMANUAL_FAST_REQUEST)
    garbled[-1] ^= 1
    assert _raw(bus, bytes(garbled)) == b""  # bad CRC, broadcast: no answer
    # A latched hardware error sets the alert bit in that servo's block only.
    bus.servos[7].set_hardware_error(0x20)
    reply_bytes = _raw(bus, EMANUAL_FAST_REQUEST)
    assert [reply_bytes[8], reply_bytes[16], reply_bytes[24]] == [0, 0x80, 0]
    # A read the servos refuse keeps the layout: each block has its error and zeros.
    beyond = _raw(bus, encode(0xFE, Instruction.FAST_SYNC_READ, b"\x94\x02\x04\x00\x03\x04"))
    assert beyond[5:7] == (1 + 2 * 8).to_bytes(2, "little")
    assert beyond[8:14] == bytes([Error.ACCESS, 3, 0, 0, 0, 0])
    assert beyond[16:18] == bytes([Error.ACCESS, 4])
    assert crc16(beyond[:-2]) == int.from_bytes(beyond[-2:], "little")


def test_servos_before_firmware_45_ignore_fast_reads() -> None:
    bus = Bus(IDS, IdealPlant(), firmware_version=44)
    assert _raw(bus, encode(0xFE, Instruction.FAST_SYNC_READ, b"\x84\x00\x04\x00\x01\x02")) == b""
    (reply,) = _ask(bus, 1, Instruction.READ, b"\x06\x00\x01\x00")
    assert reply.params == bytes([0, 44])  # the firmware version says so (also after reset)
    bus.servos[2].firmware_version = 45
    only_2 = _raw(bus, encode(0xFE, Instruction.FAST_SYNC_READ, b"\x84\x00\x04\x00\x02\x01"))
    assert only_2[9] == 2 and len(only_2) == 7 + 1 + 8  # ID 2's block, then ID 1 is silent


def test_fast_sync_and_bulk_read_through_the_sdk(rig) -> None:
    pty, plant, port, ph = rig
    goals = GroupSyncWrite(port, ph, GOAL, 4)
    for i in IDS:
        assert ph.write1ByteTxRx(port, i, TORQUE, 1)[0] == COMM_SUCCESS
        goals.addParam(i, list((2048 + 100 * i).to_bytes(4, "little")))
    assert goals.txPacket() == COMM_SUCCESS
    assert pty.sync()
    with pty.lock:
        plant.step(1.0)
    reader = GroupSyncRead(port, ph, PRESENT, 4)
    for i in IDS:
        reader.addParam(i)
    assert reader.fastSyncRead() == COMM_SUCCESS
    assert [reader.getData(i, PRESENT, 4) for i in IDS] == [2148, 2248, 2348]
    bulk = GroupBulkRead(port, ph)
    assert bulk.addParam(1, 0, 2) and bulk.addParam(3, 146, 1)
    assert bulk.fastBulkRead() == COMM_SUCCESS
    assert bulk.getData(1, 0, 2) == ct.MODEL_NUMBER and bulk.getData(3, 146, 1) == 30
    assert pty.bus.instructions[Instruction.FAST_SYNC_READ] == 1
    assert pty.bus.instructions[Instruction.FAST_BULK_READ] == 1


def test_the_sdk_keeps_nothing_of_a_fast_sync_read_cut_short(rig) -> None:
    pty, _, port, ph = rig
    with pty.lock:
        pty.bus.servos[3].connected = False
    reader = GroupSyncRead(port, ph, PRESENT, 4)
    for i in IDS:
        reader.addParam(i)
    # Servos 1 and 2 sent their blocks, but the packet never completes: the SDK waits for
    # it, calls it corrupt and drops it whole. A driver must read the others another way.
    assert reader.fastSyncRead() == COMM_RX_CORRUPT
    assert not any(reader.isAvailable(i, PRESENT, 4) for i in IDS)
    assert ph.ping(port, 1)[1] == COMM_SUCCESS  # and the bus serves the next request


# -- the indirect address area -------------------------------------------------------------


def test_indirect_addresses_gather_items_for_one_sync_read(rig) -> None:
    pty, plant, port, ph = rig
    for i in IDS:  # Indirect Data 1..8 (224..) = present position (132..), then velocity (128..)
        for k, target in enumerate([*range(132, 136), *range(128, 132)]):
            result, error = ph.write2ByteTxRx(port, i, 168 + 2 * k, target)
            assert (result, error) == (COMM_SUCCESS, 0)
        assert ph.write1ByteTxRx(port, i, TORQUE, 1)[0] == COMM_SUCCESS
        # Indirect Data 29..32 (634..) = goal position (116..): written through them.
        for k in range(4):
            assert ph.write2ByteTxRx(port, i, 578 + 2 * k, 116 + k)[1] == 0
        assert ph.write4ByteTxRx(port, i, 634, 2048 + 100 * i)[1] == 0
    assert [pty.bus.servos[i].get("goal_position") for i in IDS] == [2148, 2248, 2348]
    with pty.lock:
        plant.step(1.0)
    reader = GroupSyncRead(port, ph, 224, 8)
    for i in IDS:
        reader.addParam(i)
    assert reader.fastSyncRead() == COMM_SUCCESS
    assert [reader.getData(i, 224, 4) for i in IDS] == [2148, 2248, 2348]
    assert ph.read4ByteTxRx(port, 2, 634)[0] == 2248  # reads give the named bytes too


def test_indirect_data_inherits_the_named_items_rules() -> None:
    bus = Bus(IDS, IdealPlant())
    servo = bus.servos[1]
    assert servo.get("indirect_address_1") == 224 and servo.get("indirect_address_29") == 634
    assert servo.write(224, b"\x07") == Error.NONE  # by default: plain storage
    assert servo.read(224, 1) == (Error.NONE, b"\x07")
    assert servo.write(168, (63).to_bytes(2, "little")) == Error.DATA_RANGE  # EEPROM: no
    assert servo.write(168, (662).to_bytes(2, "little")) == Error.DATA_RANGE
    for k in range(4):  # Indirect Data 1..4 = present position: read only
        assert servo.write(168 + 2 * k, (132 + k).to_bytes(2, "little")) == Error.NONE
    assert servo.write(224, bytes(4)) == Error.ACCESS
    for k in range(4):  # now goal position: a 4-byte item, its limits included
        servo.write(168 + 2 * k, (116 + k).to_bytes(2, "little"))
    assert servo.write(224, bytes(2)) == Error.DATA_LENGTH  # two bytes of four
    servo.write(TORQUE, b"\x01")
    assert servo.write(224, (5000).to_bytes(4, "little")) == Error.DATA_LIMIT
    assert servo.get("goal_position") == 2048  # nothing refused was written
    assert servo.write(224, (3000).to_bytes(4, "little")) == Error.NONE
    assert servo.get("goal_position") == 3000
    # Naming another Indirect Data byte does not chain: the byte is plain storage again.
    servo.write(168, (225).to_bytes(2, "little"))
    assert servo.read(224, 1)[1] == b"\x07" and servo.read(225, 1)[1] == b"\x0b"  # 3000 >> 8
