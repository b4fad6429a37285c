"""The driver, through dynamixel-sdk and the emulated bus, moves MuJoCo joints (lockstep)."""

from __future__ import annotations

import math

import pytest
from sensor_msgs.msg import JointState

from efficient_comm.testing import TestHandle
from humanoid_sim.driver import ServoDriver
from humanoid_sim.dynamixel.bus import Bus
from humanoid_sim.dynamixel.pty import PtyBus
from humanoid_sim.joints import JOINTS
from humanoid_sim.mujoco_plant import (
    GEAR_RATIO,
    NO_LOAD_SPEED_RAD_S,
    ROTOR_INERTIA_KG_M2,
    STALL_CURRENT_A,
    STALL_TORQUE_NM,
    MujocoPlant,
)
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


# -- the servos' motor model (XM430-W350 at 12 V) -------------------------------------------

ADDR_TORQUE, ADDR_PROFILE_VELOCITY, ADDR_GOAL = 64, 112, 116
FASTEST_PROFILE = 32767  # 0.229 rpm units: 7,500 rpm asked for, far beyond the motor
NO_LOAD_RPM = 46.0


def _servo_id(name: str) -> int:
    return next(i for i, joint in JOINTS.items() if joint == name)


def _go(bus: Bus, dxl_id: int, goal_rad: float, *, profile: int = FASTEST_PROFILE) -> None:
    """Through the emulated servo's control table, as a driver's writes would arrive."""
    servo = bus.servos[dxl_id]
    ticks = round(goal_rad * 4096 / (2 * math.pi)) + 2048
    assert servo.write(ADDR_PROFILE_VELOCITY, profile.to_bytes(4, "little")) == 0
    assert servo.write(ADDR_TORQUE, b"\x01") == 0
    assert servo.write(ADDR_GOAL, ticks.to_bytes(4, "little")) == 0


def _rpm(rad_s: float) -> float:
    return abs(rad_s) * 60 / (2 * math.pi)


@pytest.mark.parametrize("joint", ["neck_yaw", "l_elbow", "r_shoulder_pitch"])
@pytest.mark.parametrize("profile", [FASTEST_PROFILE, 0])  # 0: no profile, "infinite"
def test_a_large_step_never_turns_a_joint_faster_than_the_no_load_speed(
        joint: str, profile: int) -> None:
    plant = MujocoPlant()
    plant.model.opt.gravity[:] = 0.0  # no load: gravity could drive the joint, not the motor
    bus = Bus(JOINTS, plant)
    dxl_id = _servo_id(joint)
    low, high = plant.model.joint(joint).range
    _go(bus, dxl_id, low + 0.1, profile=profile)
    plant.step(1.0)
    _go(bus, dxl_id, high - 0.1, profile=profile)
    peak, moved_from = 0.0, plant.state(dxl_id).position_rad
    for _ in range(500):
        plant.step(DT / 5)
        peak = max(peak, _rpm(plant.state(dxl_id).velocity_rad_s))
    assert plant.state(dxl_id).position_rad - moved_from > 1.5  # it did make the big move
    assert NO_LOAD_RPM * 0.9 < peak <= NO_LOAD_RPM * 1.01  # as fast as the motor, no faster


@pytest.mark.parametrize("load_nm", [0.0, 1.0, 2.0, 3.0])
def test_under_load_the_speed_falls_along_the_torque_speed_line(load_nm: float) -> None:
    plant = MujocoPlant()
    plant.model.opt.gravity[:] = 0.0  # the load is the one torque applied, nothing else
    bus = Bus(JOINTS, plant)
    dxl_id = _servo_id("l_shoulder_pitch")
    _go(bus, dxl_id, -2.9)
    plant.step(1.5)
    dof = plant.model.joint("l_shoulder_pitch").dofadr[0]
    plant.data.qfrc_applied[dof] = -load_nm  # opposes the move toward +2.9 rad
    _go(bus, dxl_id, 2.9)
    while plant.state(dxl_id).position_rad < 0.0:  # half way: long past accelerating
        plant.step(DT / 5)
        assert plant.data.time < 10.0
    speed = plant.state(dxl_id).velocity_rad_s
    # The line through stall torque (4.1 N m, standing still) and no-load speed (46 rpm).
    expected = NO_LOAD_SPEED_RAD_S * (1 - load_nm / STALL_TORQUE_NM)
    assert speed == pytest.approx(expected, abs=0.03 * NO_LOAD_SPEED_RAD_S)
    # The current follows the torque: the load's share of the stall current (2.3 A).
    assert plant.state(dxl_id).current_a == pytest.approx(
        load_nm / STALL_TORQUE_NM * STALL_CURRENT_A, abs=0.05)


def test_the_servo_figures_in_the_model_follow_from_the_datasheet() -> None:
    plant = MujocoPlant()
    bus = Bus(JOINTS, plant)
    for dxl_id, name in JOINTS.items():
        joint, actuator = plant.model.joint(name), plant.model.actuator(name)
        dof = joint.dofadr[0]
        assert plant.model.dof_damping[dof] == 0.0  # torque off: limp, no back-EMF
        assert bus.servos[dxl_id].write(ADDR_TORQUE, b"\x01") == 0
        assert tuple(actuator.forcerange) == pytest.approx((-STALL_TORQUE_NM, STALL_TORQUE_NM))
        assert plant.model.dof_damping[dof] == pytest.approx(
            STALL_TORQUE_NM / NO_LOAD_SPEED_RAD_S, rel=1e-3)
        assert joint.armature[0] == pytest.approx(GEAR_RATIO**2 * ROTOR_INERTIA_KG_M2, rel=1e-3)
        # Default Position P Gain 800: 800/128 PWM units per tick, 885 units = stall torque.
        assert actuator.gainprm[0] == pytest.approx(
            800 / 128 / 885 * STALL_TORQUE_NM * 4096 / (2 * math.pi), rel=1e-2)
        assert actuator.biasprm[2] == 0.0  # D gain 0: the back-EMF is the only damping
