"""Analytic inverse kinematics of the simulated humanoid's legs (``models/robot.xml``).

Each leg is, from the torso down: hip yaw (z), hip roll (x) 3 cm below it, hip pitch (y)
2 cm below that, thigh 11 cm, knee (y), shin 11 cm, ankle pitch (y), ankle roll (x) 1.5 cm
below it; the foot body's origin is the ankle roll joint, its sole 1.6 cm lower. The roll
and pitch axes do not meet (neither at the hip nor at the ankle), so the textbook solution
for a leg whose hip axes intersect does not apply as is; but every offset lies along the
leg's own axis, which keeps the problem closed-form:

1. the hip yaw is the foot's yaw (the leg below the yaw joint cannot turn the foot about z);
2. turned back by it, the foot lies in the plane the hip roll swings the leg through, so
   the roll is the angle of that plane: ``atan2(y, -z)`` below the roll axis;
3. in that plane, hip pitch, knee and ankle pitch are a planar two-link arm (thigh, shin)
   with a known end segment (ankle pitch to ankle roll, turned by the foot's pitch): the
   law of cosines gives the knee, the rest the hip pitch; the ankle pitch makes up the
   foot's pitch; the ankle roll undoes the hip roll, so the sole stays level.

Targets are the foot origin's position in the **hip frame** (origin at the hip yaw joint,
axes those of the torso) and the foot's yaw and pitch. :func:`foot_pose` is the forward
kinematics of the same chain; ``test/test_leg_ik.py`` checks both against MuJoCo's.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from ..errors import SimConfigError

#: Torso origin to each hip yaw joint (m), from ``models/robot.xml``.
HIP_OFFSET = {"l": (0.0, 0.045, -0.09), "r": (0.0, -0.045, -0.09)}
YAW_TO_ROLL = 0.03
ROLL_TO_PITCH = 0.02
THIGH = 0.11
SHIN = 0.11
ANKLE_PITCH_TO_ROLL = 0.015
#: Ankle roll joint (the foot body's origin) to the bottom of the sole.
SOLE_BELOW_FOOT = 0.016
#: Joint ranges of the legs (rad), as the model limits them.
LIMITS = {
    "hip_yaw": (-1.57, 1.57), "hip_roll": (-0.8, 0.8), "hip_pitch": (-1.8, 1.0),
    "knee": (0.0, 2.3), "ankle_pitch": (-1.2, 1.2), "ankle_roll": (-0.6, 0.6),
}
JOINT_ORDER = ("hip_yaw", "hip_roll", "hip_pitch", "knee", "ankle_pitch", "ankle_roll")


class UnreachableError(SimConfigError):
    """A foot target the leg cannot reach (too far, or beyond a joint's range)."""


@dataclass(frozen=True, slots=True)
class LegAngles:
    """One leg's six joint angles (rad), in the model's sign conventions."""

    hip_yaw: float
    hip_roll: float
    hip_pitch: float
    knee: float
    ankle_pitch: float
    ankle_roll: float

    def named(self, side: str) -> dict[str, float]:
        """``{"l_hip_yaw": ..., ...}``: the joint names of the model for side ``l`` or ``r``."""
        return {f"{side}_{j}": getattr(self, j) for j in JOINT_ORDER}


def leg_ik(x: float, y: float, z: float, *, yaw: float = 0.0, pitch: float = 0.0,
           clamp: bool = True) -> LegAngles:
    """Joint angles that put the foot origin at ``(x, y, z)`` in the hip frame.

    ``yaw`` turns the foot about the vertical; ``pitch`` tilts it about the leg's pitch axis
    (toes down positive, as the model's pitch joints turn), which is the sole's pitch when
    the hip roll is zero; the sole is otherwise kept parallel to the torso's x-y plane.
    A target beyond the leg's reach raises :class:`UnreachableError`; with ``clamp`` (the
    default) the joint angles are then clipped to their ranges, without it an angle beyond
    its range raises too.
    """
    # 1. undo the hip yaw; the roll axis is YAW_TO_ROLL below the yaw joint.
    c, s = math.cos(yaw), math.sin(yaw)
    qx, qy, qz = c * x + s * y, -s * x + c * y, z + YAW_TO_ROLL
    # 2. the hip roll turns the leg's plane; wz is the (negative) height within it.
    roll = math.atan2(qy, -qz)
    wz = -math.hypot(qy, qz)
    # 3. the planar arm from the hip pitch joint to the ankle pitch joint.
    px = qx - ANKLE_PITCH_TO_ROLL * -math.sin(pitch)
    pz = wz + ROLL_TO_PITCH + ANKLE_PITCH_TO_ROLL * math.cos(pitch)
    d2 = px * px + pz * pz
    cos_knee = (d2 - THIGH * THIGH - SHIN * SHIN) / (2 * THIGH * SHIN)
    if not -1.0 <= cos_knee <= 1.0:
        raise UnreachableError(f"foot target ({x:.3f}, {y:.3f}, {z:.3f}) m is out of the "
                               f"leg's reach ({math.sqrt(d2):.3f} m from the hip pitch joint)")
    knee = math.acos(cos_knee)  # bent forward: positive
    # The thigh points down at angle a from -z (positive: foot forward is -hip_pitch).
    # Ry(a) (0, 0, -L) = (-L sin a, 0, -L cos a): direction of the hip-to-ankle line.
    line = math.atan2(-px, -pz)
    inner = math.atan2(SHIN * math.sin(knee), THIGH + SHIN * math.cos(knee))
    hip_pitch = line - inner
    ankle_pitch = pitch - hip_pitch - knee
    angles = {"hip_yaw": yaw, "hip_roll": roll, "hip_pitch": hip_pitch, "knee": knee,
              "ankle_pitch": ankle_pitch, "ankle_roll": -roll}
    for name, value in angles.items():
        low, high = LIMITS[name]
        if not low - 1e-9 <= value <= high + 1e-9:
            if not clamp:
                raise UnreachableError(f"{name} would be {value:.3f} rad, beyond its range "
                                       f"[{low}, {high}]")
            angles[name] = min(high, max(low, value))
    return LegAngles(**angles)


def foot_pose(angles: LegAngles) -> tuple[tuple[float, float, float],
                                          tuple[tuple[float, ...], ...]]:
    """Forward kinematics: the foot origin's position and orientation (3x3, rows) in the
    hip frame, for ``angles``."""
    def rx(a: float) -> list[list[float]]:
        c, s = math.cos(a), math.sin(a)
        return [[1, 0, 0], [0, c, -s], [0, s, c]]

    def ry(a: float) -> list[list[float]]:
        c, s = math.cos(a), math.sin(a)
        return [[c, 0, s], [0, 1, 0], [-s, 0, c]]

    def rz(a: float) -> list[list[float]]:
        c, s = math.cos(a), math.sin(a)
        return [[c, -s, 0], [s, c, 0], [0, 0, 1]]

    def mul(a: list[list[float]], b: list[list[float]]) -> list[list[float]]:
        return [[sum(a[i][k] * b[k][j] for k in range(3)) for j in range(3)] for i in range(3)]

    position = [0.0, 0.0, 0.0]
    rotation = rz(angles.hip_yaw)
    chain = ((YAW_TO_ROLL, rx(angles.hip_roll)), (ROLL_TO_PITCH, ry(angles.hip_pitch)),
             (THIGH, ry(angles.knee)), (SHIN, ry(angles.ankle_pitch)),
             (ANKLE_PITCH_TO_ROLL, rx(angles.ankle_roll)))
    for length, joint in chain:
        position = [position[i] - rotation[i][2] * length for i in range(3)]
        rotation = mul(rotation, joint)
    return ((position[0], position[1], position[2]),
            tuple(tuple(row) for row in rotation))
