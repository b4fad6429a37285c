"""The kick: from standing, shift the weight, lift the foot, swing it through the ball, stand.

A kick of the kind KidSize robots make from a stop: the trunk moves over the support foot,
the kicking foot is lifted and drawn back, swung forward through the ball (straight ahead,
along the torso's x axis), brought back, set down, and the weight moves back onto both feet
into the standing pose (:data:`~.motion.STANCE`). Every foot coordinate follows quintic
splines (:mod:`.spline`) through the phases' knots, at rest at each knot, so no servo is
asked to jump; the feet's positions go through the legs' analytic inverse kinematics
(:mod:`.leg_ik`), as the walk's do. The swing is short: the servos turn at most 46 rpm, so
its speed at the ball is what they give, not what the spline asks (the spline asks more).

Two swings (``swing``): ``joint`` (the default) swings the kicking leg in joint space: from
the lifted foot it winds up (hip pitch, knee and ankle pitch to ``windup_*``: thigh
upright, knee bent far back) and then the hip flexes and the knee extends together
(``swing_*``: the goals jump ahead of the servos, which turn at their speed limit), so
both joints' speeds add at the foot when it meets the ball; the leg then comes back to
the lifted foot, all along quintic splines in joint space. Measured on the plant, the ball
leaves at 1.28 m/s and rolls 0.87 m where the ``spline`` swing (the foot's path through the
IK, below) gives 0.96 m/s and 0.52 m: the IK path keeps the knee bent and the foot level, so
the knee's speed goes into keeping the foot's height, not into the ball. The support leg
stays straighter (``crouch`` 0): a kicking leg swung nearly straight needs the hip that
high to clear the ground.

The ball must lie in front of the kicking foot: its centre about 0.16 m ahead of the
torso's origin (``kick_rig.BALL_AHEAD_M``; 4 cm either way still kicks it well) and on the
foot's line (the hip, ``leg_ik.HIP_OFFSET``, 4.5 cm to that side); walking there is the
behaviour's job.

Feedback from the IMU (``imu/data``), as in the walk: the torso's pitch and roll rates,
low-pass filtered, added to the support leg's ankle pitch and hip roll.

Topics, relative to the robot namespace: ``motion/kick/request`` (std_msgs/String: ``left``
or ``right``, the kicking foot) starts a kick if the motion arbiter's ``motion/state`` is
``stand``; otherwise (walking, fallen, getting up, already kicking) the request is refused
with a log line and counted (:attr:`Kick.refused`). ``motion/kick`` (sensor_msgs/JointState,
whole body, every ``1 / rate_hz`` s while kicking) and ``motion/kick/active`` (std_msgs/Bool,
transient local, on every change): true from the accepted request to the end of the kick,
so a behaviour waits for it to go false. A fall (``fall/state`` not ``standing``) aborts the
kick at once (:attr:`Kick.aborted`). Every figure of :class:`KickParameters` is a ROS
parameter, changeable between kicks.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

from sensor_msgs.msg import Imu, JointState
from std_msgs.msg import Bool, String

from efficient_comm import bind_parameters, from_msg, latched_qos, to_msg
from efficient_comm.handle import NodeHandle

from ..errors import SimConfigError
from .fall import STANDING
from .leg_ik import LIMITS, LegAngles, UnreachableError, foot_pose, leg_ik
from .motion import STANCE, Cadence
from .spline import Knot, QuinticSpline

LATCHED = latched_qos()
#: ``motion/kick/request`` data -> the kicking leg's side and the sign of its y.
SIDES = {"left": ("l", 1.0), "right": ("r", -1.0)}
#: Time step at which a kick's trajectory is checked against the legs' reach.
REACH_CHECK_S = 0.02
#: The swings (``KickParameters.swing``), and the joints the joint-space swing moves.
SWINGS = ("joint", "spline")
JOINT_SWING = ("hip_pitch", "knee", "ankle_pitch")


@dataclass(frozen=True, slots=True)
class ImuSample:
    """The torso's tilt (rad: pitch forward, roll to the right positive) and its rates."""

    pitch: float = 0.0
    roll: float = 0.0
    pitch_rate: float = 0.0
    roll_rate: float = 0.0

    @classmethod
    def from_imu(cls, imu: Imu) -> ImuSample:
        q = imu.orientation
        roll = math.atan2(2 * (q.w * q.x + q.y * q.z), 1 - 2 * (q.x * q.x + q.y * q.y))
        pitch = math.asin(max(-1.0, min(1.0, 2 * (q.w * q.y - q.z * q.x))))
        return cls(pitch=pitch, roll=roll, pitch_rate=imu.angular_velocity.y,
                   roll_rate=imu.angular_velocity.x)


