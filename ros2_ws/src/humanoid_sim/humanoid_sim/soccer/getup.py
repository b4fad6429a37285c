"""Getting up: after a fall, a keyframed motion from the front or the back to the standing crouch.

A soccer robot that falls must be back on its feet within seconds. The component follows the
fall detector (``fall/state``, :mod:`.fall`):

* **falling**: the protective reaction (``protect``): ``"none"`` holds the joints where the
  fall found them, ``"relax"`` makes them compliant by setting each goal to where the joint
  is (``joint_states``, the driver's reading): the servo's controller then pushes only
  against its own delay, the back-EMF damps the impact; docs/HUMANOID_SIM.md has the
  measurement that chose the default;
* **fallen** and at rest (the IMU's angular rate below ``rest_rate`` for ``rest_s``): the
  IMU's orientation says whether the robot lies on its front (the torso's forward axis
  points down) or its back; the matching get-up motion plays: keyframes (whole-body poses
  with durations) joined per joint by quintic splines (:mod:`.spline`) at rest at each
  keyframe, starting from the joints' present positions, ending in the standing crouch
  (:data:`.motion.STANCE`, the walk's standing pose);
* after the motion it holds the crouch until the fall detector says ``standing`` (success)
  or ``confirm_s`` has passed; then, still lying, it tries again when at rest, up to
  ``max_attempts`` times in a row (0: without limit).

While it acts (from ``falling`` to ``standing``) it owns every joint: it publishes whole-body
goals on ``motion/getup`` (sensor_msgs/JointState; ``output_topic`` renames it, e.g. to
``joint_commands`` without the motion arbiter) every cycle of ``rate_hz``, and its activity on
``motion/getup/active`` (std_msgs/Bool, transient local, on every change). It counts
attempts, successes and the time each get-up took (from ``fallen`` to ``standing``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

from sensor_msgs.msg import Imu, JointState
from std_msgs.msg import Bool, String

from efficient_comm import from_msg, latched_qos, to_msg
from efficient_comm.handle import NodeHandle

from ..errors import SimConfigError
from .fall import FALLEN, FALLING, STANDING, rate_rad_s
from .motion import STANCE
from .spline import Knot, QuinticSpline

LATCHED = latched_qos()
PROTECTIONS = ("none", "relax")
FRONT, BACK = "front", "back"


@dataclass(frozen=True, slots=True)
class Keyframe:
    """A pose (joint name to angle, rad; joints not named keep the previous keyframe's) to
    be reached ``duration_s`` after the previous keyframe."""

    duration_s: float
    pose: Mapping[str, float]


def _legs(hip_pitch: float, knee: float, ankle_pitch: float) -> dict[str, float]:
    return {f"{side}_{joint}": value for side in "lr" for joint, value in
            (("hip_pitch", hip_pitch), ("knee", knee), ("ankle_pitch", ankle_pitch))}


def _arms(pitch: float, *, roll: float = 0.15, elbow: float = 0.0) -> dict[str, float]:
    return {"l_shoulder_pitch": pitch, "r_shoulder_pitch": pitch, "l_shoulder_roll": roll,
            "r_shoulder_roll": -roll, "l_elbow": elbow, "r_elbow": elbow}


#: Standing up from a pike (hips flexed to their limit, legs straight, trunk forward, hands
#: off the ground) to the crouch with the centre of mass over the feet all the way: for each
#: trunk pitch from 1.35 to 0.15 rad the knee is scheduled and the hip pitch solved (by
#: bisection on the model's centre of mass) so that the centre of mass stays above the middle
#: of the soles, the ankles keeping the soles flat. (trunk pitch, hip, knee, ankle, shoulder).
ROLL_UP = ((1.35, -1.80, 0.07, 0.38, -0.27), (1.20, -1.76, 0.14, 0.42, -0.24),
           (1.05, -1.61, 0.21, 0.35, -0.21), (0.90, -1.45, 0.28, 0.27, -0.18),
           (0.75, -1.28, 0.35, 0.18, -0.15), (0.60, -1.10, 0.42, 0.08, -0.12),
           (0.45, -0.92, 0.49, -0.02, -0.09), (0.30, -0.72, 0.56, -0.14, -0.06),
           (0.15, -0.53, 0.63, -0.25, -0.03))


def front_getup(*, sweep_s: float = 0.16, push_s: float = 0.28, pike_s: float = 0.4,
                hold_s: float = 0.1, tip_s: float = 0.3, settle_s: float = 0.08,
                roll_up_step_s: float = 0.06, crouch_s: float = 0.2, pike_ankle: float = 0.3,
                pike_arms: float = -1.5) -> tuple[Keyframe, ...]:
    """Face down to the crouch: arms overhead, push up, pike, stand up from the pike.

    1. The arms sweep sideways along the ground (shoulder roll), turn (pitch) and come in
       again beside the head (``sweep_s`` each): overhead, where pushing lifts the trunk
       instead of rolling it head down (with the hands near the hips the shoulders' reaction
       tips the trunk over the hands). 2. Pushing the hands into the ground lifts the trunk on
       straight arms (``push_s``). 3. The hips flex to their limit, legs straight, soles flat
       (``pike_s``, then ``hold_s``): the robot stands on hands and feet, an inverted V, and
       the feet slide in under it. 4. The ankles and arms tip it back until the centre of mass
       is over the feet and the hands come off the ground (``tip_s``, ``settle_s``).
       5. :data:`ROLL_UP` to the crouch (``roll_up_step_s`` each, ``crouch_s``).
    """
    frames = [
        Keyframe(sweep_s, dict(STANCE) | _arms(0.0, roll=1.5) | _legs(0.0, 0.0, 0.0)
                 | {"neck_pitch": -0.5}),
        Keyframe(sweep_s, _arms(-3.0, roll=1.5)),
        Keyframe(sweep_s, _arms(-3.0, roll=0.1)),
        Keyframe(push_s, _arms(-1.6, roll=0.1)),
        Keyframe(pike_s, _arms(-1.6, roll=0.1) | _legs(-1.8, 0.0, 0.2)),
        Keyframe(hold_s, {}),
        Keyframe(tip_s, _arms(pike_arms, roll=0.1) | _legs(-1.8, 0.0, pike_ankle)),
        Keyframe(settle_s, {}),
    ]
    frames += [Keyframe(roll_up_step_s, _legs(hip, knee, ankle) | _arms(arms)
                        | {"neck_pitch": 0.0})
               for _, hip, knee, ankle, arms in ROLL_UP]
    frames.append(Keyframe(crouch_s, STANCE))
    return tuple(frames)


#: Face up to face down: one arm overhead, the other pushing the shoulder up and the legs
#: crossing over roll the robot onto its front (found by a seeded cross-entropy search over
#: these keyframes on the MuJoCo model, from two headings), then the arms and legs stretch.
ROLL_OVER: tuple[Keyframe, ...] = (
    Keyframe(0.30, dict(STANCE) | {
        "l_shoulder_pitch": 2.34, "l_shoulder_roll": -0.38, "r_shoulder_pitch": -1.76,
        "r_shoulder_roll": -0.01, "l_hip_pitch": -0.45, "l_hip_roll": 0.36, "r_hip_pitch": 0.43,
        "r_hip_roll": 0.06, "l_knee": 0.67, "r_knee": 0.04, "l_elbow": 0.0, "r_elbow": 0.0,
        "neck_pitch": 0.0, "l_ankle_pitch": 0.0, "r_ankle_pitch": 0.0}),
    Keyframe(0.25, {
        "l_shoulder_pitch": 0.92, "l_shoulder_roll": 0.21, "r_shoulder_pitch": -3.09,
        "r_shoulder_roll": 0.41, "l_hip_pitch": -1.36, "l_hip_roll": -0.75, "r_hip_pitch": 0.86,
        "r_hip_roll": 0.8, "l_knee": 2.3, "r_knee": 1.83}),
    Keyframe(0.34, {
        "l_shoulder_pitch": 2.05, "l_shoulder_roll": 0.06, "r_shoulder_pitch": -2.71,
        "r_shoulder_roll": -1.37, "l_hip_pitch": 0.67, "l_hip_roll": 0.37, "r_hip_pitch": 1.0,
        "r_hip_roll": 0.15, "l_knee": 0.63, "r_knee": 0.82}),
    Keyframe(0.20, _arms(0.0) | _legs(0.0, 0.0, 0.0) | {
        "l_hip_roll": 0.0, "r_hip_roll": 0.0}),
)

#: Lying on the front (face down).
FRONT_GETUP: tuple[Keyframe, ...] = front_getup()
#: Lying on the back (face up): roll over, then as from the front.
BACK_GETUP: tuple[Keyframe, ...] = ROLL_OVER + FRONT_GETUP
MOTIONS: dict[str, tuple[Keyframe, ...]] = {FRONT: FRONT_GETUP, BACK: BACK_GETUP}


class Trajectory:
    """Keyframes as one quintic spline per joint, starting at ``start`` at time 0."""

    def __init__(self, start: Mapping[str, float], keyframes: Sequence[Keyframe]) -> None:
        if not keyframes or any(k.duration_s <= 0 for k in keyframes):
            raise SimConfigError("a motion needs keyframes with durations > 0")
        knots = {name: [Knot(0.0, position)] for name, position in start.items()}
        t = 0.0
        for keyframe in keyframes:
            t += keyframe.duration_s
            for name, joint_knots in knots.items():
                joint_knots.append(Knot(t, keyframe.pose.get(name, joint_knots[-1].position)))
        self.duration_s = t
        self._splines = {name: QuinticSpline(k) for name, k in knots.items()}

    def at(self, t: float) -> dict[str, float]:
        return {name: spline(t) for name, spline in self._splines.items()}


def lying_on(imu: Imu) -> str:
    """``"front"`` if the torso's forward axis points down, else ``"back"``."""
    q = imu.orientation
    forward_z = 2 * (q.x * q.z - q.w * q.y)  # z of the body's x axis in the world
    return FRONT if forward_z < 0 else BACK


class GetUp:
    """The get-up component (see the module's docstring for topics and parameters)."""

    def __init__(self, node: NodeHandle) -> None:
        self.node = node
        rate = node.declare_parameter("rate_hz", 100.0)
        output = node.declare_parameter("output_topic", "motion/getup")
        self.protect = node.declare_parameter("protect", "relax")
        self.rest_rate = node.declare_parameter("rest_rate", 0.6)
        self.rest_ns = round(node.declare_parameter("rest_s", 0.1) * 1e9)
        self.confirm_ns = round(node.declare_parameter("confirm_s", 1.5) * 1e9)
        self.max_attempts = node.declare_parameter("max_attempts", 5)
        if not 1.0 <= rate <= 1000.0 or not output:
            raise SimConfigError(f"need 1 <= rate_hz <= 1000 and an output_topic, got {rate}, "
                                 f"{output!r}")
        if self.protect not in PROTECTIONS:
            raise SimConfigError(f"protect must be one of {', '.join(PROTECTIONS)}, got "
                                 f"{self.protect!r}")
        if (self.rest_rate <= 0 or self.rest_ns < 0 or self.confirm_ns < 0
                or self.max_attempts < 0):
            raise SimConfigError(
                f"need rest_rate > 0, rest_s >= 0, confirm_s >= 0 and max_attempts >= 0, got "
                f"{self.rest_rate}, {self.rest_ns / 1e9}, {self.confirm_ns / 1e9}, "
                f"{self.max_attempts}")
        self.period_s = 1.0 / rate
        self.posture = STANDING
        #: ``idle``, ``protect``, ``wait`` (lying, waiting for rest), ``play``, ``confirm``
        #: (holding the crouch for the fall detector's verdict), ``gave_up``.
        self.phase = "idle"
        self.side: str | None = None
        self.attempts = 0
        self.successes = 0
        #: Seconds from ``fallen`` to ``standing``, one per successful get-up.
        self.durations_s: list[float] = []
        self.cycles = 0
        self._failed_in_row = 0
        self._imu: Imu | None = None
        self._still_since_ns: int | None = None
        self._fallen_at_ns: int | None = None
        self._present: dict[str, float] = {}
        self._goals: dict[str, float] = dict(STANCE)
        self._trajectory: Trajectory | None = None
        self._phase_start_ns = 0
        self.pub = node.create_publisher(JointState, output, qos=10)
        self.active_pub = node.create_publisher(Bool, "motion/getup/active", qos=LATCHED)
        self.active = False
        self.active_pub.publish(Bool(data=False))
        node.create_subscription(String, "fall/state", self._on_posture, qos=LATCHED)
        node.create_subscription(Imu, "imu/data", self._on_imu, qos=10)
        node.create_subscription(JointState, "joint_states", self._on_joints, qos=10)
        node.create_timer(self.period_s, self.cycle)

    # -- inputs -------------------------------------------------------------------------------

    def _on_joints(self, state: JointState) -> None:
        for name, position in zip(state.name, state.position, strict=False):
            if math.isfinite(position):
                self._present[name] = position

    def _on_imu(self, imu: Imu) -> None:
        self._imu = imu
        stamp = from_msg(imu.header.stamp)
        if rate_rad_s(imu) <= self.rest_rate:
            if self._still_since_ns is None:
                self._still_since_ns = stamp
        else:
            self._still_since_ns = None

    def _on_posture(self, posture: String) -> None:
        previous, self.posture = self.posture, posture.data
        now = self.node.clock.now_ns()
        if posture.data == STANDING:
            if self.phase in ("confirm", "play") and self._fallen_at_ns is not None:
                self.successes += 1
                self.durations_s.append((now - self._fallen_at_ns) / 1e9)
                self.node.logger.info(f"got up from the {self.side} in "
                                      f"{self.durations_s[-1]:.2f} s (attempt "
                                      f"{self._failed_in_row + 1})")
            self._failed_in_row = 0
            self._fallen_at_ns = None
            self._enter("idle", now)
            self._set_active(False)
            return
        if posture.data == FALLEN and previous != FALLEN:
            if self._fallen_at_ns is None:  # the first time down counts, not a tip mid-motion
                self._fallen_at_ns = now
            if self.phase in ("idle", "protect"):
                self._enter("wait", now)
        elif posture.data == FALLING and self.phase == "idle":
            self._goals = dict(self._present) if self._present else dict(STANCE)
            self._enter("protect", now)
        self._set_active(True)

    # -- the cycle ----------------------------------------------------------------------------

    def _enter(self, phase: str, now_ns: int) -> None:
        self.phase = phase
        self._phase_start_ns = now_ns

    def _set_active(self, active: bool) -> None:
        if active != self.active:
            self.active = active
            self.active_pub.publish(Bool(data=active))

    def _at_rest(self, now_ns: int) -> bool:
        return self._still_since_ns is not None and now_ns - self._still_since_ns >= self.rest_ns

    def cycle(self) -> None:
        if self.phase in ("idle", "gave_up"):
            return
        self.cycles += 1
        now = self.node.clock.now_ns()
        if self.phase == "protect" and self.protect == "relax" and self._present:
            self._goals.update(self._present)
        elif self.phase == "wait" and self._at_rest(now) and self._imu is not None:
            self._start(now)
        elif self.phase == "play":
            assert self._trajectory is not None
            t = (now - self._phase_start_ns) / 1e9
            self._goals = self._trajectory.at(t)
            if t >= self._trajectory.duration_s:
                self._enter("confirm", now)
        elif self.phase == "confirm" and now - self._phase_start_ns >= self.confirm_ns:
            self._failed_in_row += 1
            self.node.logger.warning(f"get-up from the {self.side} failed (attempt "
                                     f"{self._failed_in_row}): still {self.posture}")
            if self.max_attempts and self._failed_in_row >= self.max_attempts:
                self.node.logger.error(f"giving up after {self._failed_in_row} attempts")
                self._enter("gave_up", now)
                self._set_active(False)
                return
            self._still_since_ns = None
            self._enter("wait", now)
        self._publish(now)

    def _start(self, now_ns: int) -> None:
        assert self._imu is not None
        self.side = lying_on(self._imu)
        start = dict(self._goals) | {n: p for n, p in self._present.items() if n in STANCE}
        self._trajectory = Trajectory(start, MOTIONS[self.side])
        self.attempts += 1
        self.node.logger.info(f"lying on the {self.side}: getting up (attempt "
                              f"{self._failed_in_row + 1})")
        self._enter("play", now_ns)

    def _publish(self, now_ns: int) -> None:
        command = JointState(name=list(self._goals), position=list(self._goals.values()))
        command.header.stamp = to_msg(now_ns)
        self.pub.publish(command)

    def status(self) -> dict[str, object]:
        return {"phase": self.phase, "side": self.side, "attempts": self.attempts,
                "successes": self.successes, "durations_s": list(self.durations_s)}
