"""The robot's joints by servo id: what its wiring numbers, shared by the simulator and the
robot's software. A module of its own so that robot software (motion, the driver's
process) does not import MuJoCo for a table of names."""

from __future__ import annotations

__all__ = ["JOINTS"]

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