@dataclass(frozen=True, slots=True)
class KickParameters:
    """The kick's figures; each is also a ROS parameter of the same name."""

    #: Time to move the trunk over the support foot, and back at the end (s).
    shift_s: float = 0.8
    #: How far the trunk moves sideways toward the support foot (m).
    shift_y: float = 0.05
    #: Extra hip roll of the support leg while on one foot (rad): the servos give under
    #: the body's weight, and the trunk sags toward the kicking side.
    support_roll: float = 0.1
    #: How much lower the trunk goes during the kick (m).
    crouch: float = 0.0
    #: Trunk leaning forward during the kick (rad).
    trunk_pitch: float = 0.0
    #: Lifting the kicking foot and drawing it back (s, m, m).
    lift_s: float = 0.35
    lift_height: float = 0.05
    draw_back: float = 0.05
    #: The swing through the ball: its time (s), the foot's height (m) and how far ahead of
    #: the hip it ends (m).
    swing_s: float = 0.1
    kick_height: float = 0.04
    reach: float = 0.10
    #: ``joint``: the kicking leg swings in joint space from ``windup_*`` (reached at the
    #: end of the lift) to ``swing_*`` (rad; hip pitch forward negative, knee bent
    #: positive); ``spline``: the foot follows ``draw_back``, ``kick_height``, ``reach``
    #: through the IK.
    swing: str = "joint"
    windup_hip_pitch: float = -0.2
    windup_knee: float = 1.7
    windup_ankle_pitch: float = -1.0
    swing_hip_pitch: float = -1.6
    swing_knee: float = 0.05
    swing_ankle_pitch: float = 0.0
    #: Bringing the foot back under the hip (s), and setting it down (s).
    retract_s: float = 0.4
    set_down_s: float = 0.35
    #: Standing still on both feet before the weight moves back (s).
    settle_s: float = 0.2
    #: Balance on the support foot, from the IMU: ankle pitch per rad of torso pitch and
    #: per rad/s of its rate; ankle roll per rad of torso roll and per rad/s of its rate.
    pitch_gain: float = 0.0
    gyro_pitch_gain: float = 0.15
    roll_gain: float = 1.0
    gyro_roll_gain: float = 0.4
    #: Low-pass time constant of the gyro feedback (s).
    gyro_filter_s: float = 0.03

    def check(self) -> None:
        """Raise :class:`SimConfigError` naming the first figure the kick cannot use."""
        rules = {
            "shift_s": 0.05 <= self.shift_s <= 5.0,
            "shift_y": 0.0 <= self.shift_y <= 0.1,
            "support_roll": abs(self.support_roll) <= 0.3,
            "crouch": 0.0 <= self.crouch <= 0.06,
            "trunk_pitch": abs(self.trunk_pitch) <= 0.5,
            "lift_s": 0.05 <= self.lift_s <= 5.0,
            "lift_height": 0.0 <= self.lift_height <= 0.12,
            "draw_back": 0.0 <= self.draw_back <= 0.15,
            "swing_s": 0.03 <= self.swing_s <= 2.0,
            "kick_height": 0.0 <= self.kick_height <= 0.12,
            "reach": 0.0 <= self.reach <= 0.2,
            "retract_s": 0.05 <= self.retract_s <= 5.0,
            "set_down_s": 0.05 <= self.set_down_s <= 5.0,
            "settle_s": 0.0 <= self.settle_s <= 5.0,
            "gyro_filter_s": self.gyro_filter_s >= 0,
        }
        for joint in JOINT_SWING:
            low, high = LIMITS[joint]
            for phase in ("windup", "swing"):
                rules[f"{phase}_{joint}"] = low <= getattr(self, f"{phase}_{joint}") <= high
        for name, ok in rules.items():
            if not ok or not math.isfinite(getattr(self, name)):
                raise SimConfigError(f"kick parameter {name} = {getattr(self, name)} is out "
                                     f"of range")
        if self.swing not in SWINGS:
            raise SimConfigError(f"kick parameter swing = {self.swing!r} is not one of "
                                 f"{', '.join(SWINGS)}")


#: The ROS parameters of the kick and their defaults.
PARAMETERS: dict[str, float | str] = asdict(KickParameters())


def _stance_foot(side: str) -> tuple[float, float, float]:
    """The foot origin in the hip frame in the standing pose (forward kinematics)."""
    angles = LegAngles(**{j: STANCE[f"{side}_{j}"] for j in (
        "hip_yaw", "hip_roll", "hip_pitch", "knee", "ankle_pitch", "ankle_roll")})
    return foot_pose(angles)[0]


