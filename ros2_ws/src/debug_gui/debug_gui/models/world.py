"""The world view's data: every robot's pose and ball on the field, beliefs and truth.

Per robot it follows (relative to the robot's namespace):

* ``localization/pose`` (geometry_msgs/PoseWithCovarianceStamped, field frame): the
  robot's belief of its pose where it localizes (the team match's robots), else
* ``odom`` (nav_msgs/Odometry): the robot's own belief of its pose, from its steps;
* ``ball/estimate`` (geometry_msgs/PointStamped, frame ``torso``): the ball model's bearing
  (``x`` yaw, ``y`` pitch, radians) and line-of-sight distance (``z``, metres; 0 = unknown);
* ``team_ball`` (PoseWithCovarianceStamped, field frame): the ball the robot's team
  shares, as this robot fused it (the team match's robots);
* ``ground_truth/robot`` (``ground_truth/pose`` in the team match), ``ground_truth/ball``
  (PoseStamped, field frame): what a simulation knows to be true, drawn apart from the
  beliefs so errors show;
* ``motion/state`` (std_msgs/String, latched): which motion owns the joints (``stand``,
  ``walk``, ``kick``, ``getup``, ``fallen``, as humanoid_sim's motion arbiter says), so a
  robot that stopped, fell or is kicking says so on the field;
* ``role`` (std_msgs/String, latched): the robot's role in its team (``striker``, ...);
* ``game_state`` (soccer_interfaces/GameState, latched): the referee's broadcast as the
  robot received it: the view shows the newest any robot has (state, score, kick-off).

Ages are judged on each robot's own clock, tied to the source's (:mod:`.ages`): the
robot's "now" is the newest stamp of the messages it stamps itself (odometry,
localization, ball estimates, team ball) plus the source's time since it was delivered,
never a stamp of ground truth or the game state, which the world stamps: robots' clocks may
be skewed against the world's (as separate computers' are), and a ball estimate must not
look old because the world's clock runs ahead. So a paused playback keeps every belief as
old as it was, a jump forward ages them all, and a seek (``reset``) forgets everything.

Odometry starts where the robot started, not at the field's origin, so its frame is anchored
where it agrees with ground truth the first time the view has both (a simulation: drift
then shows from that moment on), else at the field's centre. A robot
without odometry is placed by ground truth, and its pose is labelled so: the ball estimate
is then the robot's belief on a true pose.

The team's ball is what the robots' fresh estimates (younger than :data:`FRESH_S`) say
together: their mean, each weighted by 1 / distance, because a ball seen from nearer is
seen sharper. It is the GUI's fusion, labelled as such, drawn only while no robot tells
the ball its team shares (``team_ball``): then each robot's own is drawn.

Team colours: robots named as the team match names them (``blue1`` .. ``blue3``,
``red1`` .. ``red3``) are drawn in shades of their team's colour; others get a colour of
their own from their name.
"""

from __future__ import annotations

import functools
import math
import re
import threading
import zlib
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from efficient_comm import from_msg, latched_qos
from soccer_field import KIDSIZE

from ..robots import RobotId
from ..source import Source, Stream
from .ages import StampAges

#: The field the view draws, by the names ui/world.py uses (metres); the dimensions are
#: soccer_field's, the same the simulator builds and the referee judges with.
FIELD = {
    "length": KIDSIZE.length, "width": KIDSIZE.width,
    "goal_area_depth": KIDSIZE.goal_area_length, "goal_area_width": KIDSIZE.goal_area_width,
    "penalty_area_depth": KIDSIZE.penalty_area_length,
    "penalty_area_width": KIDSIZE.penalty_area_width,
    "penalty_mark": KIDSIZE.penalty_mark_distance, "centre_circle": KIDSIZE.centre_circle_diameter,
    "border": KIDSIZE.border_strip_width, "goal_width": KIDSIZE.goal_width,
}
#: A ball estimate older than this (seconds, by message stamps) no longer counts for the
#: team ball; the view fades it from here on.
FRESH_S = 1.0
#: A ball estimate older than this is not drawn at all: a belief of 14 s ago is no belief.
STALE_S = 3.0
#: Distinct colours; each robot's is chosen by its name (see :func:`colours_for`).
COLOURS = ("#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#17becf", "#8c564b")
#: Shades of each team's colour, player 1 first (the team match's robot names).
TEAM_COLOURS = {"blue": ("#1f4fd8", "#00a2e8", "#0b1f66"),
                "red": ("#d62728", "#ff7f50", "#7a0010")}
