"""The striker: find the ball, walk behind it lined up with the opponent goal, kick, repeat.

It is the body's behaviour; the head's (:mod:`.behaviour`) keeps looking at the ball or
searching for it on its own. The striker knows only what a robot knows: where the ball
lies relative to it (``ball/position``, from the ball model), where it started (the
``start_pose`` parameter: where it was placed for kick-off), how far its steps carried it
(``odom``, the walk engine's odometry) and which way its torso faces (the IMU's
orientation, relative to the heading it had at the start). From these it keeps its own pose
and the ball's on the field, and so the direction to the opponent goal (``goal``).

At the start it stands for ``settle_s`` before it moves at all (the servos settle into the
stance; the head already looks). States (published on ``behaviour/state``, std_msgs/String,
latched, on every change):

* ``search``: the ball has not been seen for ``ball_lost_s``; the head sweeps, and after
  ``search_wait_s`` more the body turns in place (towards where the ball was last seen);
* ``approach``: walking (``cmd_vel``) to the kick position: ``kick_distance`` behind the
  ball on the line from the goal through the ball, the kicking foot (the one on the
  ball's side) ``foot_offset`` to the side, facing the goal; a robot in front of the ball
  walks around it first;
* ``stop``: there, within ``position_tolerance`` and ``heading_tolerance``: the walk is
  stopped (zero ``cmd_vel``) and the striker waits for ``motion/state`` ``stand``;
* ``kick``: still lined up, it requested the kick (``motion/kick/request``, ``left`` or
  ``right``) and waits for ``motion/state`` to go through ``kick`` and back to ``stand``,
  then starts over; a kick not begun within ``kick_start_s`` (refused) or not over within
  ``kick_timeout_s`` starts over too;
* ``fallen``: ``fall/state`` is not ``standing`` or ``motion/state`` is ``getup`` or
  ``fallen``: it does nothing (the get-up runs by itself) and searches when up again;
* ``position`` and ``wait``: the referee's game state does not let it play
  (:mod:`.game_control`, which reads ``game_state`` and the ``robot`` parameter, e.g.
  ``blue1``): it walks to its kick-off spot in ``ready`` (and out of the centre circle
  during the other team's kick-off), and stands otherwise. In a team game it attacks the
  goal of its team in this half, and a robot the referee placed for the kick-off takes its
  kick-off spot as its pose. Without a ``game_state`` it plays, as in the one-robot demo;
* ``support``, ``defend``, ``guard``: the team layer's ``role`` (std_msgs/String, latched,
  :class:`~.roles.Role` values) is not ``striker``: it walks to where its role stands and
  waits there facing the ball (:func:`role_pose`): a supporter ``support_distance`` behind
  the ball towards its own goal and to the side, a defender between the ball and its own
  goal, a goalie in front of its goal. Without a ``role`` (a robot playing alone) it is the
  striker.

Where its own camera has not seen the ball for ``ball_lost_s`` it takes the team's fused
ball (``team_ball``, geometry_msgs/PoseWithCovarianceStamped on the field, from
:class:`~.team_comm.TeamComm`) while that arrived within ``ball_lost_s``.

Every figure is a ROS parameter (see :data:`PARAMETERS`); ``rate_hz`` is the decision rate.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from geometry_msgs.msg import PointStamped, PoseWithCovarianceStamped, Twist
from nav_msgs.msg import Odometry
from sensor_msgs.msg import Imu
from std_msgs.msg import String

from efficient_comm.handle import NodeHandle
from soccer_field import KIDSIZE

from ..errors import SimConfigError
from .fall import LATCHED, STANDING
from .game_control import PLAY, POSITION, GameControl, Order
from .roles import Role

SEARCH, APPROACH, STOP, KICK, FALLEN = "search", "approach", "stop", "kick", "fallen"
#: Standing by the referee's order (walking to the kick-off spot is ``position``).
WAIT = "wait"
#: What the behaviour does in each role but the striker's: walk to its place and wait there.
ROLE_STATES = {Role.SUPPORTER: "support", Role.DEFENDER: "defend", Role.GOALIE: "guard"}
#: ``motion/state`` values (the motion arbiter's) during which the striker keeps still.
DOWN_MOTIONS = ("getup", "fallen")

#: The striker's parameters and their defaults (lengths in m, angles in rad, times in s).
PARAMETERS: dict[str, float | list[float]] = {
    "rate_hz": 10.0,
    "settle_s": 2.0,  # standing still at the start: the servos settle into the stance
    "start_pose": [0.0, 0.0, 0.0],  # x, y, heading on the field at the start
    "goal": list(KIDSIZE.opponent_goal),  # the opponent goal's centre on the field
    "kick_distance": 0.16,  # torso origin behind the ball's centre, along the kick
    "foot_offset": 0.045,  # the kicking foot (its hip) beside the torso origin
    "position_tolerance": 0.05,
    "heading_tolerance": 0.15,
    "max_vx": 0.175,  # forward; what the walk holds against shoves
    "max_vx_back": 0.08,
    "max_vy": 0.08,
    "max_wz": 0.6,
    "gain": 1.5,  # 1/s, from position error to velocity
    "turn_gain": 1.5,  # 1/s, from heading error to turning rate
    "ball_lost_s": 2.0,
    "search_wait_s": 3.0,
    "search_turn": 0.45,
    "kick_start_s": 1.0,  # a kick not begun by then was refused: line up again
    "kick_timeout_s": 6.0,
    "support_distance": 1.0,  # a supporter behind the ball, towards its own goal ...
    "support_side": 0.5,  # ... and this far to the side of that line
    "goalie_distance": 0.5,  # a goalie this far in front of its goal line
}


def _wrap(angle: float) -> float:
    return (angle + math.pi) % (2 * math.pi) - math.pi


def _yaw(x: float, y: float, z: float, w: float) -> float:
    return math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))


@dataclass(frozen=True, slots=True)
class Pose:
    """A pose on the field: x, y (m), heading (rad)."""

    x: float
    y: float
    heading: float

    def to_local(self, x: float, y: float) -> tuple[float, float]:
        """A field point in this pose's frame (x forward, y left)."""
        dx, dy = x - self.x, y - self.y
        c, s = math.cos(self.heading), math.sin(self.heading)
        return c * dx + s * dy, -s * dx + c * dy

    def to_field(self, x: float, y: float) -> tuple[float, float]:
        """A point in this pose's frame on the field."""
        c, s = math.cos(self.heading), math.sin(self.heading)
        return self.x + c * x - s * y, self.y + s * x + c * y


