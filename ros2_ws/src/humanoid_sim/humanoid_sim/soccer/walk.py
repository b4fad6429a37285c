"""The walk engine: an open-loop omnidirectional gait from foot splines and leg IK.

Modelled on the walk engines KidSize humanoids use (Rhoban's IKWalk, Bit-Bots' quintic
walk), written for our robot: a periodic gait whose phase runs at ``freq`` cycles a second;
in each cycle each foot is on the ground, moving backward under the trunk at the walking
velocity, then lifted and carried forward along quintic splines (:mod:`.spline`) to where
it lands; the trunk sways over the supporting foot. The feet's poses go through the
analytic inverse kinematics of :mod:`.leg_ik` to joint angles, sent every cycle of
``rate_hz`` as one whole-body JointState (legs, arms swinging against them, neck at rest).

Why the feet move as they do: a foot on the ground must move backward under the trunk at
exactly the trunk's velocity (any other speed is a slip), so each foot spends the share of
the cycle it is on the ground moving back by ``v (1 - air) / freq`` and the rest of the
cycle in the air, carried forward the same distance. Turning is the same with the feet's
yaw, their positions turned about the trunk's centre.

Smooth start and stop: the gait's amplitude (lift and sway) ramps up over one cycle before
the trunk is asked to move, the velocity follows the command within acceleration limits,
and a zero command slows the steps down to stepping in place, then stops them over one
cycle: the feet end on the ground in the standing pose.

Feedback from the IMU (``imu/data``): the torso's pitch and roll rates, low-pass filtered,
add to the ankles' pitch and the hips' roll (``gyro_pitch_gain``, ``gyro_roll_gain``):
damping a sway or a forward lurch before it grows, which the open-loop gait cannot.

Topics (relative to the robot namespace): ``cmd_vel`` (geometry_msgs/Twist: linear.x
forward, linear.y left in m/s, angular.z in rad/s; zero stops); ``fall/state`` (while the
robot is not standing, the walk stops and publishes nothing); published: ``motion/walk``
(sensor_msgs/JointState; ``output_topic`` renames it, e.g. to ``joint_commands`` to drive
the servo driver directly), ``motion/walk/active`` (std_msgs/Bool, transient local, on every
change: true while stepping, for the motion arbiter of :mod:`.arbiter`) and ``odom``
(nav_msgs/Odometry, integrated from the commanded steps, frame ``odom``, child
``base_footprint``). Every gait figure is a ROS parameter that
can be changed while it walks (see :data:`PARAMETERS`).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

from geometry_msgs.msg import Quaternion, Twist
from nav_msgs.msg import Odometry
from sensor_msgs.msg import Imu, JointState
from std_msgs.msg import Bool, String

from efficient_comm import bind_parameters, from_msg, latched_qos, to_msg
from efficient_comm.handle import NodeHandle

from ..errors import SimConfigError
from .leg_ik import HIP_OFFSET, SOLE_BELOW_FOOT, leg_ik
from .motion import STANCE, Cadence
from .spline import BUMP, SMOOTH_STEP

LATCHED = latched_qos()


@dataclass(frozen=True, slots=True)
class GaitParameters:
    """The walk's figures; each is also a ROS parameter of the same name."""

    #: Gait cycles a second (each foot steps once a cycle).
    freq: float = 2.0
    #: Share of each half cycle with both feet on the ground.
    double_support: float = 0.1
    #: How high the swing foot is lifted (m).
    step_height: float = 0.035
    #: Foot origin below the hip yaw joint, standing (m): how deep the crouch is.
    trunk_height: float = 0.255
    #: Feet further apart than the hips, each (m): room between the feet.
    foot_distance: float = 0.012
    #: Feet ahead of the hips (m): moves the trunk (and the centre of mass) back and forth.
    trunk_x: float = 0.0
    #: Trunk leaning forward (rad).
    trunk_pitch: float = 0.08
    #: Lateral sway of the trunk over the supporting foot (m, amplitude).
    sway: float = 0.022
    #: Phase lead of the sway over the steps (share of a cycle).
    sway_phase: float = 0.0
    #: Forward, sideways and turning speeds are capped at these (m/s, rad/s).
    max_vx: float = 0.25
    max_vy: float = 0.12
    max_wz: float = 0.9
    #: Acceleration limits of the commanded velocity (m/s², rad/s²).
    accel: float = 0.3
    accel_yaw: float = 1.5
    #: Extra lift (m) per m/s of forward speed: longer steps need more clearance.
    height_per_speed: float = 0.0
    #: Trunk pitch added per m/s of forward speed (rad s/m).
    pitch_per_speed: float = 0.0
    #: Ankle pitch per rad/s of torso pitch rate; hip roll per rad/s of roll rate.
    gyro_pitch_gain: float = 0.15
    gyro_roll_gain: float = 0.0
    #: Low-pass time constant of the gyro feedback (s).
    gyro_filter_s: float = 0.03
    #: Shoulder pitch per m of the opposite foot's forward offset (rad/m).
    arm_swing: float = 3.0
    #: Calibration of the commanded step to the velocity achieved (1: none).
    vx_scale: float = 0.87
    vy_scale: float = 0.85
    wz_scale: float = 0.87

    def check(self) -> None:
        """Raise :class:`SimConfigError` naming the first figure the gait cannot use."""
        rules = {
            "freq": 0.2 <= self.freq <= 5.0,
            "double_support": 0.0 <= self.double_support < 0.9,
            "step_height": 0.0 <= self.step_height <= 0.08,
            "trunk_height": 0.15 <= self.trunk_height <= 0.28,
            "foot_distance": -0.01 <= self.foot_distance <= 0.08,
            "trunk_x": abs(self.trunk_x) <= 0.08,
            "trunk_pitch": abs(self.trunk_pitch) <= 0.6,
            "sway": 0.0 <= self.sway <= 0.08,
            "sway_phase": abs(self.sway_phase) <= 0.5,
            "max_vx": 0.0 <= self.max_vx <= 1.0,
            "max_vy": 0.0 <= self.max_vy <= 0.5,
            "max_wz": 0.0 <= self.max_wz <= 3.0,
            "accel": self.accel > 0,
            "accel_yaw": self.accel_yaw > 0,
            "gyro_filter_s": self.gyro_filter_s >= 0,
            "vx_scale": 0.2 <= self.vx_scale <= 5.0,
            "vy_scale": 0.2 <= self.vy_scale <= 5.0,
            "wz_scale": 0.2 <= self.wz_scale <= 5.0,
        }
        for name, ok in rules.items():
            if not ok or not math.isfinite(getattr(self, name)):
                raise SimConfigError(f"walk parameter {name} = {getattr(self, name)} is out "
                                     f"of range")


