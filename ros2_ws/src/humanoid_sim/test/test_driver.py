"""The servo driver, dynamixel-sdk unchanged, against the emulated bus (no MuJoCo here)."""

from __future__ import annotations

import math
from collections.abc import Iterator
from pathlib import Path

import pytest
from diagnostic_msgs.msg import DiagnosticStatus
from sensor_msgs.msg import JointState

from efficient_comm.testing import TestHandle, test_container
from humanoid_sim.driver import SDK_LATENCY_TIMER_MS, ServoDriver
from humanoid_sim.dynamixel.bus import Bus
from humanoid_sim.dynamixel.plant import IdealPlant
from humanoid_sim.dynamixel.protocol import Instruction
from humanoid_sim.dynamixel.pty import PtyBus
from humanoid_sim.errors import SimConfigError
from humanoid_sim.soccer.compose import LOCKSTEP_LATENCY_TIMER_MS

IDS = [1, 2, 3]
NAMES = ["neck_yaw", "neck_pitch", "hip_roll"]


#: The manual clock stops for nothing, but dynamixel-sdk times replies on the wall clock:
#: relaxed as in a composed lockstep run, so a loaded machine cannot fake a missing servo.
LOCKSTEP = {"latency_timer_ms": LOCKSTEP_LATENCY_TIMER_MS}


def _driver(pty: PtyBus, **extra: object) -> tuple[TestHandle, ServoDriver]:
    extra = {**LOCKSTEP, **extra}
    node = TestHandle("driver", container=test_container(),
                      parameters={"port": pty.port, "ids": IDS, "joint_names": NAMES, **extra})
    return node, ServoDriver(node)


@pytest.fixture
def bus() -> Iterator[tuple[PtyBus, IdealPlant]]:
    plant = IdealPlant()
    with PtyBus(Bus(IDS, plant)) as pty:
        yield pty, plant


def _last_state(node: TestHandle) -> dict[str, float]:
    msg = node.published("joint_states")[-1]
    return dict(zip(msg.name, msg.position, strict=True))


def test_reaches_commanded_positions(bus: tuple[PtyBus, IdealPlant]) -> None:
    pty, plant = bus
    node, driver = _driver(pty)
    node.advance(0.01)
    assert driver.status()["present"] == IDS
    targets = {"neck_yaw": 0.5, "neck_pitch": -0.3, "hip_roll": 1.0}
    node.inject("joint_commands", JointState(name=list(targets), position=list(targets.values())))
    for _ in range(50):
        node.advance(0.01)
        with pty.lock:
            plant.step(0.01)
    state = _last_state(node)
    for name, target in targets.items():
        assert state[name] == pytest.approx(target, abs=2 * math.pi / 4096)
    driver.close()


def _diagnostics(node: TestHandle) -> dict[str, DiagnosticStatus]:
    statuses = node.published("/diagnostics")[-1].status
    return {s.name.split("(")[1].rstrip(")"): s for s in statuses}


def test_reads_all_servos_with_one_fast_sync_read_per_cycle(
        bus: tuple[PtyBus, IdealPlant]) -> None:
    pty, _ = bus
    node, driver = _driver(pty)
    node.advance(1.0)
    assert driver.fast_servos == IDS
    sent = pty.bus.instructions
    assert sent[Instruction.FAST_SYNC_READ] == driver.cycles + 1  # + the hardware errors
    assert sent[Instruction.SYNC_READ] == 0
    assert all(set(m.name) == set(NAMES) for m in node.published("joint_states"))
    driver.close()


@pytest.mark.parametrize(("firmware", "parameters"), [
    (44, {}),  # servos that do not know it
    (45, {"fast_sync_read": False}),  # turned off
])
def test_plain_sync_read_without_fast_sync_read(
        firmware: int, parameters: dict[str, object]) -> None:
    with PtyBus(Bus(IDS, IdealPlant(), firmware_version=firmware)) as pty:
        node, driver = _driver(pty, **parameters)
        node.advance(0.5)
        assert driver.fast_servos == []
        assert pty.bus.instructions[Instruction.FAST_SYNC_READ] == 0
        assert pty.bus.instructions[Instruction.SYNC_READ] == driver.cycles + 1
        assert all(set(m.name) == set(NAMES) for m in node.published("joint_states"))
        driver.close()


