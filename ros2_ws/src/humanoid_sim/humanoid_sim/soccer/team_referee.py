"""The team game's referee: game states, kick-offs, goals for either team, set plays and
robots placed for kick-off, judged from ground truth and broadcast as the GameController's
data.

It is part of the world (simulation side): it reads ``ground_truth/ball`` and
``ground_truth/<robot>/pose`` (PoseStamped, field frame) for each robot of its ``robots``
parameter (``blue1``, ``red2``: :func:`.laws.parse_robot`), puts the ball back through
``place_ball`` (Point) and robots through ``place_robot`` (PoseStamped, ``frame_id`` the
robot's name, orientation its heading), and broadcasts ``game_state``
(soccer_interfaces/GameState, latched) every ``1 / rate_hz`` s and on every change, its
``packet_number`` counting.

The game, as the Humanoid League's GameController runs it (the laws are in :mod:`.laws`):

* ``initial`` for ``initial_s``; then ``ready`` (``ready_s``, 45 s as in the
  GameController): the robots walk to their kick-off positions. Ready ends early once every
  robot has stood still (within :data:`STILL_M`) in a legal position for ``settle_s`` (0:
  never early), as a referee sets the game when everyone is in place. Robots still in an
  illegal position then (outside the field, in the opponent half, or in the centre circle
  without the kick-off) are placed on their kick-off spots (manual placement), and the ball
  on the centre mark;
* ``set`` for ``set_s`` (the whistle), then ``playing``. The kick-off's ball is free once
  it moved ``ball_moved_m`` or ``kickoff_free_s`` (10 s) passed; until then
  ``secondary_seconds_remaining`` counts down to it;
* a goal for either team (blue attacks +x in the first half, red in the second) raises its
  score and gives the next kick-off to the team that conceded: back to ``ready``;
* a ball out restarts with a set play for the opponents of the team that last touched it
  (the team of the robot nearest the ball within ``touch_m``; not known: the defending
  side): a throw-in over a touch line, a goal kick or a corner kick over a goal line.
  ``secondary_state`` says which, ``secondary_state_info`` ``[team number, 0, 0, 0]``,
  ``kicking_team`` its team; after ``restart_s`` the ball is placed on the set play's
  spot, and the set play lasts until the ball moved or ``free_kick_s`` passed;
* ``seconds_remaining`` counts the half's ``half_s`` down in the world's time while ready,
  set and playing (the laws do not stop the clock for ready and set); at zero the half is
  ``finished``. After the first of ``halves`` (2) and ``half_time_s``, the second half
  starts in ``initial`` with ends changed and the kick-off to the team that did not have
  the first; after the last it stays ``finished``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import partial

from geometry_msgs.msg import Point, PoseStamped

from efficient_comm import latched_qos, to_msg
from efficient_comm.handle import NodeHandle
from soccer_interfaces.msg import GameState, PlayerInfo, TeamInfo

from ..errors import SimConfigError
from .laws import (
    TEAMS,
    Line,
    Player,
    attack_sign,
    corner_spot,
    goal_kick_spot,
    judge_ball,
    kickoff_pose,
    legal_at_kickoff,
    other,
    parse_robot,
    throw_in_spot,
)

#: The referee's decision rate (Hz): state changes happen on these ticks.
TICK_HZ = 10.0
#: A robot that stays within this of where it stood (m) stands still.
STILL_M = 0.05
#: Names of the game states, for logs and reports.
STATE_NAMES = {GameState.STATE_INITIAL: "initial", GameState.STATE_READY: "ready",
               GameState.STATE_SET: "set", GameState.STATE_PLAYING: "playing",
               GameState.STATE_FINISHED: "finished"}
SET_PLAY_NAMES = {GameState.STATE2_NORMAL: "normal", GameState.STATE2_THROW_IN: "throw-in",
                  GameState.STATE2_GOAL_KICK: "goal kick",
                  GameState.STATE2_CORNER_KICK: "corner kick"}
RUNNING = (GameState.STATE_READY, GameState.STATE_SET, GameState.STATE_PLAYING)

#: The referee's parameters and their defaults (times in s, lengths in m).
PARAMETERS: dict[str, float | int | str | list[str]] = {
    "robots": ["blue1", "red1"],
    "half_s": 600.0,  # Law 7: 10 minutes a half
    "halves": 2,
    "initial_s": 1.0,
    "ready_s": 45.0,  # the GameController's ready time
    "settle_s": 3.0,  # ready ends early when everyone stood legally this long (0: never)
    "set_s": 2.0,
    "half_time_s": 10.0,
    "kickoff_free_s": 10.0,  # Law 8: the ball is in play after 10 s anyway
    "free_kick_s": 30.0,
    "restart_s": 1.0,  # from the ball going out to its placement
    "ball_moved_m": 0.1,  # "kicked and clearly moves"
    "touch_m": 0.3,
    "rate_hz": 2.0,  # the GameController sends two packets a second
    "first_kickoff": "blue",
    "blue_team_number": 1,
    "red_team_number": 2,
}


@dataclass(slots=True)
class _Tracked:
    """A robot's ground truth: where it is, and since when it has stood still."""

    x: float
    y: float
    anchor: tuple[float, float]
    still_since_ns: int


