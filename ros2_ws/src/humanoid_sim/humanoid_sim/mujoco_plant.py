"""MuJoCo as the :class:`~humanoid_sim.dynamixel.plant.Plant` behind the emulated servos.

Each servo id drives one joint through a position actuator (XM430-like: 4.1 N m stall
torque). A goal is approached no faster than the servo's profile speed (the set-point
slews), and torque off makes the joint limp (the actuator's gains drop to zero).
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import mujoco
import numpy as np

from .dynamixel.plant import JointState

MODEL = Path(__file__).with_name("models") / "soccer_field.xml"

#: Servo ids of the 20 joints, as the robot's wiring would number them.
JOINTS: dict[int, str] = {
    i + 1: name
    for i, name in enumerate([
        "neck_yaw", "neck_pitch",
        "l_shoulder_pitch", "l_shoulder_roll", "l_elbow",
        "r_shoulder_pitch", "r_shoulder_roll", "r_elbow",
        "l_hip_yaw", "l_hip_roll", "l_hip_pitch", "l_knee", "l_ankle_pitch", "l_ankle_roll",
        "r_hip_yaw", "r_hip_roll", "r_hip_pitch", "r_knee", "r_ankle_pitch", "r_ankle_roll",
    ])
}


class MujocoPlant:
    def __init__(self, *, model_path: Path = MODEL, joints: Mapping[int, str] = JOINTS) -> None:
        self.model = mujoco.MjModel.from_xml_path(str(model_path))
        self.data = mujoco.MjData(self.model)
        self._joint = {i: self.model.joint(name) for i, name in joints.items()}
        self._actuator = {i: self.model.actuator(name).id for i, name in joints.items()}
        self._kp = {i: float(self.model.actuator_gainprm[a, 0]) for i, a in self._actuator.items()}
        self._kv = {i: float(-self.model.actuator_biasprm[a, 2]) for i, a in self._actuator.items()}
        self._goal: dict[int, tuple[bool, float, float]] = {}
        # Set-point slewing for all torqued joints at once: actuator index, goal, speed.
        self._slew_index = np.zeros(0, dtype=np.intp)
        self._slew_goal = np.zeros(0)
        self._slew_speed = np.zeros(0)
        for dxl_id in joints:
            self._set_torque(dxl_id, on=False)
        mujoco.mj_forward(self.model, self.data)

    def _set_torque(self, dxl_id: int, *, on: bool) -> None:
        a = self._actuator[dxl_id]
        kp, kv = (self._kp[dxl_id], self._kv[dxl_id]) if on else (0.0, 0.0)
        self.model.actuator_gainprm[a, 0] = kp
        self.model.actuator_biasprm[a, 1] = -kp
        self.model.actuator_biasprm[a, 2] = -kv

    def command(self, dxl_id: int, *, torque: bool, goal_rad: float, max_speed_rad_s: float
                ) -> None:
        if dxl_id not in self._actuator:
            return
        was_on = self._goal.get(dxl_id, (False, 0.0, 0.0))[0]
        if torque and not was_on:  # start slewing from where the joint is now
            self.data.ctrl[self._actuator[dxl_id]] = self.data.qpos[self._joint[dxl_id].qposadr[0]]
        self._goal[dxl_id] = (torque, goal_rad, max_speed_rad_s)
        self._set_torque(dxl_id, on=torque)
        on = [(self._actuator[i], g, s) for i, (t, g, s) in self._goal.items() if t]
        self._slew_index = np.array([a for a, _, _ in on], dtype=np.intp)
        self._slew_goal = np.array([g for _, g, _ in on])
        self._slew_speed = np.array([s for _, _, s in on])

    def step(self, seconds: float) -> None:
        """Advance the simulation; set-points move toward goals at the allowed speed."""
        steps = max(1, round(seconds / self.model.opt.timestep))
        dt = self.model.opt.timestep
        index, goal, limit = self._slew_index, self._slew_goal, self._slew_speed * dt
        for _ in range(steps):
            if len(index):
                ctrl = self.data.ctrl[index]
                self.data.ctrl[index] = ctrl + np.clip(goal - ctrl, -limit, limit)
            mujoco.mj_step(self.model, self.data)

    def state(self, dxl_id: int) -> JointState:
        joint = self._joint[dxl_id]
        return JointState(
            position_rad=float(self.data.qpos[joint.qposadr[0]]),
            velocity_rad_s=float(self.data.qvel[joint.dofadr[0]]),
            current_a=abs(float(self.data.actuator_force[self._actuator[dxl_id]])) / 1.8,
        )

    def torso_height(self) -> float:
        return float(self.data.xpos[self.model.body("torso").id][2])
