"""The legs' analytic IK against MuJoCo's forward kinematics of models/robot.xml."""

from __future__ import annotations

import itertools
import math

import mujoco
import numpy as np
import pytest

from humanoid_sim.mujoco_plant import MujocoPlant
from humanoid_sim.soccer.leg_ik import HIP_OFFSET, LegAngles, UnreachableError, foot_pose, leg_ik


def _mujoco_foot(plant: MujocoPlant, side: str, angles: LegAngles
                 ) -> tuple[np.ndarray, np.ndarray]:
    """The foot origin's position (hip frame) and orientation (torso axes) per MuJoCo."""
    m, d = plant.model, plant.data
    d.qpos[:] = m.qpos0
    for name, value in angles.named(side).items():
        d.qpos[m.joint(name).qposadr[0]] = value
    mujoco.mj_kinematics(m, d)
    torso, foot = m.body("torso").id, m.body(f"{side}_foot").id
    r = d.xmat[torso].reshape(3, 3)
    position = r.T @ (d.xpos[foot] - d.xpos[torso]) - np.array(HIP_OFFSET[side])
    return position, r.T @ d.xmat[foot].reshape(3, 3)


def _rot(axis: str, a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return {"x": np.array([[1, 0, 0], [0, c, -s], [0, s, c]]),
            "y": np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]]),
            "z": np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])}[axis]


TARGETS = list(itertools.product((-0.06, 0.0, 0.07), (-0.04, 0.0, 0.05), (-0.27, -0.23, -0.19),
                                 (-0.4, 0.0, 0.5), (-0.2, 0.0, 0.25)))


@pytest.mark.parametrize("side", ["l", "r"])
def test_ik_puts_the_foot_where_mujoco_finds_it(side: str) -> None:
    plant = MujocoPlant()
    checked = 0
    for x, y, z, yaw, pitch in TARGETS:
        try:
            angles = leg_ik(x, y, z, yaw=yaw, pitch=pitch, clamp=False)
        except UnreachableError:  # a joint's range: the walk's feet stay well inside
            continue
        checked += 1
        position, orientation = _mujoco_foot(plant, side, angles)
        assert position == pytest.approx([x, y, z], abs=1e-9), (x, y, z, yaw, pitch)
        # The documented orientation: yaw, then pitch about the leg's (rolled) pitch axis,
        # the ankle roll undoing the hip roll.
        expected = (_rot("z", yaw) @ _rot("x", angles.hip_roll) @ _rot("y", pitch)
                    @ _rot("x", -angles.hip_roll))
        assert np.abs(orientation - expected).max() < 1e-9
        if pitch == 0.0:  # the sole stays level with the torso's x-y plane
            assert np.abs(orientation - _rot("z", yaw)).max() < 1e-9
        fk_position, fk_orientation = foot_pose(angles)
        assert fk_position == pytest.approx(position.tolist(), abs=1e-12)
        assert np.abs(np.array(fk_orientation) - orientation).max() < 1e-12
    assert checked > 0.8 * len(TARGETS)


def test_the_standing_pose_bends_the_knee_forward_and_keeps_the_sole_level() -> None:
    angles = leg_ik(0.0, 0.0, -0.255)
    assert angles.knee > 0.3 and angles.hip_pitch < 0 and angles.ankle_pitch < 0
    assert angles.hip_pitch + angles.knee + angles.ankle_pitch == pytest.approx(0.0, abs=1e-12)
    assert angles.hip_roll == angles.ankle_roll == 0.0


def test_out_of_reach_and_out_of_range_targets_are_refused() -> None:
    with pytest.raises(UnreachableError, match="out of the leg's reach"):
        leg_ik(0.0, 0.0, -0.40)
    with pytest.raises(UnreachableError, match="hip_roll"):
        leg_ik(0.0, 0.15, -0.15, clamp=False)
    clamped = leg_ik(0.0, 0.15, -0.15)
    assert clamped.hip_roll == 0.8 and clamped.ankle_roll == -0.6
