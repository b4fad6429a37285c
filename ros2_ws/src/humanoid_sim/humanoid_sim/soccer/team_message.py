"""The team message: what a robot tells its teammates, written and read in one place.

``soccer_interfaces/TeamMessage`` is the wire format (ROS 2 CDR, 64 bytes serialised, 82
on the team link with rf_bridge's attachment and a 5-character robot id): :func:`encode`
writes a :class:`PlayerState` into one and :func:`decode` reads one back, refusing what
no robot could have sent (a non-finite pose, a negative sigma) with
:class:`~humanoid_sim.errors.TeamMessageError`, so nothing downstream has to check again.
The numbers in a message are float32: positions keep about a millimetre on a 9 m field,
far below any robot's sigma. rf_bridge zlib-compresses a payload when that makes it
smaller: a message without a ball goes out in about 74 bytes.

Intentions say what the sender is doing, derived from its behaviour's state
(:data:`INTENTION_OF_BEHAVIOUR`), so teammates can tell "going for the ball" from "lying
on the ground" without its role.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass

from efficient_comm import from_msg, to_msg
from soccer_interfaces.msg import TeamMessage

from ..errors import TeamMessageError
from .roles import Role
from .shared_ball import BallBelief, observed


class Intention(enum.IntEnum):
    """What the sender is doing (``TeamMessage.INTENTION_*``)."""

    NONE = 0
    GO_TO_BALL = 1
    KICK = 2
    POSITION = 3
    GET_UP = 4


#: ``behaviour/state`` (the striker's) -> intention; other states: NONE.
INTENTION_OF_BEHAVIOUR = {
    "approach": Intention.GO_TO_BALL,
    "stop": Intention.KICK,
    "kick": Intention.KICK,
    "fallen": Intention.GET_UP,
}


@dataclass(frozen=True, slots=True)
class OwnBall:
    """The sender's own sighting of the ball, on the field: ``sigma`` is the observation's
    alone (its pose's sigma travels beside it), ``age_s`` since it was last seen."""

    x: float
    y: float
    sigma: float
    age_s: float


@dataclass(frozen=True, slots=True)
class PlayerState:
    """One player as its team message describes it (pose in the team's field frame)."""

    team: int
    player: int
    x: float
    y: float
    theta: float
    pose_sigma: float
    ball: OwnBall | None
    role: Role
    intention: Intention
    #: Seconds to reach the ball and kick; inf when the player does not know the ball.
    time_to_ball_s: float
    fallen: bool
    #: The sender's clock when it sent the message (ns).
    stamp_ns: int = 0

    def ball_belief(self, *, aged_s: float = 0.0) -> BallBelief | None:
        """The player's ball as a belief for fusion: its observation's sigma and its
        pose's, combined; ``aged_s`` older than the message said (the time since it
        arrived)."""
        if self.ball is None:
            return None
        return observed(self.ball.x, self.ball.y, ball_sigma=self.ball.sigma,
                        pose_sigma=self.pose_sigma, age_s=self.ball.age_s + aged_s,
                        source=self.player)


def encode(state: PlayerState) -> TeamMessage:
    """The message for ``state`` (stamped with ``state.stamp_ns``)."""
    msg = TeamMessage()
    msg.stamp = to_msg(state.stamp_ns)
    msg.team_number = state.team
    msg.player_number = state.player
    msg.x, msg.y, msg.theta = state.x, state.y, state.theta
    msg.pose_sigma = state.pose_sigma
    if state.ball is not None:
        msg.ball_known = True
        msg.ball_x, msg.ball_y = state.ball.x, state.ball.y
        msg.ball_sigma, msg.ball_age_s = state.ball.sigma, state.ball.age_s
    else:
        msg.ball_known = False
        msg.ball_age_s = math.nan
    msg.role = state.role.wire
    msg.intention = int(state.intention)
    msg.time_to_ball_s = state.time_to_ball_s
    msg.fallen = state.fallen
    return msg


def _finite(msg: TeamMessage, *names: str) -> None:
    bad = [n for n in names if not math.isfinite(getattr(msg, n))]
    if bad:
        raise TeamMessageError(f"team message from player {msg.player_number}: "
                               f"{', '.join(bad)} not finite")


def decode(msg: TeamMessage) -> PlayerState:
    """The player a message describes; raises TeamMessageError for one no robot could
    have sent (non-finite pose, negative sigma or age, player number 0)."""
    if msg.player_number == 0:
        raise TeamMessageError("team message with player number 0")
    _finite(msg, "x", "y", "theta", "pose_sigma")
    if msg.pose_sigma < 0:
        raise TeamMessageError(f"team message from player {msg.player_number}: "
                               f"negative pose_sigma {msg.pose_sigma}")
    ball = None
    if msg.ball_known:
        _finite(msg, "ball_x", "ball_y", "ball_sigma", "ball_age_s")
        if msg.ball_sigma < 0 or msg.ball_age_s < 0:
            raise TeamMessageError(f"team message from player {msg.player_number}: "
                                   "negative ball_sigma or ball_age_s")
        ball = OwnBall(msg.ball_x, msg.ball_y, msg.ball_sigma, msg.ball_age_s)
    ttb = float(msg.time_to_ball_s)
    try:
        intention = Intention(msg.intention)
    except ValueError:
        intention = Intention.NONE
    return PlayerState(
        team=msg.team_number, player=msg.player_number, x=msg.x, y=msg.y, theta=msg.theta,
        pose_sigma=msg.pose_sigma, ball=ball, role=Role.from_wire(msg.role),
        intention=intention,
        time_to_ball_s=ttb if not math.isnan(ttb) and ttb >= 0 else math.inf,
        fallen=bool(msg.fallen), stamp_ns=from_msg(msg.stamp),
    )


def time_to_ball(x: float, y: float, theta: float, ball: tuple[float, float] | None, *,
                 walk_speed: float, turn_speed: float, fallen: bool,
                 fallen_penalty_s: float) -> float:
    """Seconds for a robot at (x, y) facing ``theta`` to reach ``ball``: walking the
    distance, turning to face it, and getting up first if it lies on the ground; inf
    without a ball."""
    if ball is None:
        return math.inf
    dx, dy = ball[0] - x, ball[1] - y
    turn = abs((math.atan2(dy, dx) - theta + math.pi) % (2 * math.pi) - math.pi)
    return (math.hypot(dx, dy) / walk_speed + turn / turn_speed
            + (fallen_penalty_s if fallen else 0.0))
