"""The driver, through dynamixel-sdk and the emulated bus, moves MuJoCo joints (lockstep)."""

from __future__ import annotations

import pytest
from sensor_msgs.msg import JointState

from efficient_comm.testing import TestHandle
from humanoid_sim.driver import ServoDriver
from humanoid_sim.dynamixel.bus import Bus
from humanoid_sim.dynamixel.pty import PtyBus
from humanoid_sim.mujoco_plant import JOINTS, MujocoPlant
from humanoid_sim.soccer.compose import LOCKSTEP_LATENCY_TIMER_MS

DT = 0.01


def _lockstep(node: TestHandle, pty: PtyBus, plant: MujocoPlant, seconds: float) -> None:
    for _ in range(round(seconds / DT)):
        node.advance(DT)
        with pty.lock:
            plant.step(DT)


def test_the_model_has_the_robot_a_kid_size_league_uses() -> None:
    plant = MujocoPlant()
    assert len(JOINTS) == 20 and plant.model.nu == 20
    assert 3.0 < plant.model.body_subtreemass[plant.model.body("torso").id] < 5.0
    assert 0.35 < plant.torso_height() < 0.45


def test_driver_reaches_commands_and_torque_off_is_limp() -> None:
    plant = MujocoPlant()
    with PtyBus(Bus(JOINTS, plant)) as pty:
        node = TestHandle("driver", parameters={
            "port": pty.port, "ids": list(JOINTS), "joint_names": list(JOINTS.values()),
            "latency_timer_ms": LOCKSTEP_LATENCY_TIMER_MS,  # wall-time replies: see compose
        })
        driver = ServoDriver(node)
        _lockstep(node, pty, plant, 0.05)
        assert driver.status()["present"] == list(JOINTS)
        crouch = {f"{side}_{joint}": angle for side in "lr"
                  for joint, angle in (("hip_pitch", -0.5), ("knee", 1.0), ("ankle_pitch", -0.5))}
        command = {"neck_yaw": 0.6, "l_elbow": -1.0, **crouch}
        node.inject("joint_commands", JointState(name=list(command),
                                                 position=list(command.values())))
        _lockstep(node, pty, plant, 1.5)
        state = dict(zip(node.published("joint_states")[-1].name,
                         node.published("joint_states")[-1].position, strict=True))
        assert state["neck_yaw"] == pytest.approx(0.6, abs=0.03)
        assert state["l_elbow"] == pytest.approx(-1.0, abs=0.05)
        assert state["l_knee"] == pytest.approx(1.0, abs=0.1)
        standing = plant.torso_height()
        assert standing > 0.3  # stiff joints hold the crouching robot up
        for dxl_id in JOINTS:  # torque off: bent knees give way
            with pty.lock:
                pty.bus.servos[dxl_id].write(64, b"\x00")
        _lockstep(node, pty, plant, 1.5)
        assert plant.torso_height() < standing - 0.05
        driver.close()