_TEAM_ROBOT = re.compile(r"^(?P<team>blue|red)(?P<number>[1-9])$")
TOPICS = ("odom", "localization/pose", "ball/estimate", "team_ball", "ground_truth/robot",
          "ground_truth/pose", "ground_truth/ball", "motion/state", "role", "game_state")
#: Latched state topics: a view opened later still learns the current state at once.
LATCHED = latched_qos()


@dataclass(frozen=True, slots=True)
class Pose2D:
    x: float
    y: float
    yaw: float


@dataclass(frozen=True, slots=True)
class RobotState:
    """One robot on the field, as the view draws it (field frame, metres, radians)."""

    robot: RobotId
    colour: str
    #: The robot's pose belief (odometry anchored to the field) or, without odometry,
    #: ground truth; ``pose_source`` says which ("odom", "ground truth" or "" = unknown).
    pose: Pose2D | None
    pose_source: str
    #: Where the robot believes the ball is, on the field (None: no estimate yet).
    ball: tuple[float, float] | None
    ball_age_s: float | None
    true_pose: Pose2D | None
    true_ball: tuple[float, float] | None
    #: Which motion owns the joints ("" until the robot says).
    motion: str = ""
    #: The robot's role in its team ("" until it says, or a robot without one).
    role: str = ""
    #: The ball the robot's team shares, as this robot fused it (field frame), and its age
    #: on the robot's clock (None: the robot tells none, or it is too old to be drawn).
    team_ball: tuple[float, float] | None = None
    team_ball_age_s: float | None = None
    #: How old the pose is (the robot's belief by its stamp, ground truth since it was
    #: delivered), on the source's clock; None without a pose.
    pose_age_s: float | None = None

    @property
    def pose_stale(self) -> bool:
        """The pose is older than :data:`STALE_S` (the robot stopped telling it)."""
        return self.pose_age_s is not None and self.pose_age_s > STALE_S

    @property
    def team(self) -> str:
        """``blue`` or ``red`` for a robot named as the team match names them, else ""."""
        return team_of(self.robot)


@dataclass(frozen=True, slots=True)
class Game:
    """The referee's broadcast (soccer_interfaces/GameState) as the view shows it."""

    #: ``initial``, ``ready``, ``set``, ``playing``, ``finished``.
    state: str
    #: The set play (``normal``, ``throw in``, ``corner kick``, ...).
    secondary: str
    first_half: bool
    #: Goals by team colour (``{"blue": 1, "red": 0}``).
    score: dict[str, int]
    #: The team colour that has the kick-off or the set play ("" if neither team's).
    kicking: str
    seconds_remaining: int
    secondary_seconds_remaining: int

    def text(self) -> str:
        """One line: ``playing, 1st half, blue 1 : 0 red, kick-off blue, 583 s left``."""
        parts = [self.state, "1st half" if self.first_half else "2nd half",
                 f"blue {self.score.get('blue', 0)} : {self.score.get('red', 0)} red"]
        if self.secondary != "normal":
            parts.append(f"{self.secondary} {self.kicking}".strip()
                         + f" ({self.secondary_seconds_remaining} s)")
        elif self.kicking and self.state in ("ready", "set"):
            parts.append(f"kick-off {self.kicking}")
        parts.append(f"{self.seconds_remaining} s left")
        return ", ".join(parts)


def _constant_names(cls: type, prefix: str) -> dict[int, str]:
    """``{3: "playing"}`` from ``STATE_PLAYING = 3``: the message's own constants, so no
    number is written twice."""
    return {getattr(cls, name): name[len(prefix):].lower().replace("_", " ")
            for name in dir(cls) if name.startswith(prefix) and name[len(prefix):].isupper()}


def read_game(msg: Any) -> Game:
    """A GameState message as the view shows it (teams by their ``team_colour``)."""
    cls = type(msg)
    states, secondaries = _constant_names(cls, "STATE_"), _constant_names(cls, "STATE2_")
    score: dict[str, int] = {}
    kicking = ""
    for team in msg.teams:
        colour = _constant_names(type(team), "COLOUR_").get(team.team_colour,
                                                            f"team {team.team_number}")
        score[colour] = int(team.score)
        if team.team_number == msg.kicking_team and team.team_number:
            kicking = colour
    return Game(state=states.get(msg.game_state, f"state {msg.game_state}"),
                secondary=secondaries.get(msg.secondary_state,
                                          f"set play {msg.secondary_state}"),
                first_half=bool(msg.first_half), score=score, kicking=kicking,
                seconds_remaining=int(msg.seconds_remaining),
                secondary_seconds_remaining=int(msg.secondary_seconds_remaining))


