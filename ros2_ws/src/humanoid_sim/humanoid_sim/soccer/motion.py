"""The standing pose, the neck's range and the motions' cadence, shared by the motions and
the motion arbiter.

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

#: The most one round of a motion's timer advances the motion by, s (see :class:`Cadence`).
MAX_STEP_S = 0.1


class Cadence:
    """How far a motion advances at a round of its timer: the time that passed since the last.

    A loaded real-time process runs a motion's timer late or skips rounds (the walk's 100 Hz
    ran at 66 Hz beside the simulator's camera renders). Advancing by the nominal period then
    plays the motion slower than the physics it moves: the walk's step rhythm fell behind
    and the robot fell within seconds in about half of the real-time demos. In lockstep the
    rounds are a period apart, so nothing changes there. At most :data:`MAX_STEP_S` at once:
    after a long stall the feet do not jump.
    """

    def __init__(self, period_s: float) -> None:
        self.period_s = period_s
        self._last_ns: int | None = None

    def step_s(self, now_ns: int) -> float:
        """Seconds to advance by at ``now_ns`` (one period at the first round)."""
        last, self._last_ns = self._last_ns, now_ns
        if last is None or now_ns <= last:
            return self.period_s
        return min((now_ns - last) / 1e9, max(MAX_STEP_S, self.period_s))

    def restart(self) -> None:
        """The motion starts afresh: its next round is its first."""
        self._last_ns = None
