"""The servo driver, dynamixel-sdk unchanged, against the emulated bus (no MuJoCo here)."""

from __future__ import annotations

import math
from collections.abc import Iterator

import pytest
from diagnostic_msgs.msg import DiagnosticStatus
from sensor_msgs.msg import JointState

from efficient_comm.testing import TestHandle, test_container
from humanoid_sim.driver import ServoDriver
from humanoid_sim.dynamixel.bus import Bus
from humanoid_sim.dynamixel.plant import IdealPlant
from humanoid_sim.dynamixel.pty import PtyBus

IDS = [1, 2, 3]
NAMES = ["neck_yaw", "neck_pitch", "hip_roll"]


def _driver(pty: PtyBus, **extra: object) -> tuple[TestHandle, ServoDriver]:
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


def test_an_unplugged_servo_is_reported_and_taken_back(bus: tuple[PtyBus, IdealPlant]) -> None:
    pty, _ = bus
    node, driver = _driver(pty)
    node.advance(0.01)
    with pty.lock:
        pty.bus.servos[3].connected = False
    node.advance(1.0)  # ten missed reads, then reported
    assert "hip_roll" not in _last_state(node)
    assert set(_last_state(node)) == {"neck_yaw", "neck_pitch"}  # the others keep going
    diag = {s.name.split("(")[1].rstrip(")"): s for s in node.published("/diagnostics")[-1].status}
    assert diag["hip_roll"].level == DiagnosticStatus.ERROR
    assert diag["neck_yaw"].level == DiagnosticStatus.OK
    with pty.lock:
        pty.bus.servos[3].connected = True
    node.advance(1.1)
    assert "hip_roll" in _last_state(node)
    driver.close()


def test_line_noise_is_counted_and_survived() -> None:
    plant = IdealPlant()
    with PtyBus(Bus(IDS, plant), corrupt=0.2, seed=3) as pty:
        node, driver = _driver(pty)
        for _ in range(100):
            node.advance(0.01)
        assert driver.comm_errors > 0 and pty.bus.packets > 100
        assert len(node.published("joint_states")) > 50  # most cycles still got through
        assert pty.errors == []
        driver.close()


def test_a_missing_port_is_reported_not_fatal() -> None:
    node = TestHandle("driver", parameters={"port": "/dev/does_not_exist", "ids": [1]})
    driver = ServoDriver(node)
    node.advance(2.0)
    status = node.published("/diagnostics")[-1].status[0]
    assert status.level == DiagnosticStatus.ERROR and status.message == "port not open"
    assert driver.cycles > 100
    assert any("cannot open" in text for level, text in node.records if level == "error")
