"""Several robots on one field: one MuJoCo world built with MjSpec, and each robot's view of it.

The field and ball come from ``models/field.xml``, each robot from ``models/robot.xml``,
attached with its name as prefix (``blue1/torso``, ``blue1/head_camera``, ``blue1/imu_gyro``,
``blue1/l_knee``, ...), so one model holds up to six robots that collide with each other and
the ball like any other bodies, and one ``mj_step`` moves them all. Each robot keeps its own
:class:`~.mujoco_plant.RobotPlant`: the Plant its emulated servo bus drives, which never
steps the world itself.

Names are the team game's (``<team colour><number>``: ``blue1``..``blue3``,
``red1``..``red3``); the blue team attacks +x in the first half, so by default blue starts in
the -x half facing +x and red in the +x half facing -x. A robot's torso and head wear its
team's colour; red is a deep red, outside the ball detector's orange hues.

The one-robot world (:class:`~.mujoco_plant.MujocoPlant`, ``models/soccer_field.xml``) stays
as it was, with unprefixed names: its seeded runs are unchanged.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from dataclasses import dataclass

import mujoco
import numpy as np
import numpy.typing as npt

from soccer_field import KIDSIZE

from .errors import SimConfigError
from .joints import JOINTS
from .mujoco_plant import FIELD_MODEL, ROBOT_MODEL, RobotPlant, set_ball, step_world

TEAMS = ("blue", "red")
PLAYERS_PER_TEAM = 3
ROBOT_NAMES = tuple(f"{team}{n}" for team in TEAMS for n in range(1, PLAYERS_PER_TEAM + 1))
#: Jersey colours (RGBA) of the torso and head.
TEAM_COLOURS: dict[str, tuple[float, float, float, float]] = {
    "blue": (0.1, 0.25, 0.85, 1.0),
    "red": (0.8, 0.05, 0.08, 1.0),
}
#: Start poses closer than this (torso to torso) would put two robots inside each other
#: (shoulder to shoulder a robot is 0.24 m wide, toe to heel 0.13 m long).
MIN_START_DISTANCE_M = 0.3
#: The world's ``<visual><quality numslices numstacks numquads>`` (MuJoCo's: 28, 16, 4).
RENDER_QUALITY = (16, 8, 1)
_NAME = re.compile(r"^(blue|red)([1-9][0-9]*)$")


@dataclass(frozen=True)
class Pose2D:
    """Where a robot stands on the field: x, y (m, field frame: origin at the centre mark,
    x toward the goal blue attacks) and its heading (rad, 0 facing +x)."""

    x: float
    y: float
    heading: float


#: Start poses when none are given: blue in its own half facing +x, red mirrored.
DEFAULT_START: dict[str, Pose2D] = {
    **{f"blue{n}": Pose2D(x, y, 0.0)
       for n, (x, y) in enumerate([(-1.0, 0.0), (-2.0, 1.5), (-3.5, 0.0)], start=1)},
    **{f"red{n}": Pose2D(x, -y, math.pi)
       for n, (x, y) in enumerate([(1.0, 0.0), (2.0, 1.5), (3.5, 0.0)], start=1)},
}


def team_of(robot: str) -> str:
    """``"blue"`` or ``"red"``; SimConfigError for a name the team game does not use."""
    match = _NAME.match(robot)
    if match is None or robot not in ROBOT_NAMES:
        raise SimConfigError(f"robot {robot!r}: robots are named {', '.join(ROBOT_NAMES)}")
    return match.group(1)


def check_on_field(robot: str, pose: Pose2D, *, border_m: float = 0.0) -> None:
    """SimConfigError naming ``robot`` unless ``pose`` is finite and on the field (with
    ``border_m`` of the border strip around it)."""
    if not all(map(math.isfinite, (pose.x, pose.y, pose.heading))):
        raise SimConfigError(f"robot {robot}: pose ({pose.x}, {pose.y}, {pose.heading}) is "
                             "not finite")
    half_x, half_y = KIDSIZE.half_length + border_m, KIDSIZE.half_width + border_m
    if abs(pose.x) > half_x or abs(pose.y) > half_y:
        where = "on the field" if not border_m else "on the field or its border strip"
        raise SimConfigError(f"robot {robot}: ({pose.x:g}, {pose.y:g}) is not {where} "
                             f"(x within ±{half_x:g} m, y within ±{half_y:g} m)")


def build_model(robots: Mapping[str, Pose2D]) -> mujoco.MjModel:
    """Compile the world: the field, the ball and ``robots`` at their start poses (which are
    the model's ``qpos0``: resetting the data puts them back)."""
    if not robots:
        raise SimConfigError("a world needs at least one robot")
    for name, pose in robots.items():
        team_of(name)
        check_on_field(name, pose)
    named = list(robots.items())
    for i, (a, pa) in enumerate(named):
        for b, pb in named[i + 1:]:
            if math.hypot(pa.x - pb.x, pa.y - pb.y) < MIN_START_DISTANCE_M:
                raise SimConfigError(
                    f"robots {a} and {b} start {math.hypot(pa.x - pb.x, pa.y - pb.y):.2f} m "
                    f"apart: closer than {MIN_START_DISTANCE_M} m they would start inside "
                    "each other")
    spec = mujoco.MjSpec.from_file(str(FIELD_MODEL))
    robot_options = mujoco.MjSpec.from_file(str(ROBOT_MODEL)).option
    # The world steps as the robot's model was tuned to (the field has no say).
    spec.option.timestep = robot_options.timestep
    spec.option.integrator = robot_options.integrator
    # Coarser tessellation of spheres, capsules and cylinders, and the ground as one quad:
    # with six robots in view the software rasteriser's triangles, not the pixels, were
    # most of a frame (23 -> 10 ms; 10 -> 7 ms with one robot; bench/world_bench.py). A
    # 16-gon ball reads 1.3 % smaller than a circle; colours and lines stay as they were.
    # No multisampling either: the field's <visual><quality offsamples="0"/>.
    spec.visual.quality.numslices = RENDER_QUALITY[0]
    spec.visual.quality.numstacks = RENDER_QUALITY[1]
    spec.visual.quality.numquads = RENDER_QUALITY[2]
    for name, pose in robots.items():
        robot = mujoco.MjSpec.from_file(str(ROBOT_MODEL))
        robot.option.integrator = spec.option.integrator  # nothing left to disagree on
        colour = TEAM_COLOURS[team_of(name)]
        for body in ("torso", "head"):
            for geom in robot.body(body).geoms:
                geom.rgba = colour
        frame = spec.worldbody.add_frame(
            pos=[pose.x, pose.y, 0.0],
            quat=[math.cos(pose.heading / 2), 0.0, 0.0, math.sin(pose.heading / 2)])
        frame.attach_body(robot.body("torso"), f"{name}/", "")
    return spec.compile()


class World:
    """The field, the ball and several robots in one model; :meth:`step` moves them all.

    ``robots`` maps names to start poses (each on the field); ``ball`` is where the ball
    lies at the start. Not thread-safe: whoever steps it holds the lock the robots' buses
    share (see :class:`~.world_simulator.WorldSimulator`).
    """

    def __init__(self, robots: Mapping[str, Pose2D], *, ball: tuple[float, float] = (0.0, 0.0)
                 ) -> None:
        self.model = build_model(robots)
        self.data = mujoco.MjData(self.model)
        #: Each robot's servos and names (``self.robots["blue1"].name("torso")``).
        self.robots = {name: RobotPlant(self.model, self.data, prefix=f"{name}/",
                                        joints=JOINTS) for name in robots}
        self._plants = list(self.robots.values())
        self._ball = self.model.body("ball").id
        self.place_ball(x=ball[0], y=ball[1])

    def step(self, seconds: float) -> None:
        """Advance the world: every robot's servos, contacts between all bodies."""
        step_world(self.model, self.data, self._plants, seconds)

    @property
    def time_s(self) -> float:
        return float(self.data.time)

    def place_robot(self, robot: str, pose: Pose2D) -> None:
        """Put ``robot`` at ``pose``, upright and at rest (a fallen one is stood up): as a
        referee places robots. The field's border strip counts (a removed robot waits
        there); SimConfigError for an unknown robot or a pose beyond it."""
        if robot not in self.robots:
            raise SimConfigError(f"no robot {robot!r} in this world (it has "
                                 f"{', '.join(self.robots)})")
        check_on_field(robot, pose, border_m=KIDSIZE.border_strip_width)
        self.robots[robot].place(x=pose.x, y=pose.y, heading=pose.heading)
        mujoco.mj_forward(self.model, self.data)

    def place_ball(self, *, x: float, y: float, velocity: tuple[float, float] = (0.0, 0.0)
                   ) -> None:
        """Put the ball at (x, y), rolling at ``velocity`` (m/s); SimConfigError if it would
        leave the ground (the field and its border strip) or is not finite."""
        check_on_field("ball", Pose2D(x, y, 0.0), border_m=KIDSIZE.border_strip_width)
        set_ball(self.model, self.data, position=(x, y), velocity=velocity)

    def torso_pose(self, robot: str) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
        """The robot's torso position and orientation (quaternion w, x, y, z), field frame."""
        torso = self.model.body(self.robots[robot].name("torso")).id
        return np.array(self.data.xpos[torso]), np.array(self.data.xquat[torso])

    def ball_pose(self) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
        return np.array(self.data.xpos[self._ball]), np.array(self.data.xquat[self._ball])
