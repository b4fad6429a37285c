"""Game control: what the referee's ``game_state`` allows the robot to do now (robot side).

The body's behaviour consults it before it plays (:class:`~.striker.Striker` does, each
decision); it only reads the broadcast (soccer_interfaces/GameState, latched, as the team
referee :mod:`.team_referee` or a real GameController bridge sends it) and the robot's own
name (the behaviour's ``robot`` parameter, ``blue1`` .. ``red3``: team and player number).
The orders, by game state (Humanoid League laws, robot states; :mod:`.laws`):

* no ``game_state`` received yet: :data:`PLAY` (the one-robot demo has no referee);
* ``initial``, ``set``, ``finished``, or the robot itself penalised: :data:`STAND` (no
  walking; the head may still look);
* ``ready``: :data:`POSITION` at its kick-off spot (:func:`.laws.kickoff_pose`: own half, by
  team and player number, the kicking team's player 1 just behind the ball);
* ``playing``: :data:`PLAY`; but while the other team's kick-off has not freed the ball
  (``secondary_seconds_remaining`` above zero in the normal secondary state, and at most
  ``kickoff_free_s`` after playing began, by the robot's own clock), the robot keeps out of
  the centre circle: it stands outside it, or walks back to its kick-off spot if inside.

Without a ``robot`` name the robot cannot know its team: it stands in ``ready`` too, and
plays in ``playing``. A robot whose pose estimate is illegal when ``set`` begins was placed
by the referee (which places exactly those) on its kick-off spot: :meth:`GameControl.placed`
says so during ``set``, for the behaviour to take that spot as its pose.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

from efficient_comm import latched_qos
from efficient_comm.handle import NodeHandle
from soccer_field import KIDSIZE
from soccer_interfaces.msg import GameState, PlayerInfo, TeamInfo

from .laws import (
    CENTRE_CIRCLE_RADIUS,
    Player,
    attack_sign,
    kickoff_pose,
    legal_at_kickoff,
    parse_robot,
)

PLAY, STAND, POSITION = "play", "stand", "position"
#: How far outside the centre circle a robot waiting for the other team's kick-off keeps (m).
CIRCLE_MARGIN_M = 0.15
#: After this long in ``playing`` the kick-off's ball is free whatever the referee says (s).
KICKOFF_FREE_S = 10.0


@dataclass(frozen=True, slots=True)
class Order:
    """What the robot may do: :data:`PLAY`, :data:`STAND`, or walk to ``target`` (x, y,
    heading on the field) for :data:`POSITION`."""

    what: str
    target: tuple[float, float, float] | None = None


class GameControl:
    """Reads ``game_state`` for the behaviour on ``node``; ``on_change`` is called on every
    new game state or secondary state (a behaviour that decides on a timer reacts at once)."""

    def __init__(self, node: NodeHandle, *, on_change: Callable[[], None] | None = None) -> None:
        self.node = node
        robot = node.declare_parameter("robot", "")
        self.player: Player | None = parse_robot(robot) if robot else None
        self.state: GameState | None = None
        self._on_change = on_change
        self._playing_since_ns: int | None = None
        self._placement_due = False
        self._placed_spot: tuple[float, float, float] | None = None
        node.create_subscription(GameState, "game_state", self._on_state, qos=latched_qos())

    def _on_state(self, state: GameState) -> None:
        last, self.state = self.state, state
        changed = last is None or (last.game_state, last.secondary_state) != (
            state.game_state, state.secondary_state)
        if not changed:
            return
        if state.game_state == GameState.STATE_PLAYING:
            self._playing_since_ns = self.node.clock.now_ns()
        self._placement_due = state.game_state == GameState.STATE_SET
        self._placed_spot = None
        if self._on_change is not None:
            self._on_change()

    # -- what the game state says about this robot ----------------------------------------

    def _team(self) -> TeamInfo | None:
        if self.state is None or self.player is None:
            return None
        colour = TeamInfo.COLOUR_BLUE if self.player.team == "blue" else TeamInfo.COLOUR_RED
        return next((t for t in self.state.teams if t.team_colour == colour), None)

    def kicking(self) -> bool:
        """Whether the robot's team has the kick-off (or the set play)."""
        team = self._team()
        return team is not None and self.state is not None and (
            team.team_number == self.state.kicking_team)

    def penalised(self) -> bool:
        team = self._team()
        if team is None or self.player is None or len(team.players) < self.player.number:
            return False
        info: PlayerInfo = team.players[self.player.number - 1]
        return bool(info.penalty != PlayerInfo.PENALTY_NONE)

    def goal(self) -> tuple[float, float] | None:
        """The centre of the goal the robot attacks in this half (None: not known)."""
        if self.state is None or self.player is None:
            return None
        return (attack_sign(self.player.team, first_half=self.state.first_half)
                * KIDSIZE.half_length, 0.0)

    def kickoff_pending(self) -> bool:
        """The other team's kick-off has not freed the ball yet: keep out of the circle."""
        state = self.state
        if state is None or state.game_state != GameState.STATE_PLAYING or self.kicking():
            return False
        waited = (self.node.clock.now_ns() - (self._playing_since_ns or 0)) / 1e9
        return (state.secondary_state == GameState.STATE2_NORMAL
                and state.secondary_seconds_remaining > 0 and waited < KICKOFF_FREE_S)

    def _spot(self, *, kicking: bool) -> tuple[float, float, float] | None:
        if self.state is None or self.player is None:
            return None
        return kickoff_pose(self.player, first_half=self.state.first_half, kicking=kicking)

    def order(self, x: float, y: float) -> Order:
        """The order for a robot that believes it stands at ``x, y`` on the field."""
        state = self.state
        if state is None:
            return Order(PLAY)
        if state.game_state == GameState.STATE_READY:
            spot = self._spot(kicking=self.kicking())
            return Order(STAND) if spot is None else Order(POSITION, spot)
        if state.game_state != GameState.STATE_PLAYING or self.penalised():
            return Order(STAND)
        if self.kickoff_pending():
            if math.hypot(x, y) < CENTRE_CIRCLE_RADIUS + CIRCLE_MARGIN_M:
                return Order(POSITION, self._spot(kicking=False))
            return Order(STAND)
        return Order(PLAY)

    def placed(self, x: float, y: float) -> tuple[float, float, float] | None:
        """During ``set``: the kick-off spot if the robot, believing it stood at ``x, y``
        when ``set`` began, was in an illegal position (so the referee placed it there),
        else None. Answered for the whole of ``set``, so a behaviour that takes it as its
        pose at every decision has it after the placement, whenever that arrives."""
        state = self.state
        if state is None or self.player is None or state.game_state != GameState.STATE_SET:
            return None
        if self._placement_due:
            self._placement_due = False
            if not legal_at_kickoff(self.player.team, x, y, first_half=state.first_half,
                                    kicking=self.kicking()):
                self._placed_spot = self._spot(kicking=self.kicking())
        return self._placed_spot