def kick_pose(ball: tuple[float, float], goal: tuple[float, float], *, foot: str,
              kick_distance: float, foot_offset: float) -> Pose:
    """Where the torso stands to kick ``ball`` at ``goal`` with ``foot``: behind the ball,
    facing the goal, the kicking foot in line with the ball."""
    ux, uy = goal[0] - ball[0], goal[1] - ball[1]
    norm = math.hypot(ux, uy) or 1.0
    ux, uy = ux / norm, uy / norm
    side = -1.0 if foot == "left" else 1.0  # the torso is on the other side of the foot
    return Pose(ball[0] - kick_distance * ux - side * foot_offset * uy,
                ball[1] - kick_distance * uy + side * foot_offset * ux,
                math.atan2(uy, ux))


def role_pose(role: Role, ball: tuple[float, float], own_goal: tuple[float, float], *,
              support_distance: float, support_side: float, goalie_distance: float) -> Pose:
    """Where a player of ``role`` (not the striker) waits, facing the ball: a supporter
    ``support_distance`` behind the ball towards ``own_goal`` and ``support_side`` to the
    side nearer the field's middle; a defender half way from its goal to the ball (at
    least a metre out); a goalie ``goalie_distance`` in front of its goal's centre, moved
    towards the ball's side by a quarter of the ball's offset."""
    gx, gy = own_goal
    inward = -1.0 if gx > 0 else 1.0  # from the own goal into the field
    if role == Role.GOALIE:
        x, y = gx + inward * goalie_distance, max(-0.6, min(0.6, 0.25 * ball[1]))
    else:
        dx, dy = gx - ball[0], gy - ball[1]
        norm = math.hypot(dx, dy) or 1.0
        ux, uy = dx / norm, dy / norm  # from the ball towards the own goal
        if role == Role.DEFENDER:
            along = max(min(1.0, norm), 0.5 * norm)
            x, y = gx - along * ux, gy - along * uy
        else:
            side = -1.0 if ball[1] > 0 else 1.0
            x = ball[0] + support_distance * ux - side * support_side * uy
            y = ball[1] + support_distance * uy + side * support_side * ux
    half_l, half_w = KIDSIZE.half_length - 0.2, KIDSIZE.half_width - 0.2
    x, y = max(-half_l, min(half_l, x)), max(-half_w, min(half_w, y))
    return Pose(x, y, math.atan2(ball[1] - y, ball[0] - x))


