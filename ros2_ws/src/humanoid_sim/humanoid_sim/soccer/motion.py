"""The standing pose and the neck's range, shared by the motions and the motion arbiter.

The robot stands in a slight crouch (knees bent, so it can balance and react); head goals
are clamped to the neck's range. Which motion moves the body is the arbiter's choice
(:mod:`.arbiter`), which sends this pose while no motion runs.
"""

from __future__ import annotations

from ..joints import JOINTS

STANCE: dict[str, float] = {name: 0.0 for name in JOINTS.values()} | {
    "l_hip_pitch": -0.35, "l_knee": 0.7, "l_ankle_pitch": -0.35,
    "r_hip_pitch": -0.35, "r_knee": 0.7, "r_ankle_pitch": -0.35,
    "l_shoulder_roll": 0.15, "r_shoulder_roll": -0.15, "l_elbow": -0.5, "r_elbow": -0.5,
    "neck_pitch": 0.45,
}
NECK_LIMITS = {"neck_yaw": (-2.0, 2.0), "neck_pitch": (-1.0, 1.3)}