#: The ROS parameters of the walk engine and their defaults.
PARAMETERS: dict[str, float] = asdict(GaitParameters())
SIDES = (("l", 0.0, 1.0), ("r", 0.5, -1.0))  # side, phase of its swing, sign of y


def _approach(value: float, target: float, step: float) -> float:
    return value + max(-step, min(step, target - value))


@dataclass(frozen=True, slots=True)
class FootTarget:
    """One foot relative to its standing place, in the level frame under the trunk."""

    x: float
    y: float
    z: float
    yaw: float


class Gait:
    """The gait generator, free of ROS: velocity command and IMU in, joint angles out.

    :meth:`update` advances it by ``dt`` and returns the whole body's joint goals; the
    component :class:`WalkEngine` calls it on a timer. Tests and the tuning harness drive
    it directly.
    """

    def __init__(self, parameters: GaitParameters | None = None) -> None:
        self.p = parameters or GaitParameters()
        self.p.check()
        self.phase = 0.0
        #: Gait amplitude: 0 standing, 1 walking (lift and sway scale with it).
        self.amplitude = 0.0
        self.command = (0.0, 0.0, 0.0)
        #: The velocity the steps are made for now (m/s, m/s, rad/s), after the limits.
        self.velocity = (0.0, 0.0, 0.0)
        #: Odometry from the commanded steps: x, y (m), yaw (rad) in the start's frame.
        self.odometry = (0.0, 0.0, 0.0)
        self._gyro = (0.0, 0.0)

    @property
    def walking(self) -> bool:
        return self.amplitude > 0.0

    def set_command(self, vx: float, vy: float, wz: float) -> None:
        """The wanted velocity, clipped to the limits; all zero stops the walk."""
        p = self.p
        self.command = (max(-p.max_vx, min(p.max_vx, vx)), max(-p.max_vy, min(p.max_vy, vy)),
                        max(-p.max_wz, min(p.max_wz, wz)))

    def set_gyro(self, pitch_rate: float, roll_rate: float, dt: float) -> None:
        """Feed the torso's angular rates (rad/s) through the low-pass filter."""
        tau = self.p.gyro_filter_s
        k = 1.0 if tau <= 0 else min(1.0, dt / tau)
        gp, gr = self._gyro
        self._gyro = (gp + k * (pitch_rate - gp), gr + k * (roll_rate - gr))

    def stop_now(self) -> None:
        """Forget the walk at once (the robot fell): standing pose, no velocity."""
        self.amplitude, self.phase = 0.0, 0.0
        self.velocity = self.command = (0.0, 0.0, 0.0)
        self._gyro = (0.0, 0.0)

    def update(self, dt: float) -> dict[str, float]:
        """Advance by ``dt`` seconds; the joint goals (rad) for that moment."""
        self._advance(dt)
        return self.joint_goals()

    def _advance(self, dt: float) -> None:
        p = self.p
        moving = any(self.command)
        if moving:
            self.amplitude = min(1.0, self.amplitude + dt * p.freq)
        target = self.command if self.amplitude >= 1.0 else (0.0, 0.0, 0.0)
        vx, vy, wz = self.velocity
        self.velocity = (_approach(vx, target[0], p.accel * dt),
                         _approach(vy, target[1], p.accel * dt),
                         _approach(wz, target[2], p.accel_yaw * dt))
        if not moving and not any(self.velocity):
            self.amplitude = max(0.0, self.amplitude - dt * p.freq)
        if self.amplitude > 0.0:
            self.phase = (self.phase + dt * p.freq) % 1.0
        else:
            self.phase = 0.0
        vx, vy, wz = self.velocity
        x, y, yaw = self.odometry
        c, s = math.cos(yaw), math.sin(yaw)
        self.odometry = (x + (c * vx - s * vy) * dt, y + (s * vx + c * vy) * dt, yaw + wz * dt)

    def foot(self, swing_phase: float) -> FootTarget:
        """Where a foot is, relative to its standing place, given its swing's phase."""
        p = self.p
        air = 0.5 * (1.0 - p.double_support)
        u = (self.phase - swing_phase) % 1.0
        start = 0.25 - air / 2  # the lift is centred in the foot's half cycle
        vx, vy, wz = self.velocity
        ground_share = (1.0 - air) / p.freq
        dx = vx / p.vx_scale * ground_share
        dy = vy / p.vy_scale * ground_share
        dyaw = wz / p.wz_scale * ground_share
        if start <= u < start + air:  # in the air: carried forward along the splines
            s = (u - start) / air
            along = SMOOTH_STEP(s) - 0.5
            height = (p.step_height + p.height_per_speed * abs(vx)) * self.amplitude
            z = height * BUMP(s)
        else:  # on the ground: moving back under the trunk at the walking velocity
            g = (u - start - air) % 1.0 / (1.0 - air)
            along = 0.5 - g
            z = 0.0
        return FootTarget(x=dx * along, y=dy * along, z=z, yaw=dyaw * along)

    def joint_goals(self) -> dict[str, float]:
        """The whole body's joint goals for the gait's present phase and velocity."""
        p = self.p
        pitch = p.trunk_pitch + p.pitch_per_speed * self.velocity[0]
        sway = p.sway * self.amplitude * math.sin(2 * math.pi * (self.phase + p.sway_phase))
        goals = dict(STANCE)
        gyro_pitch, gyro_roll = self._gyro
        cp, sp = math.cos(pitch), math.sin(pitch)
        forward: dict[str, float] = {}
        for side, swing_phase, sign in SIDES:
            foot = self.foot(swing_phase)
            hx, hy, hz = HIP_OFFSET[side]
            yaw = foot.yaw
            # Standing place of the foot (torso frame, level), turned about the trunk centre.
            nx, ny = p.trunk_x, hy + sign * p.foot_distance
            c, s = math.cos(yaw), math.sin(yaw)
            lx = c * nx - s * ny + foot.x
            ly = s * nx + c * ny + foot.y + sway
            lz = hz - p.trunk_height + foot.z
            # Into the pitched torso's frame, relative to the hip.
            tx, tz = cp * lx - sp * lz, sp * lx + cp * lz
            angles = leg_ik(tx - hx, ly - hy, tz - hz, yaw=yaw, pitch=-pitch)
            named = angles.named(side)
            named[f"{side}_ankle_pitch"] += p.gyro_pitch_gain * gyro_pitch
            named[f"{side}_hip_roll"] += p.gyro_roll_gain * gyro_roll
            goals.update(named)
            forward[side] = foot.x
        goals["l_shoulder_pitch"] = STANCE["l_shoulder_pitch"] - p.arm_swing * forward["r"]
        goals["r_shoulder_pitch"] = STANCE["r_shoulder_pitch"] - p.arm_swing * forward["l"]
        return goals


