"""The robot's team layer: team messages out and in, the shared ball, this robot's role.

:class:`TeamComm` is a component on the node handle. At ``send_hz`` (default 2 Hz) it
publishes this robot's :class:`~soccer_interfaces.msg.TeamMessage` on ``team/messages``;
rf_bridge's team link carries that topic to the teammates (a ``both`` route: the bridge
sends what this robot publishes and publishes what teammates send on the same topic, see
docs/HUMANOID_SIM.md, "Team play"). Everything that arrives there goes through
:class:`Teammates`, which keeps the newest message of each teammate and drops this robot's
own (the topic carries both), the other team's, malformed ones and ones older than what the
sender already said; a teammate not heard for ``teammate_timeout_s`` is gone. Ages are
measured on this robot's clock from arrival, so no clock offset between robots enters;
the stamp (the sender's clock) is for the logs, which team_clock aligns after the fact.

At ``update_hz`` it fuses the ball (:mod:`.shared_ball`) and decides roles
(:mod:`.roles`), and publishes:

* ``team_ball`` (geometry_msgs/PoseWithCovarianceStamped, frame ``field``): the fused ball
  in the team's field frame, the variance on the diagonal (x, y), stamped when the
  freshest belief in it was seen; nothing while no belief is fresh;
* ``role`` (std_msgs/String, latched, on every change): this robot's :class:`Role` value.

Inputs (relative names, remap as needed): ``localization/pose``
(PoseWithCovarianceStamped, the team's field frame: this robot's pose; sigma from the
covariance), ``ball/position`` (PointStamped, ``base_footprint``: the ball model's), ``fall/state``
and ``behaviour/state`` (String, latched). Until a pose arrives the robot says it is at the
centre with a sigma of :data:`UNKNOWN_POSE_SIGMA_M`, which keeps its ball out of everyone's
fusion but still lets it take part in the roles.

Figures are ROS parameters (:class:`TeamParameters`), kept current while running (so the
hysteresis can be turned down on a running robot to watch roles oscillate); ``send_hz`` and
``update_hz`` are read at start.
"""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass

from geometry_msgs.msg import PointStamped, PoseWithCovarianceStamped
from std_msgs.msg import String

from efficient_comm import bind_parameters, from_msg, latched_qos, to_msg
from efficient_comm.handle import NodeHandle
from soccer_interfaces.msg import TeamMessage

from ..errors import SimConfigError, TeamMessageError
from .fall import STANDING
from .roles import Player, Role, RoleKeeper, RoleRules, assign_roles
from .shared_ball import OWN, FusedBall, fuse, observed
from .team_message import (
    INTENTION_OF_BEHAVIOUR,
    Intention,
    OwnBall,
    PlayerState,
    decode,
    encode,
    time_to_ball,
)

LATCHED = latched_qos()
MESSAGES_TOPIC = "team/messages"
#: A robot that has no pose yet says it is this unsure (m): far beyond any field.
UNKNOWN_POSE_SIGMA_M = 100.0


@dataclass(frozen=True, slots=True)
class TeamParameters:
    """The team layer's figures (lengths m, times s, speeds m/s and rad/s)."""

    team_number: int = 1
    player_number: int = 1
    teammate_timeout_s: float = 3.0  # not heard for this long: gone (a cut link)
    max_ball_age_s: float = 10.0  # beliefs older than this are not fused
    ball_sigma_growth: float = 0.3  # m/s: how fast an unseen ball's sigma grows
    ball_sigma_m: float = 0.05  # own observation's sigma at the robot's feet ...
    ball_sigma_per_m: float = 0.1  # ... growing with the distance
    ball_gate: float = 3.0  # beliefs further from the best than this many sigmas: left out
    goalie_number: int = 0  # 0: no fixed goalie
    role_margin_s: float = 1.0  # a challenger must be this much faster to take striker
    role_position_margin_m: float = 0.5  # ... this much nearer the own goal to defend
    role_min_hold_s: float = 2.0  # this robot keeps a role at least this long
    walk_speed: float = 0.15
    turn_speed: float = 0.6
    fallen_penalty_s: float = 8.0  # time to get up, added to a fallen robot's time to ball