def team_of(robot: RobotId) -> str:
    """``blue`` or ``red`` for a robot named as the team match names them, else ""."""
    m = _TEAM_ROBOT.match(robot.name)
    return m["team"] if m else ""


def colours_for(robots: list[RobotId]) -> dict[RobotId, str]:
    """Each robot's colour, from its name: a robot keeps its colour when others come and
    go (colours by position changed every robot's colour when one appeared). A team
    match's robot takes its team's shade for its number. Two other names that hash alike:
    the one first in name order keeps it, the next takes the next free colour."""
    out: dict[RobotId, str] = {}
    for robot in robots:
        m = _TEAM_ROBOT.match(robot.name)
        shades = TEAM_COLOURS[m["team"]] if m else ()
        if m and int(m["number"]) <= len(shades):
            out[robot] = shades[int(m["number"]) - 1]
    for robot in sorted(set(robots) - set(out), key=lambda r: (r.namespace, r.domain)):
        slot = zlib.crc32(robot.namespace.encode()) % len(COLOURS)
        for step in range(len(COLOURS)):
            colour = COLOURS[(slot + step) % len(COLOURS)]
            if colour not in out.values() or len(out) >= len(COLOURS):
                break
        out[robot] = colour
    return out


def yaw_of(q: Any) -> float:
    """Heading (rotation about z) of a geometry_msgs quaternion."""
    return math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))


def pose_2d(pose: Any) -> Pose2D:
    """A geometry_msgs Pose on the field's plane."""
    return Pose2D(pose.position.x, pose.position.y, yaw_of(pose.orientation))


def compose(base: Pose2D, local: Pose2D) -> Pose2D:
    """``local`` (a pose in ``base``'s frame) in the frame ``base`` is given in."""
    c, s = math.cos(base.yaw), math.sin(base.yaw)
    return Pose2D(base.x + c * local.x - s * local.y, base.y + s * local.x + c * local.y,
                  math.atan2(math.sin(base.yaw + local.yaw), math.cos(base.yaw + local.yaw)))


def invert(pose: Pose2D) -> Pose2D:
    """The inverse transform: ``compose(pose, invert(pose))`` is the identity."""
    c, s = math.cos(pose.yaw), math.sin(pose.yaw)
    return Pose2D(-c * pose.x - s * pose.y, s * pose.x - c * pose.y, -pose.yaw)


def ball_in_torso(estimate: Any) -> tuple[float, float] | None:
    """The ball on the ground relative to the torso, from the ball model's bearing/distance."""
    yaw, pitch, distance = estimate.point.x, estimate.point.y, estimate.point.z
    if not (distance > 0 and math.isfinite(distance) and math.isfinite(yaw)):
        return None
    ground = distance * abs(math.cos(pitch)) if math.isfinite(pitch) else distance
    return ground * math.cos(yaw), ground * math.sin(yaw)


class _Robot:
    """What one robot's feeds told (written on the Hub's thread, read under the lock)."""

    def __init__(self, robot: RobotId, colour: str, clock: Callable[[], float]) -> None:
        self.robot = robot
        self.colour = colour
        self.ages = StampAges(clock)
        self.feeds: list[Stream] = []
        self.reset()

    def reset(self) -> None:
        """Forget everything heard (a seek); the robot, its colour and feeds stay."""
        self.ages.reset()
        self.odom: Pose2D | None = None
        self.odom_at = (0, 0.0)  # (stamp ns, delivered on the source's clock)
        self.anchor: Pose2D | None = None
        self.ball: tuple[float, float] | None = None  # torso frame
        self.ball_heard: float | None = None
        self.ball_stamp_ns = 0
        self.true_pose: Pose2D | None = None
        self.true_heard = 0.0
        self.true_ball: tuple[float, float] | None = None
        self.motion = ""
        self.role = ""
        #: The robot's localization (field frame): preferred to odometry once heard.
        self.localized: Pose2D | None = None
        self.localized_at = (0, 0.0)
        self.team_ball: tuple[float, float] | None = None
        self.team_ball_at = (0, 0.0)

    def heard(self, stamp: Any) -> tuple[int, float]:
        """A stamp of the robot's own clock (never one the world stamped: see the module
        docstring), and when it was delivered on the source's clock."""
        ns = from_msg(stamp)
        return ns, self.ages.heard(ns)

    def age_s(self, at: tuple[int, float]) -> float:
        return self.ages.age_s(at[0], delivered_s=at[1])

    def team_ball_age_s(self) -> float | None:
        return None if self.team_ball is None else self.age_s(self.team_ball_at)

    def ball_age_s(self) -> float | None:
        """By its stamp where the robot stamps its messages (its clock, not the GUI's:
        under lockstep they differ), else since it was delivered."""
        if self.ball_heard is None:
            return None
        return self.age_s((self.ball_stamp_ns, self.ball_heard))

    def anchor_if_possible(self) -> None:
        """Fix the odometry frame on the field where odometry and truth first meet."""
        if self.anchor is None and self.odom is not None and self.true_pose is not None:
            self.anchor = compose(self.true_pose, invert(self.odom))