def _path(*points: tuple[float, float]) -> QuinticSpline:
    return QuinticSpline([Knot(t, p) for t, p in points])


class KickMotion:
    """One kick's trajectory, free of ROS: time in, whole-body joint goals out.

    ``side`` is the kicking foot (``left`` or ``right``). :meth:`goals` is the pose at ``t``
    seconds into the kick; at 0 and from :attr:`duration` on it is the standing pose.
    """

    def __init__(self, side: str, parameters: KickParameters | None = None) -> None:
        if side not in SIDES:
            raise SimConfigError(f"kick side must be 'left' or 'right', got {side!r}")
        self.p = p = parameters or KickParameters()
        p.check()
        self.side, sign = SIDES[side]
        self.support = "r" if self.side == "l" else "l"
        t1 = p.shift_s
        t2 = t1 + p.lift_s
        t3 = t2 + p.swing_s
        t4 = t3 + p.retract_s
        t5 = t4 + p.set_down_s
        t6 = t5 + p.settle_s
        self.duration = t6 + p.shift_s
        #: When the swing starts and ends (s into the kick).
        self.swing = (t2, t3)
        end = self.duration
        # 0 -> 1 while the weight is over the support foot.
        self._shift = _path((0.0, 0.0), (t1, 1.0), (t6, 1.0), (end, 0.0))
        self._dy = sign * p.shift_y
        self._x = _path((0.0, 0.0), (t1, 0.0), (t2, -p.draw_back), (t3, p.reach), (t4, 0.0),
                        (end, 0.0))
        self._z = _path((0.0, 0.0), (t1, 0.0), (t2, p.lift_height), (t3, p.kick_height),
                        (t4, p.lift_height), (t5, 0.0), (end, 0.0))
        self._stance = {s: _stance_foot(s) for s in ("l", "r")}
        self._gyro = (0.0, 0.0)
        self._tilt = (0.0, 0.0)
        #: The joint-space swing: per joint of the kicking leg a spline from the lifted
        #: foot (t1) through the wind-up (t2) and the swing's end (t3) back to the lifted
        #: foot (t4), which the IK's path replaces between t1 and t4.
        self._joint_swing: dict[str, QuinticSpline] = {}
        self._joint_window = (t1, t4)
        if p.swing == "joint":
            lifted, back = self._ik_goals(t1), self._ik_goals(t4)
            for joint in JOINT_SWING:
                name = f"{self.side}_{joint}"
                self._joint_swing[name] = _path(
                    (0.0, lifted[name]), (t1, lifted[name]),
                    (t2, getattr(p, f"windup_{joint}")), (t3, getattr(p, f"swing_{joint}")),
                    (t4, back[name]), (end, back[name]))

    def set_imu(self, imu: ImuSample, dt: float) -> None:
        """Feed the torso's tilt (rad) and angular rates (rad/s); the rates low-pass filtered."""
        tau = self.p.gyro_filter_s
        k = 1.0 if tau <= 0 or dt <= 0 else min(1.0, dt / tau)
        gp, gr = self._gyro
        self._gyro = (gp + k * (imu.pitch_rate - gp), gr + k * (imu.roll_rate - gr))
        self._tilt = (imu.pitch, imu.roll)

    def goals(self, t: float) -> dict[str, float]:
        """The whole body's joint goals (rad) at ``t`` seconds into the kick."""
        goals = self._ik_goals(t)
        if self._joint_window[0] < t < self._joint_window[1]:
            for name, path in self._joint_swing.items():
                goals[name] = path(t)
        return goals

    def _ik_goals(self, t: float) -> dict[str, float]:
        """The goals with both feet on the IK's paths (the spline swing's, for either)."""
        p = self.p
        shift = self._shift(t)
        pitch = p.trunk_pitch * shift
        cp, sp = math.cos(pitch), math.sin(pitch)
        goals = dict(STANCE)
        for side in ("l", "r"):
            x, y, z = self._stance[side]
            y += self._dy * shift
            z += p.crouch * shift
            if side == self.side:
                x += self._x(t)
                z += self._z(t)
            # Into the pitched torso's frame (the hip frame turns with the trunk).
            tx, tz = cp * x - sp * z, sp * x + cp * z
            goals.update(leg_ik(tx, y, tz, pitch=-pitch).named(side))
        s = self.support
        gyro_pitch, gyro_roll = self._gyro
        tilt_pitch, tilt_roll = self._tilt
        goals[f"{s}_ankle_pitch"] += (p.pitch_gain * tilt_pitch + p.gyro_pitch_gain * gyro_pitch)
        goals[f"{s}_ankle_roll"] += shift * (p.roll_gain * tilt_roll + p.gyro_roll_gain * gyro_roll)
        goals[f"{s}_hip_roll"] += (1.0 if s == "l" else -1.0) * p.support_roll * shift
        return goals

    def check_reach(self) -> None:
        """Raise :class:`SimConfigError` if the trajectory leaves a leg's reach anywhere."""
        steps = math.ceil(self.duration / REACH_CHECK_S)
        try:
            for i in range(steps + 1):
                self.goals(i * self.duration / steps)
        except UnreachableError as exc:
            raise SimConfigError(f"kick parameters out of the leg's reach: {exc}") from None