def _check(p: TeamParameters) -> None:
    if not 1 <= p.player_number <= 255 or not 0 <= p.team_number <= 255:
        raise SimConfigError(f"need player_number 1..255 and team_number 0..255, got "
                             f"{p.player_number}, {p.team_number}")
    if not 0 <= p.goalie_number <= 255:
        raise SimConfigError(f"need goalie_number 0..255 (0: none), got {p.goalie_number}")
    positive = ("teammate_timeout_s", "max_ball_age_s", "walk_speed", "turn_speed",
                "ball_gate")
    bad = [n for n in positive if not getattr(p, n) > 0]
    non_negative = ("ball_sigma_growth", "ball_sigma_m", "ball_sigma_per_m", "role_margin_s",
                    "role_position_margin_m", "role_min_hold_s", "fallen_penalty_s")
    bad += [n for n in non_negative if not getattr(p, n) >= 0]
    if bad:
        raise SimConfigError(f"need {', '.join(bad)} > 0 (or >= 0 for margins, sigmas, "
                             f"times); got {[getattr(p, n) for n in bad]}")


@dataclass(frozen=True, slots=True)
class Teammate:
    """A teammate's newest message and when it arrived (this robot's clock, ns)."""

    state: PlayerState
    arrived_ns: int


class Teammates:
    """The teammates heard from: the newest message of each, until it is too old.

    ``drops`` counts what was not taken, by reason: ``own`` (this robot's message coming
    back on the shared topic), ``other_team``, ``malformed``, ``out_of_order`` (older than
    the sender's newest) and ``timed_out`` (teammates aged out).
    """

    def __init__(self, *, team: int, player: int, timeout_s: float) -> None:
        self.team, self.player = team, player
        self.timeout_ns = round(timeout_s * 1e9)
        self._by_player: dict[int, Teammate] = {}
        self.received = 0
        self.drops: Counter[str] = Counter()

    def offer(self, msg: TeamMessage, now_ns: int) -> PlayerState | None:
        """Take ``msg`` if it is a teammate's news; returns what was taken (None: dropped,
        counted). A malformed one is counted and raises TeamMessageError, for the caller to
        say why."""
        if msg.team_number != self.team:
            self.drops["other_team"] += 1
            return None
        if msg.player_number == self.player:
            self.drops["own"] += 1
            return None
        try:
            state = decode(msg)
        except TeamMessageError:
            self.drops["malformed"] += 1
            raise
        known = self._by_player.get(state.player)
        if known is not None and state.stamp_ns <= known.state.stamp_ns:
            self.drops["out_of_order"] += 1
            return None
        self._by_player[state.player] = Teammate(state, now_ns)
        self.received += 1
        return state

    def fresh(self, now_ns: int) -> list[Teammate]:
        """The teammates heard within the timeout, by player number; forgets the others."""
        for number, mate in list(self._by_player.items()):
            if now_ns - mate.arrived_ns > self.timeout_ns:
                del self._by_player[number]
                self.drops["timed_out"] += 1
        return [self._by_player[n] for n in sorted(self._by_player)]


