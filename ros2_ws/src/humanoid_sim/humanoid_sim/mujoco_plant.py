"""MuJoCo as the :class:`~humanoid_sim.dynamixel.plant.Plant` behind the emulated servos.

Each servo id drives one joint as an XM430-W350 at 12 V drives it: a DC motor behind a
353.5:1 gearbox, whose controller turns the position error into a PWM duty cycle. In MJCF
(``models/robot.xml``, class ``servo``) that is

* a position actuator whose force is the torque the duty cycle asks for, saturating at the
  stall torque (full PWM): ``clamp(kp * (goal - q), ±τ_stall)``;
* joint damping ``b = τ_stall / ω_no_load``: the back-EMF, which takes ``b * ω`` off that
  torque at speed ω. Together they give the motor's torque-speed line: driving, the torque
  is at most ``τ_stall * (1 - ω / ω_no_load)``, so no joint ever turns faster than the
  no-load speed (46 rpm), and a loaded one slows down along the line;
* the rotor's inertia seen through the gearbox (armature).

How each figure follows from the e-Manual's is written in docs/HUMANOID_SIM.md and next to
the figures in ``models/robot.xml``. A goal is approached no faster than the servo's profile
speed (the set-point slews). Torque off makes the joint limp: the controller's gain and the
back-EMF's damping drop to zero (the motor driver's output is off, so no current flows).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path

import mujoco
import numpy as np
import numpy.typing as npt

from .dynamixel.plant import JointState
from .errors import SimConfigError
from .joints import JOINTS

#: XM430-W350 at 12 V, from the ROBOTIS e-Manual's specification table.
STALL_TORQUE_NM = 4.1
STALL_CURRENT_A = 2.3
NO_LOAD_SPEED_RAD_S = 46 * 2 * math.pi / 60
GEAR_RATIO = 353.5
#: Not published by ROBOTIS: the inertia of a 16 mm coreless motor's rotor, the size the
#: XM430's case holds (1 g cm²). Seen through the gearbox it is the joint's armature.
ROTOR_INERTIA_KG_M2 = 1.0e-7
#: Output torque per ampere of motor current (the motor's torque is proportional to it).
TORQUE_PER_AMP = STALL_TORQUE_NM / STALL_CURRENT_A

MODEL = Path(__file__).with_name("models") / "soccer_field.xml"

ROBOT_MODEL = MODEL.with_name("robot.xml")
FIELD_MODEL = MODEL.with_name("field.xml")
BALL_RADIUS_M = 0.07


def set_ball(model: mujoco.MjModel, data: mujoco.MjData, *,
             position: tuple[float, float] | None = None,
             velocity: tuple[float, float] = (0.0, 0.0)) -> None:
    """Put the ball (the field's ``ball`` joint) on the ground at ``position`` (if given) and
    set it rolling at ``velocity`` (m/s)."""
    ball = model.joint("ball")
    q, v = ball.qposadr[0], ball.dofadr[0]
    if position is not None:
        data.qpos[q : q + 7] = [position[0], position[1], BALL_RADIUS_M, 1, 0, 0, 0]
    data.qvel[v : v + 6] = [velocity[0], velocity[1], 0, 0, 0, 0]
    mujoco.mj_forward(model, data)


class RobotPlant:
    """One robot's servos in a MuJoCo world that may hold several robots: the
    :class:`~humanoid_sim.dynamixel.plant.Plant` its emulated bus drives.

    Every name of the robot's model (``torso``, ``root``, the joints, the actuators, the IMU
    sensors, ``head_camera``) is looked up with ``prefix`` in front (``blue1/torso``), so each
    robot of a shared world has a view of its own; ``prefix=""`` is the one-robot model. The
    view never steps: the world does, once for all robots (:func:`step_world`).
    """

    def __init__(self, model: mujoco.MjModel, data: mujoco.MjData, *, prefix: str = "",
                 joints: Mapping[int, str] = JOINTS) -> None:
        self.model, self.data, self.prefix = model, data, prefix
        self._joint = {i: model.joint(prefix + name) for i, name in joints.items()}
        self._actuator = {i: model.actuator(prefix + name).id for i, name in joints.items()}
        self._kp = {i: float(model.actuator_gainprm[a, 0]) for i, a in self._actuator.items()}
        self._kv = {i: float(-model.actuator_biasprm[a, 2]) for i, a in self._actuator.items()}
        self._dof = {i: int(j.dofadr[0]) for i, j in self._joint.items()}
        # Plain ints: a joint view's ``qposadr[0]`` makes an array each time, and the servo
        # bus asks every joint's state every cycle.
        self._qpos = {i: int(j.qposadr[0]) for i, j in self._joint.items()}
        self._damping = {i: float(model.dof_damping[d]) for i, d in self._dof.items()}
        self._goal: dict[int, tuple[bool, float, float]] = {}
        # Set-point slewing for all torqued joints at once: actuator index, goal, speed.
        self._slew: tuple[npt.NDArray[np.intp], npt.NDArray[np.float64],
                          npt.NDArray[np.float64]] | None = None
        #: Pushes under way: body id, the simulated time at which it ends, its force.
        self.pushes: list[tuple[int, float, npt.NDArray[np.float64]]] = []
        self._torso = model.body(prefix + "torso").id
        self._root = model.joint(prefix + "root")
        for dxl_id in joints:
            self._set_torque(dxl_id, on=False)

    def name(self, name: str) -> str:
        """``name`` of the robot's model as the world calls it (``torso`` -> ``blue1/torso``)."""
        return self.prefix + name

    def _set_torque(self, dxl_id: int, *, on: bool) -> None:
        a = self._actuator[dxl_id]
        kp, kv = (self._kp[dxl_id], self._kv[dxl_id]) if on else (0.0, 0.0)
        self.model.actuator_gainprm[a, 0] = kp
        self.model.actuator_biasprm[a, 1] = -kp
        self.model.actuator_biasprm[a, 2] = -kv
        self.model.dof_damping[self._dof[dxl_id]] = self._damping[dxl_id] if on else 0.0

    def command(self, dxl_id: int, *, torque: bool, goal_rad: float, max_speed_rad_s: float
                ) -> None:
        if dxl_id not in self._actuator:
            return
        was_on = self._goal.get(dxl_id, (False, 0.0, 0.0))[0]
        if torque and not was_on:  # start slewing from where the joint is now
            self.data.ctrl[self._actuator[dxl_id]] = self.data.qpos[self._qpos[dxl_id]]
        self._goal[dxl_id] = (torque, goal_rad, max_speed_rad_s)
        if torque != was_on:  # gains as they were otherwise (off for all at the start)
            self._set_torque(dxl_id, on=torque)
        self._slew = None  # rebuilt at the next step: a sync write commands every servo

    @property
    def slew(self) -> tuple[npt.NDArray[np.intp], npt.NDArray[np.float64],
                            npt.NDArray[np.float64]]:
        """The actuators under torque, their goals (rad) and speed limits (rad/s)."""
        if self._slew is None:
            on = [(self._actuator[i], g, s) for i, (t, g, s) in self._goal.items() if t]
            self._slew = (np.array([a for a, _, _ in on], dtype=np.intp),
                          np.array([g for _, g, _ in on], dtype=np.float64),
                          np.array([s for _, _, s in on], dtype=np.float64))
        return self._slew

    def push(self, force_n: tuple[float, float, float], *, duration_s: float,
             body: str = "torso") -> None:
        """Push the robot's ``body`` at its centre of mass with ``force_n`` (field frame,
        newtons) for the next ``duration_s`` of simulated time: a shove, as in a
        push-recovery test.

        Pushes on the same body add up while they overlap.
        """
        force = np.array(force_n, dtype=float)
        if force.shape != (3,) or not np.isfinite(force).all() or not duration_s > 0:
            raise SimConfigError(f"a push needs a finite (x, y, z) force and a duration > 0, "
                                 f"got {force_n} for {duration_s} s")
        try:
            body_id = self.model.body(self.prefix + body).id
        except KeyError:
            raise SimConfigError(f"no body {self.prefix + body!r} to push in the model") from None
        self.data.xfrc_applied[body_id, :3] += force
        self.pushes.append((body_id, self.data.time + duration_s, force))

    def end_pushes(self) -> None:
        """Take back the forces of pushes whose time is up."""
        now = self.data.time + 1e-9
        for push in list(self.pushes):
            body_id, until, force = push
            if now >= until:
                self.data.xfrc_applied[body_id, :3] -= force
                self.pushes.remove(push)

    def place(self, *, x: float, y: float, heading: float) -> None:
        """Put the torso above (x, y) on the field, upright and facing ``heading`` (rad), its
        body at rest. A robot that is down is stood up at the model's start height (it drops
        onto its feet with the joint angles it has); call ``mj_forward`` afterwards."""
        q, v = self._root.qposadr[0], self._root.dofadr[0]
        if self.data.xmat[self._torso][8] < math.cos(math.radians(30)):  # tilted: down
            self.data.qpos[q + 2] = self.model.qpos0[q + 2]
        self.data.qpos[q : q + 2] = [x, y]
        self.data.qpos[q + 3 : q + 7] = [math.cos(heading / 2), 0, 0, math.sin(heading / 2)]
        self.data.qvel[v : v + 6] = 0.0

    def motor_torque(self, dxl_id: int) -> float:
        """The motor's torque at the output (N m): what the PWM asks for less the back-EMF's."""
        dof = self._dof[dxl_id]
        return (float(self.data.actuator_force[self._actuator[dxl_id]])
                - float(self.model.dof_damping[dof]) * float(self.data.qvel[dof]))

    def state(self, dxl_id: int) -> JointState:
        data = self.data
        return JointState(position_rad=float(data.qpos[self._qpos[dxl_id]]),
                          velocity_rad_s=float(data.qvel[self._dof[dxl_id]]),
                          current_a=abs(self.motor_torque(dxl_id)) / TORQUE_PER_AMP)

    @property
    def time_s(self) -> float:
        """Simulated seconds: the servos' Realtime Tick counts them."""
        return float(self.data.time)

    def torso_height(self) -> float:
        return float(self.data.xpos[self._torso][2])