class WorldModel:
    """Several robots on one field (activate to receive, deactivate to stop)."""

    def __init__(
        self,
        source: Source,
        robots: list[RobotId],
        *,
        rate_hz: float = 10.0,
        clock: Callable[[], float] | None = None,
    ) -> None:
        self.source = source
        self.rate_hz = rate_hz
        #: The source's clock (seconds): monotonic live, the log's time in a playback.
        self._clock = clock or source.now
        self._lock = threading.Lock()
        colours = colours_for(robots)
        self._robots = [_Robot(r, colours[r], self._clock) for r in robots]
        self._unsubscribe_reset: Callable[[], None] | None = None
        #: The newest game state any robot received, and its stamp (the world's clock).
        self._game: Game | None = None
        self._game_key = (-1, -1)
        self.active = False

    # -- feeds ---------------------------------------------------------------------------

    def activate(self) -> None:
        """Subscribe to every robot's poses and ball at the view's rate (idempotent)."""
        from geometry_msgs.msg import PointStamped, PoseStamped, PoseWithCovarianceStamped
        from nav_msgs.msg import Odometry
        from std_msgs.msg import String

        from soccer_interfaces.msg import GameState

        if self.active:
            return
        self.active = True
        self._unsubscribe_reset = self.source.on_reset(self.reset)
        for r in self._robots:
            handlers: list[tuple[str, type, Callable[[RobotId, Any], None]]] = [
                ("odom", Odometry, self.on_odom),
                ("localization/pose", PoseWithCovarianceStamped, self.on_localization),
                ("ball/estimate", PointStamped, self.on_ball),
                ("team_ball", PoseWithCovarianceStamped, self.on_team_ball),
                ("ground_truth/robot", PoseStamped, self.on_true_robot),
                # The team match's robots get their ground truth under this name.
                ("ground_truth/pose", PoseStamped, self.on_true_robot),
                ("ground_truth/ball", PoseStamped, self.on_true_ball),
            ]
            r.feeds = [self.source.subscribe(r.robot, topic, msg_type,
                                          functools.partial(handler, r.robot),
                                          rate_hz=self.rate_hz)
                       for topic, msg_type, handler in handlers]
            # Every change of state, not a rate: a kick lasts a second or two, a game
            # state may last a second.
            latched: list[tuple[str, type, Callable[[RobotId, Any], None]]] = [
                ("motion/state", String, self.on_motion),
                ("role", String, self.on_role),
                ("game_state", GameState, self.on_game_state),
            ]
            r.feeds += [self.source.subscribe(r.robot, topic, msg_type,
                                           functools.partial(handler, r.robot), qos=LATCHED)
                        for topic, msg_type, handler in latched]

    def deactivate(self) -> None:
        """Close every feed: the robots stop sending to this view."""
        self.active = False
        unsubscribe, self._unsubscribe_reset = self._unsubscribe_reset, None
        for r in self._robots:
            feeds, r.feeds = r.feeds, []
            for feed in feeds:
                feed.close()
        if unsubscribe is not None:
            unsubscribe()

    def reset(self) -> None:
        """Forget every pose, ball, state and the game (the source moved to another
        instant: what it delivers next is the new instant's)."""
        with self._lock:
            for r in self._robots:
                r.reset()
            self._game, self._game_key = None, (-1, -1)

    # -- messages (Hub thread, or tests) -------------------------------------------------

    def _get(self, robot: RobotId) -> _Robot:
        for r in self._robots:
            if r.robot == robot:
                return r
        raise KeyError(robot)

    def on_odom(self, robot: RobotId, msg: Any) -> None:
        with self._lock:
            r = self._get(robot)
            r.odom_at = r.heard(msg.header.stamp)
            r.odom = pose_2d(msg.pose.pose)
            r.anchor_if_possible()

    def on_localization(self, robot: RobotId, msg: Any) -> None:
        pose = pose_2d(msg.pose.pose)
        with self._lock:
            r = self._get(robot)
            r.localized_at = r.heard(msg.header.stamp)
            r.localized = pose

    def on_team_ball(self, robot: RobotId, msg: Any) -> None:
        p = msg.pose.pose.position
        with self._lock:
            r = self._get(robot)
            r.team_ball, r.team_ball_at = (p.x, p.y), r.heard(msg.header.stamp)

    def on_ball(self, robot: RobotId, msg: Any) -> None:
        local = ball_in_torso(msg)
        with self._lock:
            r = self._get(robot)
            stamp, delivered = r.heard(msg.header.stamp)
            if local is not None:
                r.ball, r.ball_heard, r.ball_stamp_ns = local, delivered, stamp

    # Ground truth and the game state are the world's, stamped on its clock: they never
    # move the robot's "now" (see the module docstring).

    def on_true_robot(self, robot: RobotId, msg: Any) -> None:
        pose = pose_2d(msg.pose)
        with self._lock:
            r = self._get(robot)
            r.true_pose, r.true_heard = pose, self._clock()
            r.anchor_if_possible()

    def on_true_ball(self, robot: RobotId, msg: Any) -> None:
        with self._lock:
            self._get(robot).true_ball = (msg.pose.position.x, msg.pose.position.y)

    def on_motion(self, robot: RobotId, msg: Any) -> None:
        with self._lock:
            self._get(robot).motion = msg.data

    def on_role(self, robot: RobotId, msg: Any) -> None:
        with self._lock:
            self._get(robot).role = msg.data

    def on_game_state(self, robot: RobotId, msg: Any) -> None:
        """Every robot hears the same referee: the newest broadcast (by the world's stamp,
        then its packet number) is the game's state, whichever robot passed it on."""
        key = (from_msg(msg.header.stamp), int(msg.packet_number))
        game = read_game(msg)
        with self._lock:
            self._get(robot)
            if key >= self._game_key:
                self._game, self._game_key = game, key

    # -- what the view reads -------------------------------------------------------------

    def states(self) -> list[RobotState]:
        """Every robot as it stands now, in binding order (colours stay with robots)."""
        out = []
        with self._lock:
            now = self._clock()
            for r in self._robots:
                pose_age: float | None = None
                if r.localized is not None:
                    pose: Pose2D | None = r.localized
                    source, pose_age = "localization", r.age_s(r.localized_at)
                elif r.odom is not None:
                    pose = compose(r.anchor or Pose2D(0.0, 0.0, 0.0), r.odom)
                    source, pose_age = "odom", r.age_s(r.odom_at)
                elif r.true_pose is not None:
                    pose, source = r.true_pose, "ground truth"
                    pose_age = max(0.0, now - r.true_heard)
                else:
                    pose, source = None, ""
                ball = None
                age = r.ball_age_s()
                if r.ball is not None and pose is not None and age is not None \
                        and age <= STALE_S:
                    b = compose(pose, Pose2D(r.ball[0], r.ball[1], 0.0))
                    ball = (b.x, b.y)
                team_age = r.team_ball_age_s()
                team_ball = r.team_ball if team_age is not None and team_age <= STALE_S \
                    else None
                out.append(RobotState(r.robot, r.colour, pose, source, ball, age,
                                      r.true_pose, r.true_ball, r.motion, role=r.role,
                                      team_ball=team_ball,
                                      team_ball_age_s=team_age if team_ball else None,
                                      pose_age_s=pose_age))
        return out

    def game(self) -> Game | None:
        """The newest game state any robot received (None: no referee heard)."""
        with self._lock:
            return self._game

    def team_ball(self, states: list[RobotState] | None = None) -> tuple[float, float] | None:
        """The robots' fresh ball estimates fused: mean weighted by 1 / distance (None
        while any robot tells the ball its team shares: the robots' own then count)."""
        states = self.states() if states is None else states
        if any(s.team_ball is not None for s in states):
            return None
        total = wx = wy = 0.0
        for s in states:
            if s.ball is None or s.pose is None or s.ball_age_s is None:
                continue
            if s.ball_age_s > FRESH_S:
                continue
            w = 1.0 / max(0.1, math.hypot(s.ball[0] - s.pose.x, s.ball[1] - s.pose.y))
            total += w
            wx += w * s.ball[0]
            wy += w * s.ball[1]
        return (wx / total, wy / total) if total else None