class TeamComm:
    """The team layer component (see the module docstring for topics and parameters)."""

    def __init__(self, node: NodeHandle) -> None:
        self.node = node
        send_hz = node.declare_parameter("send_hz", 2.0, range=(0.1, 50.0))
        update_hz = node.declare_parameter("update_hz", 10.0, range=(0.5, 100.0))
        self.parameters = bind_parameters(node, TeamParameters(), check=_check,
                                          on_change=self._on_parameters)
        p = self.p = self.parameters.value
        self.teammates = Teammates(team=p.team_number, player=p.player_number,
                                   timeout_s=p.teammate_timeout_s)
        self.keeper = RoleKeeper(min_hold_s=p.role_min_hold_s)
        #: This robot's pose (x, y, theta) and its sigma (m); None until one arrives.
        self.pose: tuple[float, float, float] | None = None
        self.pose_sigma = UNKNOWN_POSE_SIGMA_M
        #: The ball as this robot last saw it: on the field, its sigma, when (ns).
        self._ball_seen: tuple[float, float, float, int] | None = None
        self.fallen = False
        self.intention = Intention.NONE
        self.ball: FusedBall | None = None
        self.roles: dict[int, Role] = {}
        self.sent = 0
        self._warned: set[int] = set()
        self.msg_pub = node.create_publisher(TeamMessage, MESSAGES_TOPIC, qos=10)
        self.ball_pub = node.create_publisher(PoseWithCovarianceStamped, "team_ball", qos=10)
        self.role_pub = node.create_publisher(String, "role", qos=LATCHED)
        node.create_subscription(TeamMessage, MESSAGES_TOPIC, self._on_message, qos=10)
        node.create_subscription(PoseWithCovarianceStamped, "localization/pose",
                                 self._on_pose, qos=10)
        node.create_subscription(PointStamped, "ball/position", self._on_ball, qos=10)
        node.create_subscription(String, "fall/state", self._on_fall, qos=LATCHED)
        node.create_subscription(String, "behaviour/state", self._on_behaviour, qos=LATCHED)
        node.create_timer(1.0 / update_hz, self.update)
        node.create_timer(1.0 / send_hz, self.send)

    def _on_parameters(self, p: TeamParameters) -> None:
        self.p = p
        self.teammates.team, self.teammates.player = p.team_number, p.player_number
        self.teammates.timeout_ns = round(p.teammate_timeout_s * 1e9)
        self.keeper.min_hold_ns = round(p.role_min_hold_s * 1e9)

    # -- inputs ---------------------------------------------------------------------------

    def _on_message(self, msg: TeamMessage) -> None:
        try:
            self.teammates.offer(msg, self.node.clock.now_ns())
        except TeamMessageError as exc:
            # Once per sender: one that sends garbage sends it at its rate; the rest are
            # counted (``teammates.drops["malformed"]``).
            if msg.player_number not in self._warned:
                self._warned.add(msg.player_number)
                self.node.logger.warning(f"team message dropped: {exc} (further ones from "
                                         "this player are only counted)")

    def _on_pose(self, msg: PoseWithCovarianceStamped) -> None:
        p, q = msg.pose.pose.position, msg.pose.pose.orientation
        theta = math.atan2(2 * (q.w * q.z + q.x * q.y), 1 - 2 * (q.y * q.y + q.z * q.z))
        cov = msg.pose.covariance
        sigma = math.sqrt(max(cov[0], cov[7], 0.0))
        if not all(math.isfinite(v) for v in (p.x, p.y, theta, sigma)):
            self.node.logger.warning("localization/pose with a non-finite value ignored")
            return
        self.pose, self.pose_sigma = (p.x, p.y, theta), sigma

    def _on_ball(self, msg: PointStamped) -> None:
        if self.pose is None:
            return  # a ball relative to a robot that does not know where it is
        x, y, theta = self.pose
        bx, by = msg.point.x, msg.point.y
        if not (math.isfinite(bx) and math.isfinite(by)):
            return
        c, s = math.cos(theta), math.sin(theta)
        sigma = self.p.ball_sigma_m + self.p.ball_sigma_per_m * math.hypot(bx, by)
        self._ball_seen = (x + c * bx - s * by, y + s * bx + c * by, sigma,
                           from_msg(msg.header.stamp))

    def _on_fall(self, msg: String) -> None:
        self.fallen = msg.data != STANDING

    def _on_behaviour(self, msg: String) -> None:
        self.intention = INTENTION_OF_BEHAVIOUR.get(msg.data, Intention.NONE)

    # -- what this robot knows ------------------------------------------------------------

    def own_ball(self, now_ns: int) -> OwnBall | None:
        """This robot's own sighting (not fused), if it is recent enough to tell."""
        if self._ball_seen is None:
            return None
        x, y, sigma, seen = self._ball_seen
        age = max(0.0, (now_ns - seen) / 1e9)
        return OwnBall(x, y, sigma, age) if age <= self.p.max_ball_age_s else None

    def time_to_ball(self) -> float:
        """This robot's time to the fused ball (inf without a pose or a ball)."""
        if self.pose is None or self.ball is None:
            return math.inf
        return time_to_ball(*self.pose, (self.ball.x, self.ball.y),
                            walk_speed=self.p.walk_speed, turn_speed=self.p.turn_speed,
                            fallen=self.fallen, fallen_penalty_s=self.p.fallen_penalty_s)

    def state(self, now_ns: int) -> PlayerState:
        """This robot as its next team message will describe it."""
        x, y, theta = self.pose if self.pose is not None else (0.0, 0.0, 0.0)
        return PlayerState(
            team=self.p.team_number, player=self.p.player_number, x=x, y=y, theta=theta,
            pose_sigma=self.pose_sigma, ball=self.own_ball(now_ns), role=self.keeper.role,
            intention=self.intention, time_to_ball_s=self.time_to_ball(),
            fallen=self.fallen, stamp_ns=now_ns,
        )

    # -- timers ---------------------------------------------------------------------------

    def update(self) -> None:
        """Fuse the ball, decide the roles, publish ``team_ball`` and ``role``."""
        now = self.node.clock.now_ns()
        p = self.p
        mates = self.teammates.fresh(now)
        # A teammate's ball has aged since its message arrived.
        beliefs = [b for m in mates
                   if (b := m.state.ball_belief(aged_s=(now - m.arrived_ns) / 1e9)) is not None]
        own = self.own_ball(now)
        if own is not None:
            beliefs.append(observed(own.x, own.y, ball_sigma=own.sigma,
                                    pose_sigma=self.pose_sigma, age_s=own.age_s, source=OWN))
        self.ball = fuse(beliefs, max_age_s=p.max_ball_age_s,
                         growth_m_per_s=p.ball_sigma_growth, gate=p.ball_gate)
        if self.ball is not None:
            self._publish_ball(now, self.ball)
        me = self.state(now)
        players = [Player(me.player, me.x, me.y, me.time_to_ball_s, me.role)]
        players += [Player(m.state.player, m.state.x, m.state.y, m.state.time_to_ball_s,
                           m.state.role) for m in mates]
        rules = RoleRules(goalie_number=p.goalie_number, margin_s=p.role_margin_s,
                          position_margin_m=p.role_position_margin_m)
        self.roles = assign_roles(players, rules)
        before = self.keeper.role
        role = self.keeper.update(self.roles[me.player], now)
        if role != before:
            self.role_pub.publish(String(data=role.value))

    def _publish_ball(self, now_ns: int, ball: FusedBall) -> None:
        msg = PoseWithCovarianceStamped()
        msg.header.stamp = to_msg(now_ns - round(ball.age_s * 1e9))
        msg.header.frame_id = "field"
        msg.pose.pose.position.x, msg.pose.pose.position.y = ball.x, ball.y
        msg.pose.pose.orientation.w = 1.0
        variance = ball.sigma * ball.sigma
        cov = [0.0] * 36
        cov[0] = cov[7] = variance
        msg.pose.covariance = cov
        self.ball_pub.publish(msg)

    def send(self) -> None:
        """Publish this robot's team message."""
        self.msg_pub.publish(encode(self.state(self.node.clock.now_ns())))
        self.sent += 1