def step_world(model: mujoco.MjModel, data: mujoco.MjData, robots: Sequence[RobotPlant],
               seconds: float) -> None:
    """Advance the world by ``seconds``; every robot's set-points move toward their goals at
    the allowed speed, all robots' at once in each physics step."""
    steps = max(1, round(seconds / model.opt.timestep))
    dt = model.opt.timestep
    if len(robots) == 1:
        index, goal, speed = robots[0].slew
        limit = speed * dt
    else:
        slews = [r.slew for r in robots]
        index = np.concatenate([i for i, _, _ in slews])
        goal = np.concatenate([g for _, g, _ in slews])
        limit = np.concatenate([s for _, _, s in slews]) * dt
    for _ in range(steps):
        if len(index):
            ctrl = data.ctrl[index]
            data.ctrl[index] = ctrl + np.clip(goal - ctrl, -limit, limit)
        mujoco.mj_step(model, data)
        for robot in robots:
            if robot.pushes:
                robot.end_pushes()


class MujocoPlant(RobotPlant):
    """The one-robot world (``models/soccer_field.xml``): the robot's names unprefixed, and
    :meth:`step` advances the world."""

    def __init__(self, *, model_path: Path = MODEL, joints: Mapping[int, str] = JOINTS) -> None:
        model = mujoco.MjModel.from_xml_path(str(model_path))
        super().__init__(model, mujoco.MjData(model), joints=joints)
        mujoco.mj_forward(self.model, self.data)

    def step(self, seconds: float) -> None:
        """Advance the simulation; set-points move toward goals at the allowed speed."""
        step_world(self.model, self.data, [self], seconds)