class Striker:
    """The striker component (see the module's docstring for topics and parameters)."""

    def __init__(self, node: NodeHandle) -> None:
        self.node = node
        p = {name: node.declare_parameter(name, default) for name, default in PARAMETERS.items()}
        start, goal = p["start_pose"], p["goal"]
        scalars = {name: value for name, value in p.items() if isinstance(value, float)}
        if (not isinstance(start, list) or len(start) != 3 or not isinstance(goal, list)
                or len(goal) != 2 or not all(map(math.isfinite, [*start, *goal]))):
            raise SimConfigError(f"start_pose is [x, y, heading] and goal [x, y], got "
                                 f"{start}, {goal}")
        for name, value in scalars.items():
            if not (math.isfinite(value) and value >= 0) or (
                    name in ("rate_hz", "gain", "turn_gain") and value == 0):
                raise SimConfigError(f"striker parameter {name} = {value} is out of range")
        self.p = scalars
        self.goal = (float(goal[0]), float(goal[1]))
        self.start = Pose(float(start[0]), float(start[1]), float(start[2]))
        #: The robot's own pose on the field, from odometry and the IMU (never the truth).
        self.pose = self.start
        #: The ball on the field (estimated) and when it was last seen (ns).
        self.ball: tuple[float, float] | None = None
        self.ball_seen_ns: int | None = None
        self.state = SEARCH
        self.posture = STANDING
        self.motion = "stand"
        self.foot = "left"
        self.kicks = 0
        #: The team layer's role for this robot (None or undefined: it plays striker).
        self.role: Role | None = None
        #: The team's fused ball on the field and when it arrived (this robot's clock, ns).
        self.team_ball: tuple[float, float] | None = None
        self._team_ball_ns: int | None = None
        self._since_ns = self._start_ns = node.clock.now_ns()
        self._imu_yaw0: float | None = None
        self._imu_heading: float | None = None
        self._odom: tuple[float, float, float] | None = None
        self._kick_seen = False
        self._moving = False
        self._search_side = 1.0
        self.cmd_pub = node.create_publisher(Twist, "cmd_vel", qos=10)
        self.kick_pub = node.create_publisher(String, "motion/kick/request", qos=10)
        self.state_pub = node.create_publisher(String, "behaviour/state", qos=LATCHED)
        node.create_subscription(PointStamped, "ball/position", self._on_ball, qos=10)
        node.create_subscription(Odometry, "odom", self._on_odom, qos=10)
        node.create_subscription(Imu, "imu/data", self._on_imu, qos=10)
        node.create_subscription(String, "fall/state", self._on_posture, qos=LATCHED)
        node.create_subscription(String, "motion/state", self._on_motion, qos=LATCHED)
        node.create_subscription(String, "role", self._on_role, qos=LATCHED)
        node.create_subscription(PoseWithCovarianceStamped, "team_ball", self._on_team_ball,
                                 qos=10)
        self.game = GameControl(node, on_change=self.decide)
        self.state_pub.publish(String(data=self.state))
        node.create_timer(1.0 / self.p["rate_hz"], self.decide)

    # -- what the robot knows -------------------------------------------------------------

    def _on_imu(self, imu: Imu) -> None:
        q = imu.orientation
        if not all(map(math.isfinite, (q.x, q.y, q.z, q.w))) or not any((q.x, q.y, q.z, q.w)):
            return
        yaw = _yaw(q.x, q.y, q.z, q.w)
        if self._imu_yaw0 is None:
            self._imu_yaw0 = yaw
        self._imu_heading = _wrap(self.start.heading + yaw - self._imu_yaw0)
        self.pose = Pose(self.pose.x, self.pose.y, self._imu_heading)

    def _on_odom(self, odom: Odometry) -> None:
        """Move the pose by the odometry's step, turned into the field by the heading."""
        q = odom.pose.pose.orientation
        now = (odom.pose.pose.position.x, odom.pose.pose.position.y,
               _yaw(q.x, q.y, q.z, q.w))
        if not all(map(math.isfinite, now)):
            return
        last, self._odom = self._odom, now
        if last is None:
            return
        dx, dy = now[0] - last[0], now[1] - last[1]
        c, s = math.cos(last[2]), math.sin(last[2])
        forward, left = c * dx + s * dy, -s * dx + c * dy  # the step in the robot's frame
        heading = (self._imu_heading if self._imu_heading is not None
                   else _wrap(self.pose.heading + now[2] - last[2]))
        moved = Pose(self.pose.x, self.pose.y, self.pose.heading).to_field(forward, left)
        self.pose = Pose(moved[0], moved[1], heading)

    def _on_ball(self, position: PointStamped) -> None:
        if self.state == FALLEN:
            return
        seen = self.pose.to_field(position.point.x, position.point.y)
        if self.ball is not None and math.dist(seen, self.ball) < 0.3:
            seen = (0.5 * (seen[0] + self.ball[0]), 0.5 * (seen[1] + self.ball[1]))
        self.ball = seen
        self.ball_seen_ns = self.node.clock.now_ns()

    def _on_role(self, role: String) -> None:
        try:
            self.role = Role(role.data)
        except ValueError:
            self.node.logger.warning(f"role {role.data!r} is not a role; kept {self.role}")

    def _on_team_ball(self, msg: PoseWithCovarianceStamped) -> None:
        p = msg.pose.pose.position
        if math.isfinite(p.x) and math.isfinite(p.y):
            self.team_ball = (p.x, p.y)
            self._team_ball_ns = self.node.clock.now_ns()

    def _on_posture(self, posture: String) -> None:
        self.posture = posture.data
        self.decide()

    def _on_motion(self, state: String) -> None:
        self.motion = state.data
        if state.data == "kick":
            self._kick_seen = True
        self.decide()

    # -- deciding -------------------------------------------------------------------------

    def _set_state(self, state: str) -> None:
        if state != self.state:
            self.state = state
            self._since_ns = self.node.clock.now_ns()
            self.state_pub.publish(String(data=state))
            self.node.logger.info(f"striker: {state}")

    def _seconds_in_state(self) -> float:
        return (self.node.clock.now_ns() - self._since_ns) / 1e9

    def _walk(self, vx: float, vy: float, wz: float) -> None:
        if not (vx or vy or wz) and not self._moving:
            return  # stopped already: say it once
        self._moving = bool(vx or vy or wz)
        twist = Twist()
        twist.linear.x, twist.linear.y, twist.angular.z = vx, vy, wz
        self.cmd_pub.publish(twist)

    def _fresh(self, seen_ns: int | None) -> bool:
        return seen_ns is not None and (
            self.node.clock.now_ns() - seen_ns) / 1e9 < self.p["ball_lost_s"]

    def ball_known(self) -> bool:
        """Whether it knows where the ball is: seen itself lately, or else told by the
        team lately (then ``ball`` is the team's)."""
        if self._fresh(self.ball_seen_ns):
            return True
        if self.team_ball is not None and self._fresh(self._team_ball_ns):
            self.ball = self.team_ball
            return True
        return False

    def target(self) -> Pose:
        """The kick position for the ball as now known, choosing the foot on its side."""
        assert self.ball is not None
        if self.state != STOP:
            _, left = self.pose.to_local(*self.ball)
            if abs(left) > 0.03:  # hysteresis: a ball straight ahead keeps the foot
                self.foot = "left" if left > 0 else "right"
        return kick_pose(self.ball, self.game.goal() or self.goal, foot=self.foot,
                         kick_distance=self.p["kick_distance"],
                         foot_offset=self.p["foot_offset"])

    def decide(self) -> None:
        """One decision: called by the timer and whenever posture or motion change."""
        if self.posture != STANDING or self.motion in DOWN_MOTIONS:
            if self.state != FALLEN:
                self._moving = True  # say stop even if it was never told to move
                self._walk(0.0, 0.0, 0.0)
                self.ball_seen_ns = None  # lying down it lost track: look again once up
            self._set_state(FALLEN)
            return
        placed = self.game.placed(self.pose.x, self.pose.y)
        if placed is not None:  # put on its kick-off spot: its heading from the IMU anew
            self.start = self.pose = Pose(*placed)
            self._imu_yaw0 = None
        order = self.game.order(self.pose.x, self.pose.y)
        if order.what != PLAY:
            self._obey(order)
            return
        if self.state == KICK:
            self._kicking()
            return
        if (self.node.clock.now_ns() - self._start_ns) / 1e9 < self.p["settle_s"]:
            return  # standing at the start: nothing moves yet
        if not self.ball_known():
            self._search()
            return
        if self.role in ROLE_STATES:
            self._take_place(self.role)
            return
        goal = self.target()
        x, y = self.pose.to_local(goal.x, goal.y)
        turn = _wrap(goal.heading - self.pose.heading)
        there = (math.hypot(x, y) < self.p["position_tolerance"]
                 and abs(turn) < self.p["heading_tolerance"])
        if self.state == STOP:
            self._stopping(x, y, turn)
        elif there:
            self._walk(0.0, 0.0, 0.0)
            self._set_state(STOP)
        else:
            self._set_state(APPROACH)
            self._approach(goal)

    def _obey(self, order: Order) -> None:
        """The referee does not let it play: stand, or walk to ``order.target`` and stand
        there (within twice the tolerances; four times once there, so it does not dither)."""
        settling = (self.node.clock.now_ns() - self._start_ns) / 1e9 < self.p["settle_s"]
        if order.target is not None and not settling:
            x, y = self.pose.to_local(order.target[0], order.target[1])
            turn = _wrap(order.target[2] - self.pose.heading)
            slack = 4.0 if self.state == WAIT else 2.0
            if (math.hypot(x, y) > slack * self.p["position_tolerance"]
                    or abs(turn) > slack * self.p["heading_tolerance"]):
                self._set_state(POSITION)
                self._walk_to(*order.target)
                return
        self._walk(0.0, 0.0, 0.0)
        self._set_state(WAIT)

    def _take_place(self, role: Role) -> None:
        """Not the striker: walk to the role's place (:func:`role_pose`) and wait there."""
        assert self.ball is not None
        attacked = self.game.goal() or self.goal
        place = role_pose(role, self.ball, (-attacked[0], -attacked[1]),
                          support_distance=self.p["support_distance"],
                          support_side=self.p["support_side"],
                          goalie_distance=self.p["goalie_distance"])
        state = ROLE_STATES[role]
        x, y = self.pose.to_local(place.x, place.y)
        turn = _wrap(place.heading - self.pose.heading)
        slack = 4.0 if self.state == state and not self._moving else 2.0
        if (math.hypot(x, y) > slack * self.p["position_tolerance"]
                or abs(turn) > slack * self.p["heading_tolerance"]):
            self._walk_to(place.x, place.y, place.heading)
        else:
            self._walk(0.0, 0.0, 0.0)
        self._set_state(state)

    def _search(self) -> None:
        if self.state != SEARCH:
            self._walk(0.0, 0.0, 0.0)
            self._set_state(SEARCH)
            # Turn towards where the ball was last seen, and keep turning that way.
            self._search_side = 1.0
            if self.ball is not None and self.pose.to_local(*self.ball)[1] < 0:
                self._search_side = -1.0
        if self._seconds_in_state() >= self.p["search_wait_s"]:
            self._walk(0.0, 0.0, self._search_side * self.p["search_turn"])

    def _stopping(self, x: float, y: float, turn: float) -> None:
        """Stopped there: kick once the walk has stood still, if still lined up."""
        if self.motion != "stand":
            return
        slack = 2.0  # the last steps of a stop slide a little: do not start over for that
        if (math.hypot(x, y) < slack * self.p["position_tolerance"]
                and abs(turn) < slack * self.p["heading_tolerance"]):
            self._kick_seen = False
            self.kick_pub.publish(String(data=self.foot))
            self._set_state(KICK)
        else:
            self._set_state(APPROACH)

    def _kicking(self) -> None:
        done = self._kick_seen and self.motion == "stand"
        waited = self._seconds_in_state()
        if done or waited > self.p["kick_timeout_s"] or (
                not self._kick_seen and waited > self.p["kick_start_s"]):
            if done:
                self.kicks += 1
            else:
                self.node.logger.warning("striker: the kick did not happen; starting over")
            self._set_state(SEARCH if not self.ball_known() else APPROACH)

    def _approach(self, goal: Pose) -> None:
        """Walk to ``goal``: around the ball if in front of it, facing the way to go while
        far, turning to the kick's heading on the last half metre."""
        assert self.ball is not None
        bx, by = self.ball
        ux, uy = math.cos(goal.heading), math.sin(goal.heading)
        along = (self.pose.x - bx) * ux + (self.pose.y - by) * uy
        across = -(self.pose.x - bx) * uy + (self.pose.y - by) * ux
        tx, ty = goal.x, goal.y
        if along > -0.5 * self.p["kick_distance"] and abs(across) < 0.35:
            side = 1.0 if across >= 0 else -1.0  # beside the ball, on the robot's side
            tx, ty = bx - 0.25 * ux - side * 0.4 * uy, by - 0.25 * uy + side * 0.4 * ux
        self._walk_to(tx, ty, goal.heading)

    def _walk_to(self, tx: float, ty: float, end_heading: float) -> None:
        """Walk to ``tx, ty``, facing the way to go while far and turning to ``end_heading``
        on the last half metre."""
        x, y = self.pose.to_local(tx, ty)
        distance = math.hypot(x, y)
        near = min(1.0, max(0.0, (distance - 0.2) / 0.4))  # 1 far, 0 on the last 0.2 m
        facing = math.atan2(y, x) if distance > 1e-6 else 0.0
        heading = near * facing + (1 - near) * _wrap(end_heading - self.pose.heading)
        wz = max(-self.p["max_wz"], min(self.p["max_wz"], self.p["turn_gain"] * heading))
        vx, vy = self.p["gain"] * x, self.p["gain"] * y
        if abs(heading) > 0.8 and distance > 0.3:  # mostly turn first
            vx, vy = 0.3 * vx, 0.3 * vy
        limit_x = self.p["max_vx"] if vx >= 0 else self.p["max_vx_back"]
        scale = max(1.0, abs(vx) / limit_x if limit_x else math.inf,
                    abs(vy) / self.p["max_vy"] if self.p["max_vy"] else math.inf)
        self._walk(vx / scale, vy / scale, wz)