def test_fast_sync_read_that_keeps_failing_is_given_up(bus: tuple[PtyBus, IdealPlant]) -> None:
    pty, _ = bus
    node, driver = _driver(pty)
    node.advance(0.01)
    with pty.lock:  # says firmware 45 but does not take part (as a servo in the way might)
        pty.bus.servos[2].firmware_version = 44
    node.advance(0.5)
    warnings = [text for level, text in node.records if level == "warning"]
    assert warnings == ["fast sync read failed 10 times in a row while sync read worked: "
                        "using sync read"]
    # The first cycle's two (states, hardware errors), ten that failed, and no more.
    assert pty.bus.instructions[Instruction.FAST_SYNC_READ] == 2 + 10
    assert driver.fast_servos == [] and driver.status()["present"] == IDS
    assert all(set(m.name) == set(NAMES) for m in node.published("joint_states"))
    driver.close()


@pytest.mark.parametrize("unplugged", [1, 2, 3])  # first in the sync read: it used to hide all
def test_an_unplugged_servo_is_reported_and_taken_back(
        bus: tuple[PtyBus, IdealPlant], unplugged: int) -> None:
    pty, _ = bus
    node, driver = _driver(pty)
    node.advance(0.01)
    gone = NAMES[IDS.index(unplugged)]
    with pty.lock:
        pty.bus.servos[unplugged].connected = False
    before = len(node.published("joint_states"))
    node.advance(1.0)  # ten missed reads, then reported
    states = [set(m.name) for m in node.published("joint_states")[before:]]
    others = set(NAMES) - {gone}
    assert len(states) == 100
    assert all(others <= names for names in states[1:])  # hidden for one cycle at most
    assert gone not in states[-1]
    diag = _diagnostics(node)
    assert diag[gone].level == DiagnosticStatus.ERROR and diag[gone].message == "not answering"
    assert {diag[name].level for name in others} == {DiagnosticStatus.OK}
    warnings = [text for level, text in node.records if level == "warning"]
    assert warnings == [f"servo {unplugged} did not answer 10 times in a row"]  # no other
    # The others are still read with one Fast Sync Read per cycle; the silent one costs no
    # more plain reads once given up (it is pinged once a second instead).
    sent = dict(pty.bus.instructions)
    node.advance(0.5)
    assert pty.bus.instructions[Instruction.FAST_SYNC_READ] - sent[Instruction.FAST_SYNC_READ] == 50
    assert pty.bus.instructions[Instruction.SYNC_READ] == sent[Instruction.SYNC_READ]
    assert driver.fast_servos == sorted(set(IDS) - {unplugged})
    with pty.lock:
        pty.bus.servos[unplugged].connected = True
    node.advance(1.1)
    assert gone in _last_state(node)
    assert _diagnostics(node)[gone].level == DiagnosticStatus.OK
    driver.close()


def test_a_hardware_error_is_reported_until_the_servo_is_rebooted(
        bus: tuple[PtyBus, IdealPlant]) -> None:
    pty, _ = bus
    node, driver = _driver(pty)
    node.advance(1.0)
    assert _diagnostics(node)["neck_pitch"].level == DiagnosticStatus.OK
    with pty.lock:
        pty.bus.servos[2].set_hardware_error(0x20)  # overload: torque off, alert bit set
    node.advance(1.0)
    diag = _diagnostics(node)
    assert diag["neck_pitch"].level == DiagnosticStatus.ERROR
    assert diag["neck_pitch"].message == "hardware error status 0x20"
    assert diag["neck_yaw"].level == DiagnosticStatus.OK
    assert set(_last_state(node)) == set(NAMES)  # still read: it answers, with the alert
    with pty.lock:
        pty.bus.servos[2].reset(keep=(), ram_only=True)  # what REBOOT does
    node.advance(1.0)
    assert _diagnostics(node)["neck_pitch"].level == DiagnosticStatus.OK
    driver.close()