@dataclass(frozen=True, slots=True)
class SetPlay:
    """A restart awarded after a ball out: when (ns since the referee started), to whom,
    which (``GameState.STATE2_*``) and where the ball goes."""

    at_ns: int
    team: str
    kind: int
    spot: tuple[float, float]


class TeamReferee:
    """The team referee component (see the module's docstring for topics and the game)."""

    def __init__(self, node: NodeHandle) -> None:
        self.node = node
        p = {name: node.declare_parameter(name, default) for name, default in PARAMETERS.items()}
        robots = p["robots"]
        if not isinstance(robots, list) or not robots:
            raise SimConfigError(f"robots is a list of names like blue1, red2, got {robots!r}")
        self.players = [parse_robot(name) for name in robots]
        if len({player.name for player in self.players}) != len(self.players):
            raise SimConfigError(f"robots names a robot twice: {robots}")
        times = {name: float(value) for name, value in p.items()
                 if name.endswith(("_s", "_m", "_hz")) and isinstance(value, (int, float))}
        for name, value in times.items():
            if not math.isfinite(value) or value < 0 or (
                    name in ("half_s", "rate_hz", "ball_moved_m") and value == 0):
                raise SimConfigError(f"team referee parameter {name} = {value} is out of range")
        if p["halves"] not in (1, 2) or p["first_kickoff"] not in TEAMS:
            raise SimConfigError(f"need halves 1 or 2 and first_kickoff blue or red, got "
                                 f"{p['halves']}, {p['first_kickoff']!r}")
        numbers = {t: n for t in TEAMS if isinstance(n := p[f"{t}_team_number"], int)}
        if len(numbers) != 2 or not all(0 <= n <= 255 for n in numbers.values()) or (
                numbers["blue"] == numbers["red"]):
            raise SimConfigError(f"team numbers are two different integers 0..255, got "
                                 f"{p['blue_team_number']}, {p['red_team_number']}")
        self.team_numbers = numbers
        self.ns = {name: round(value * 1e9) for name, value in times.items() if name.endswith("_s")}
        self.p = times
        self.halves = 2 if p["halves"] == 2 else 1
        self.players_per_team = max(player.number for player in self.players)

        self._start_ns = now = node.clock.now_ns()
        self.state = GameState.STATE_INITIAL
        self.first_half = True
        #: The team that took (or takes) the half's first kick-off, and the kick-off's team.
        self._half_kickoff = self.kicking = str(p["first_kickoff"])
        self.score = dict.fromkeys(TEAMS, 0)
        #: Goals as (ns since the referee started, scoring team); set plays awarded; robots
        #: placed at the end of ready (ns, name).
        self.goals: list[tuple[int, str]] = []
        self.set_plays: list[SetPlay] = []
        self.placements: list[tuple[int, str]] = []
        self.secondary = GameState.STATE2_NORMAL
        self._set_play: SetPlay | None = None
        self._secondary_until_ns: int | None = None  # the set play's or kick-off's end
        self._deadline_ns = now + self.ns["initial_s"]
        self._remaining_ns = self.ns["half_s"]
        self._clock_from_ns: int | None = None  # the half's clock runs since then
        self._ball: tuple[float, float, float] | None = None
        self._ball_anchor = (0.0, 0.0)  # where the ball lay when it was last put in play
        self._place_ball: tuple[int, tuple[float, float]] | None = None
        self._robots: dict[str, _Tracked] = {}
        self._last_touch: str | None = None
        self._packets = 0
        self._sent_ns: int | None = None
        self._changed = True  # something to broadcast at once

        self.state_pub = node.create_publisher(GameState, "game_state", qos=latched_qos())
        self.ball_pub = node.create_publisher(Point, "place_ball", qos=10)
        self.robot_pub = node.create_publisher(PoseStamped, "place_robot", qos=10)
        node.create_subscription(PoseStamped, "ground_truth/ball", self._on_ball, qos=10)
        for player in self.players:
            node.create_subscription(PoseStamped, f"ground_truth/{player.name}/pose",
                                     partial(self._on_robot, player.name), qos=10)
        node.create_timer(1.0 / TICK_HZ, self._tick)
        self._broadcast(now)

    # -- what the referee sees ------------------------------------------------------------

    def _on_robot(self, name: str, pose: PoseStamped) -> None:
        x, y = pose.pose.position.x, pose.pose.position.y
        if not (math.isfinite(x) and math.isfinite(y)):
            return
        now = self.node.clock.now_ns()
        tracked = self._robots.get(name)
        if tracked is None:
            self._robots[name] = _Tracked(x, y, (x, y), now)
            return
        tracked.x, tracked.y = x, y
        if math.dist((x, y), tracked.anchor) > STILL_M:
            tracked.anchor, tracked.still_since_ns = (x, y), now

    def _on_ball(self, pose: PoseStamped) -> None:
        position = pose.pose.position
        ball = (position.x, position.y, position.z)
        if not all(map(math.isfinite, ball)):
            return
        self._ball = ball
        near = [(math.dist(ball[:2], (r.x, r.y)), name) for name, r in self._robots.items()]
        if near and min(near)[0] < self.p["touch_m"]:
            self._last_touch = parse_robot(min(near)[1]).team
        if self.state == GameState.STATE_PLAYING and self._place_ball is None:
            now = self.node.clock.now_ns()
            self._judge(now, *ball)
            if self._changed:  # a goal or a set play is told at once
                self._broadcast(now)

    def _judge(self, now: int, x: float, y: float, z: float) -> None:
        crossing = judge_ball(x, y, z)
        if crossing is None:
            return
        if crossing.line is Line.GOAL:
            scorer = next(t for t in TEAMS
                          if attack_sign(t, first_half=self.first_half) == crossing.x_side)
            self.score[scorer] += 1
            self.goals.append((now - self._start_ns, scorer))
            self.node.logger.info(f"GOAL {scorer} ({self.score['blue']}:{self.score['red']})")
            self._ready(now, kicking=other(scorer), ball_at_ns=now + self.ns["restart_s"])
            return
        # The team defending the goal line the ball crossed, or the half it left by.
        side = crossing.x_side if crossing.line is Line.GOAL_LINE else math.copysign(1.0, x)
        defender = next(t for t in TEAMS if attack_sign(t, first_half=self.first_half) != side)
        last = self._last_touch or other(defender)
        if crossing.line is Line.TOUCH_LINE:
            play = SetPlay(now - self._start_ns, other(last), GameState.STATE2_THROW_IN,
                           throw_in_spot(x, crossing.y_side))
        elif last == defender:
            play = SetPlay(now - self._start_ns, other(defender), GameState.STATE2_CORNER_KICK,
                           corner_spot(crossing.x_side, crossing.y_side))
        else:
            play = SetPlay(now - self._start_ns, defender, GameState.STATE2_GOAL_KICK,
                           goal_kick_spot(crossing.x_side, crossing.y_side))
        self.set_plays.append(play)
        self.node.logger.info(f"ball out over the {crossing.line.value}: "
                              f"{SET_PLAY_NAMES[play.kind]} {play.team}")
        self._set_play, self.secondary, self.kicking = play, play.kind, play.team
        self._place_ball = (now + self.ns["restart_s"], play.spot)
        self._secondary_until_ns = now + self.ns["restart_s"] + self.ns["free_kick_s"]
        self._changed = True

    # -- the game -------------------------------------------------------------------------

    def seconds_remaining(self, now: int | None = None) -> float:
        """The half's time left (s), counting while ready, set and playing."""
        now = self.node.clock.now_ns() if now is None else now
        running = 0 if self._clock_from_ns is None else now - self._clock_from_ns
        return (self._remaining_ns - running) / 1e9

    def _enter(self, now: int, state: int) -> None:
        if state in RUNNING and self._clock_from_ns is None:
            self._clock_from_ns = now
        elif state not in RUNNING and self._clock_from_ns is not None:
            self._remaining_ns -= now - self._clock_from_ns
            self._clock_from_ns = None
        self.state = state
        self._changed = True
        half = "first" if self.first_half else "second"
        self.node.logger.info(f"game state {STATE_NAMES[state]} ({half} half, kick-off "
                              f"{self.kicking}, {self.score['blue']}:{self.score['red']})")

    def _ready(self, now: int, *, kicking: str, ball_at_ns: int) -> None:
        """A kick-off comes: to ``ready``, the ball on the centre mark at ``ball_at_ns``."""
        self.kicking = kicking
        self.secondary, self._set_play, self._secondary_until_ns = (
            GameState.STATE2_NORMAL, None, None)
        self._place_ball = (ball_at_ns, (0.0, 0.0))
        self._deadline_ns = now + self.ns["ready_s"]
        for tracked in self._robots.values():  # standing still counts from now on
            tracked.anchor, tracked.still_since_ns = (tracked.x, tracked.y), now
        self._enter(now, GameState.STATE_READY)

    def _legal(self, name: str) -> bool:
        player, tracked = parse_robot(name), self._robots.get(name)
        return tracked is not None and legal_at_kickoff(
            player.team, tracked.x, tracked.y, first_half=self.first_half,
            kicking=player.team == self.kicking)

    def _everyone_settled(self, now: int) -> bool:
        settle = self.ns["settle_s"]
        return settle > 0 and all(
            self._legal(p.name)
            and now - self._robots[p.name].still_since_ns >= settle for p in self.players)

    def _place_for_kickoff(self, now: int) -> None:
        """Manual placement: every robot not in a legal position to its kick-off spot, the
        ball on the centre mark."""
        for player in self.players:
            if self._legal(player.name):
                continue
            self.placements.append((now - self._start_ns, player.name))
            self.robot_pub.publish(self._placement(now, player))
            self.node.logger.info(f"{player.name} placed for the kick-off")
        self._place_ball = None
        self._ball_anchor = (0.0, 0.0)
        self.ball_pub.publish(Point())

    def _placement(self, now: int, player: Player) -> PoseStamped:
        x, y, heading = kickoff_pose(player, first_half=self.first_half,
                                     kicking=player.team == self.kicking)
        pose = PoseStamped()
        pose.header.stamp = to_msg(now)
        pose.header.frame_id = player.name
        pose.pose.position.x, pose.pose.position.y = x, y
        pose.pose.orientation.z, pose.pose.orientation.w = (math.sin(heading / 2),
                                                            math.cos(heading / 2))
        return pose

    def _ball_moved(self) -> bool:
        return self._ball is not None and (
            math.dist(self._ball[:2], self._ball_anchor) > self.p["ball_moved_m"])

    def _tick(self) -> None:
        now = self.node.clock.now_ns()
        if self._place_ball is not None and now >= self._place_ball[0]:
            spot = self._place_ball[1]
            self._place_ball = None
            self._ball_anchor = spot
            self._ball = (spot[0], spot[1], 0.0)  # until ground truth says otherwise
            self.ball_pub.publish(Point(x=spot[0], y=spot[1]))
        state = self.state
        if state == GameState.STATE_INITIAL and now >= self._deadline_ns:
            self._ready(now, kicking=self.kicking, ball_at_ns=now)
        elif state == GameState.STATE_READY and (
                now >= self._deadline_ns or self._everyone_settled(now)):
            self._place_for_kickoff(now)
            self._deadline_ns = now + self.ns["set_s"]
            self._enter(now, GameState.STATE_SET)
        elif state == GameState.STATE_SET and now >= self._deadline_ns:
            self._secondary_until_ns = now + self.ns["kickoff_free_s"]  # the ball is free then
            self._enter(now, GameState.STATE_PLAYING)
        elif state == GameState.STATE_PLAYING:
            self._playing(now)
        elif state == GameState.STATE_FINISHED and self.first_half and self.halves == 2 and (
                now >= self._deadline_ns):
            self.first_half = False
            self._remaining_ns = self.ns["half_s"]
            self._deadline_ns = now + self.ns["initial_s"]
            self.kicking = self._half_kickoff = other(self._half_kickoff)
            self._enter(now, GameState.STATE_INITIAL)
        if self.state in RUNNING and self.seconds_remaining(now) <= 0:
            self._deadline_ns = now + self.ns["half_time_s"]
            self.secondary, self._set_play, self._secondary_until_ns = (
                GameState.STATE2_NORMAL, None, None)
            self._enter(now, GameState.STATE_FINISHED)
        if self._changed or self._sent_ns is None or (
                now - self._sent_ns >= round(1e9 / self.p["rate_hz"])):
            self._broadcast(now)

    def _playing(self, now: int) -> None:
        """The kick-off's ball or a set play's end: moved, or its time is over."""
        if self._secondary_until_ns is None or self._place_ball is not None:
            return
        if now >= self._secondary_until_ns or self._ball_moved():
            if self.secondary != GameState.STATE2_NORMAL:
                self.node.logger.info(f"{SET_PLAY_NAMES[self.secondary]} over")
            self.secondary, self._set_play, self._secondary_until_ns = (
                GameState.STATE2_NORMAL, None, None)
            self._changed = True

    # -- the broadcast --------------------------------------------------------------------

    def game_state(self, now: int) -> GameState:
        """The GameController's packet for this moment (a new message each time: receivers
        keep it by reference)."""
        msg = GameState()
        msg.header.stamp = to_msg(now)
        msg.packet_number = self._packets % 2**32
        msg.players_per_team = self.players_per_team
        msg.game_type = GameState.GAME_ROUND_ROBIN
        msg.game_state = self.state
        msg.first_half = self.first_half
        msg.kicking_team = self.team_numbers[self.kicking]
        msg.secondary_state = self.secondary
        if self._set_play is not None:
            msg.secondary_state_info = [self.team_numbers[self._set_play.team], 0, 0, 0]
        msg.seconds_remaining = _int16(self.seconds_remaining(now))
        until = None
        if self.state in (GameState.STATE_INITIAL, GameState.STATE_READY,
                          GameState.STATE_FINISHED):
            until = self._deadline_ns
        elif self.state == GameState.STATE_PLAYING:
            until = self._secondary_until_ns
        if until is not None and (self.state != GameState.STATE_FINISHED or (
                self.first_half and self.halves == 2)):
            msg.secondary_seconds_remaining = _int16((until - now) / 1e9)
        msg.teams = [
            TeamInfo(team_number=self.team_numbers[team],
                     team_colour=TeamInfo.COLOUR_BLUE if team == "blue" else TeamInfo.COLOUR_RED,
                     score=self.score[team],
                     players=[PlayerInfo() for _ in range(self.players_per_team)])
            for team in TEAMS]
        return msg

    def _broadcast(self, now: int) -> None:
        self.state_pub.publish(self.game_state(now))
        self._packets += 1
        self._sent_ns = now
        self._changed = False


def _int16(seconds: float) -> int:
    """Whole seconds as the GameController counts them (rounded up, never below zero)."""
    return max(0, min(32767, math.ceil(seconds - 1e-9)))