def _check_kick(parameters: KickParameters) -> None:
    """SimConfigError (a ValueError, so a change is vetoed) for figures the kick cannot use,
    including ones that take a foot out of the leg's reach."""
    parameters.check()
    for side in SIDES:
        KickMotion(side, parameters).check_reach()


class Kick:
    """The kick component (see the module's docstring for topics and parameters)."""

    def __init__(self, node: NodeHandle) -> None:
        self.node = node
        rate = node.declare_parameter("rate_hz", 100.0)
        if not 1.0 <= rate <= 1000.0:
            raise SimConfigError(f"need 1 <= rate_hz <= 1000, got {rate}")
        self.parameters = bind_parameters(node, KickParameters(), check=_check_kick,
                                          on_change=self._on_parameters)
        self.p = self.parameters.value
        self.period_s = 1.0 / rate
        self.cadence, self._imu_cadence = Cadence(self.period_s), Cadence(self.period_s)
        self.motion: KickMotion | None = None
        self.t = 0.0
        self.motion_state = "stand"
        self.standing = True
        #: Kicks completed, requests refused, kicks aborted by a fall.
        self.kicks = self.refused = self.aborted = 0
        self._imu = ImuSample()
        self.pub = node.create_publisher(JointState, "motion/kick", qos=10)
        self.active_pub = node.create_publisher(Bool, "motion/kick/active", qos=LATCHED)
        node.create_subscription(String, "motion/kick/request", self._on_request, qos=10)
        node.create_subscription(String, "motion/state", self._on_motion_state, qos=LATCHED)
        node.create_subscription(String, "fall/state", self._on_posture, qos=LATCHED)
        node.create_subscription(Imu, "imu/data", self._on_imu, qos=10)
        node.create_timer(self.period_s, self.cycle)
        self.active_pub.publish(Bool(data=False))

    @property
    def active(self) -> bool:
        return self.motion is not None

    def _on_parameters(self, parameters: KickParameters) -> None:
        """Take new figures for the next kick (checked: one out of range was vetoed)."""
        self.p = parameters

    def _refuse(self, why: str) -> None:
        self.refused += 1
        self.node.logger.warning(f"kick refused: {why}")

    def _on_request(self, request: String) -> None:
        side = request.data.strip().lower()
        if side not in SIDES:
            self._refuse(f"request {request.data!r} is not 'left' or 'right'")
        elif self.motion is not None:
            self._refuse("a kick is under way")
        elif not self.standing or self.motion_state != "stand":
            self._refuse(f"the motion state is {self.motion_state!r}, not 'stand' (stop "
                         f"walking first)")
        else:
            self.motion = KickMotion(side, self.p)
            self.motion.set_imu(self._imu, 0.0)
            self.t = 0.0
            self.cadence.restart()
            self._imu_cadence.restart()
            self.node.logger.info(f"kick: {side} foot")
            self.active_pub.publish(Bool(data=True))

    def _on_motion_state(self, state: String) -> None:
        self.motion_state = state.data

    def _on_posture(self, posture: String) -> None:
        self.standing = posture.data == STANDING
        if not self.standing and self.motion is not None:
            self.aborted += 1
            self.node.logger.warning(f"kick aborted: the robot is {posture.data}")
            self._end()

    def _on_imu(self, imu: Imu) -> None:
        self._imu = ImuSample.from_imu(imu)
        if self.motion is not None:
            self.motion.set_imu(self._imu, self._imu_cadence.step_s(from_msg(imu.header.stamp)))

    def _end(self) -> None:
        self.motion = None
        self.active_pub.publish(Bool(data=False))

    def cycle(self) -> None:
        if self.motion is None:
            return
        now_ns = self.node.clock.now_ns()
        self.t += self.cadence.step_s(now_ns)
        goals = self.motion.goals(self.t)
        command = JointState(name=list(goals), position=list(goals.values()))
        command.header.stamp = to_msg(now_ns)
        self.pub.publish(command)
        if self.t >= self.motion.duration - 1e-9:
            self.kicks += 1
            self._end()