def standing_height(parameters: GaitParameters) -> float:
    """The torso origin's height above the ground when standing (m), trunk upright."""
    return -HIP_OFFSET["l"][2] + parameters.trunk_height + SOLE_BELOW_FOOT


def _yaw_quaternion(yaw: float) -> Quaternion:
    return Quaternion(w=math.cos(yaw / 2), x=0.0, y=0.0, z=math.sin(yaw / 2))


class WalkEngine:
    """The walk engine component (see the module's docstring for topics and parameters)."""

    def __init__(self, node: NodeHandle) -> None:
        self.node = node
        rate = node.declare_parameter("rate_hz", 100.0)
        output = node.declare_parameter("output_topic", "motion/walk")
        if not 1.0 <= rate <= 1000.0 or not output:
            raise SimConfigError(f"need 1 <= rate_hz <= 1000 and an output_topic, got "
                                 f"{rate}, {output!r}")
        self.parameters = bind_parameters(node, GaitParameters(), check=GaitParameters.check,
                                          on_change=self._on_parameters)
        self.gait = Gait(self.parameters.value)
        self.period_s = 1.0 / rate
        self.cadence, self._imu_cadence = Cadence(self.period_s), Cadence(self.period_s)
        self.standing = True
        self.cycles = 0
        self.pub = node.create_publisher(JointState, output, qos=10)
        self.odom_pub = node.create_publisher(Odometry, "odom", qos=10)
        #: Whether the robot is stepping (the motion arbiter forwards the goals only then).
        self.active = False
        self.active_pub = node.create_publisher(Bool, "motion/walk/active", qos=LATCHED)
        self.active_pub.publish(Bool(data=False))
        node.create_subscription(Twist, "cmd_vel", self._on_cmd_vel, qos=10)
        node.create_subscription(Imu, "imu/data", self._on_imu, qos=10)
        node.create_subscription(String, "fall/state", self._on_posture, qos=LATCHED)
        node.create_timer(self.period_s, self.cycle)

    def _on_parameters(self, parameters: GaitParameters) -> None:
        """Apply gait figures at once (checked: one out of range was vetoed already)."""
        self.gait.p = parameters

    def _on_cmd_vel(self, twist: Twist) -> None:
        values = (twist.linear.x, twist.linear.y, twist.angular.z)
        if not all(map(math.isfinite, values)):
            self.node.logger.error(f"cmd_vel ignored: {values} is not finite")
            return
        self.gait.set_command(*values)

    def _on_imu(self, imu: Imu) -> None:
        dt = self._imu_cadence.step_s(from_msg(imu.header.stamp))
        self.gait.set_gyro(imu.angular_velocity.y, imu.angular_velocity.x, dt)

    def _on_posture(self, posture: String) -> None:
        self.standing = posture.data == "standing"
        if not self.standing:
            self.gait.stop_now()
            self.cadence.restart()
            self._set_active(False)

    def _set_active(self, active: bool) -> None:
        if active != self.active:
            self.active = active
            self.active_pub.publish(Bool(data=active))

    def cycle(self) -> None:
        if not self.standing:
            return
        self.cycles += 1
        now_ns = self.node.clock.now_ns()
        goals = self.gait.update(self.cadence.step_s(now_ns))
        now = to_msg(now_ns)
        command = JointState(name=list(goals), position=list(goals.values()))
        command.header.stamp = now
        self.pub.publish(command)
        self._set_active(self.gait.walking)
        if self.odom_pub.get_subscription_count():
            self.odom_pub.publish(self.odometry(now))

    def odometry(self, stamp: object) -> Odometry:
        x, y, yaw = self.gait.odometry
        vx, vy, wz = self.gait.velocity
        odom = Odometry()
        odom.header.stamp = stamp
        odom.header.frame_id = "odom"
        odom.child_frame_id = "base_footprint"
        odom.pose.pose.position.x, odom.pose.pose.position.y = x, y
        odom.pose.pose.orientation = _yaw_quaternion(yaw)
        odom.twist.twist.linear.x, odom.twist.twist.linear.y = vx, vy
        odom.twist.twist.angular.z = wz
        return odom