def test_line_noise_is_counted_and_survived() -> None:
    plant = IdealPlant()
    with PtyBus(Bus(IDS, plant), corrupt=0.2, seed=3) as pty:
        # The SDK's stock timeouts: nothing here depends on them, and relaxed ones would
        # make every garbled request cost half a second.
        node, driver = _driver(pty, latency_timer_ms=SDK_LATENCY_TIMER_MS)
        for _ in range(100):
            node.advance(0.01)
        assert driver.comm_errors > 0 and pty.bus.packets > 100
        assert pty.bus.crc_errors > 0  # noise both ways: garbled requests refused too
        assert len(node.published("joint_states")) > 50  # most cycles still got through
        assert pty.errors == []
        # Noise is no reason to give Fast Sync Read up: still tried (nearly) every cycle.
        assert not any("fast sync read" in text for _, text in node.records)
        assert pty.bus.instructions[Instruction.FAST_SYNC_READ] >= 80
        driver.close()


@pytest.mark.parametrize("seed", range(6))
def test_torque_is_on_within_a_few_cycles_despite_garbled_start_up_writes(seed: int) -> None:
    """A ping, a torque write or its reply garbled at start-up used to leave the servo limp
    until the next retry a second later (a standing robot fell): the driver pings again,
    reads Torque Enable back and tries again every cycle."""
    with PtyBus(Bus(IDS, IdealPlant()), corrupt=0.2, seed=seed) as pty:
        node, driver = _driver(pty, latency_timer_ms=SDK_LATENCY_TIMER_MS)
        for _ in range(5):
            node.advance(0.01)
        with pty.lock:
            torque = {i: pty.bus.servos[i].get("torque_enable") for i in IDS}
        assert torque == dict.fromkeys(IDS, 1), (seed, torque)
        assert driver.status()["present"] == IDS
        driver.close()


def test_a_missing_port_is_reported_not_fatal() -> None:
    node = TestHandle("driver", parameters={"port": "/dev/does_not_exist", "ids": [1]})
    driver = ServoDriver(node)
    node.advance(2.0)
    status = node.published("/diagnostics")[-1].status[0]
    assert status.level == DiagnosticStatus.ERROR and status.message == "port not open"
    assert driver.cycles > 100
    assert any("cannot open" in text for level, text in node.records if level == "error")


def test_a_port_that_goes_away_is_reopened(tmp_path: Path) -> None:
    link = tmp_path / "ttyDXL"  # as udev names an adapter: the device behind it changes
    plant = IdealPlant()
    first = PtyBus(Bus(IDS, plant))
    link.symlink_to(first.port)
    node = TestHandle("driver", parameters={"port": str(link), "ids": IDS, **LOCKSTEP})
    driver = ServoDriver(node)
    node.advance(0.01)
    assert driver.status()["present"] == IDS
    first.close()  # the adapter is unplugged
    node.advance(0.05)
    assert any("lost" in text for level, text in node.records if level == "error")
    assert driver.status()["present"] == []
    with PtyBus(Bus(IDS, plant)) as second:  # and plugged in again
        link.unlink()
        link.symlink_to(second.port)
        node.advance(1.0)
        assert driver.status()["present"] == IDS
        assert len(node.published("joint_states")[-1].name) == len(IDS)
        driver.close()


@pytest.mark.parametrize("parameters", [
    {"ids": [1, 1]}, {"ids": [253]}, {"ids": [1, 2], "joint_names": ["a", "a"]},
    {"ids": [1, 2], "joint_names": ["a"]}, {"latency_timer_ms": 0.0},
])
def test_bad_driver_parameters_are_refused(parameters: dict[str, object]) -> None:
    with pytest.raises(SimConfigError):
        ServoDriver(TestHandle("driver", parameters=parameters))
