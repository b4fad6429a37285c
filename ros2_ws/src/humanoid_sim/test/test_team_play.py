"""The team layer: the team message, the shared ball and dynamic roles, first as pure logic,
then as the TeamComm component on test handles (two robots joined by a relay that stands in
for the team link, so a cut link is the relay stopping)."""

from __future__ import annotations

import math
from collections.abc import Callable

import pytest
from geometry_msgs.msg import PointStamped, PoseWithCovarianceStamped
from rclpy.serialization import serialize_message
from std_msgs.msg import String

from efficient_comm import ComponentSpec, ParameterError, to_msg
from efficient_comm.testing import TestHandle, test_container
from humanoid_sim.errors import TeamMessageError
from humanoid_sim.soccer.roles import Player, Role, RoleKeeper, RoleRules, assign_roles
from humanoid_sim.soccer.shared_ball import OWN, BallBelief, fuse, observed
from humanoid_sim.soccer.team_comm import MESSAGES_TOPIC, TeamComm
from humanoid_sim.soccer.team_message import (
    Intention,
    OwnBall,
    PlayerState,
    decode,
    encode,
    time_to_ball,
)
from soccer_field import KIDSIZE
from soccer_interfaces.msg import TeamMessage

# -- the team message ---------------------------------------------------------------------


def _state(player: int = 2, **changes: object) -> PlayerState:
    values: dict[str, object] = dict(
        team=7, player=player, x=1.0, y=-0.5, theta=0.25, pose_sigma=0.2,
        ball=OwnBall(2.0, 0.5, 0.1, 0.4), role=Role.SUPPORTER, intention=Intention.POSITION,
        time_to_ball_s=8.5, fallen=False, stamp_ns=3_000_000_123,
    )
    values.update(changes)
    return PlayerState(**values)  # type: ignore[arg-type]


def test_a_team_message_reads_back_what_was_written_and_stays_small() -> None:
    state = _state()
    back = decode(encode(state))
    assert back.ball is not None and state.ball is not None
    assert (back.team, back.player, back.role, back.intention, back.fallen, back.stamp_ns) == (
        7, 2, Role.SUPPORTER, Intention.POSITION, False, 3_000_000_123)
    for name in ("x", "y", "theta", "pose_sigma", "time_to_ball_s"):
        assert getattr(back, name) == pytest.approx(getattr(state, name), abs=1e-6)
    assert (back.ball.x, back.ball.y, back.ball.sigma, back.ball.age_s) == pytest.approx(
        (2.0, 0.5, 0.1, 0.4), abs=1e-6)
    no_ball = decode(encode(_state(ball=None, time_to_ball_s=math.inf)))
    assert no_ball.ball is None and no_ball.time_to_ball_s == math.inf
    # the figure docs/HUMANOID_SIM.md gives: 64 bytes of CDR per message
    assert len(serialize_message(encode(state))) == 64


@pytest.mark.parametrize("field, value", [("x", math.nan), ("pose_sigma", -1.0),
                                          ("player_number", 0), ("ball_sigma", math.inf)])
def test_a_message_no_robot_could_send_is_refused(field: str, value: float) -> None:
    msg = encode(_state())
    setattr(msg, field, value)
    with pytest.raises(TeamMessageError):
        decode(msg)


def test_time_to_ball_walks_turns_and_gets_up() -> None:
    kw: dict[str, float | bool] = dict(walk_speed=0.2, turn_speed=0.5, fallen=False,
                                       fallen_penalty_s=8.0)
    assert time_to_ball(0.0, 0.0, 0.0, (1.0, 0.0), **kw) == pytest.approx(5.0)  # type: ignore[arg-type]
    assert time_to_ball(0.0, 0.0, math.pi, (1.0, 0.0), **kw) == pytest.approx(  # type: ignore[arg-type]
        5.0 + math.pi / 0.5)
    kw["fallen"] = True
    assert time_to_ball(0.0, 0.0, 0.0, (1.0, 0.0), **kw) == pytest.approx(13.0)  # type: ignore[arg-type]
    assert time_to_ball(0.0, 0.0, 0.0, None, **kw) == math.inf  # type: ignore[arg-type]


# -- the shared ball ----------------------------------------------------------------------


def test_fusion_weights_by_uncertainty_and_age() -> None:
    sure = BallBelief(1.0, 0.0, 0.1, 0.0, source=OWN)
    vague = BallBelief(1.3, 0.0, 0.3, 0.0, source=2)
    fused = fuse([sure, vague], max_age_s=5.0, growth_m_per_s=0.0)
    assert fused is not None
    # inverse-variance weights 100 and 11.1: close to the sure one, surer than either
    assert fused.x == pytest.approx((100 * 1.0 + 1.3 / 0.09) / (100 + 1 / 0.09))
    assert fused.sigma == pytest.approx(1 / math.sqrt(100 + 1 / 0.09))
    assert fused.sources == (OWN, 2)
    # the same vague belief, but fresh while the sure one is 3 s old: the fresh one wins
    old = BallBelief(1.0, 0.0, 0.1, 3.0, source=OWN)
    fused = fuse([old, vague], max_age_s=5.0, growth_m_per_s=0.3)
    assert fused is not None and fused.x > 1.15
    assert fuse([BallBelief(1.0, 0.0, 0.1, 6.0)], max_age_s=5.0, growth_m_per_s=0.3) is None
    assert fuse([BallBelief(math.nan, 0.0, 0.1, 0.0)], max_age_s=5.0,
                growth_m_per_s=0.3) is None


def test_a_teammates_ball_is_only_as_good_as_its_pose() -> None:
    belief = observed(2.0, 1.0, ball_sigma=0.1, pose_sigma=0.5, age_s=0.0, source=3)
    assert belief.sigma == pytest.approx(math.hypot(0.1, 0.5))
    # a lost teammate's ball far from a sure one is left out, not averaged in
    sure = BallBelief(0.0, 0.0, 0.1, 0.0)
    lost = observed(3.0, 0.0, ball_sigma=0.1, pose_sigma=0.5, age_s=0.0, source=3)
    fused = fuse([sure, lost], max_age_s=5.0, growth_m_per_s=0.3)
    assert fused is not None and fused.sources == (OWN,) and fused.x == 0.0


# -- roles ----------------------------------------------------------------------------------

RULES = RoleRules(goalie_number=0, margin_s=1.0, position_margin_m=0.5)


def test_roles_from_time_to_ball_and_position() -> None:
    players = [Player(1, -3.0, 0.0, 20.0), Player(2, 0.0, 0.0, 5.0), Player(3, -1.0, 1.0, 9.0)]
    assert assign_roles(players, RULES) == {2: Role.STRIKER, 1: Role.DEFENDER,
                                            3: Role.SUPPORTER}
    with_goalie = RoleRules(goalie_number=1)
    assert assign_roles(players, with_goalie) == {1: Role.GOALIE, 2: Role.STRIKER,
                                                  3: Role.SUPPORTER}
    # the goalie never goes for the ball, however near it is
    near = [Player(1, -3.0, 0.0, 1.0), Player(2, 0.0, 0.0, 5.0)]
    assert assign_roles(near, with_goalie) == {1: Role.GOALIE, 2: Role.STRIKER}
    # alone, every robot plays striker, the fixed goalie too
    assert assign_roles([Player(1, -4.0, 0.0, 30.0)], with_goalie) == {1: Role.STRIKER}
    assert RULES.own_goal == (-KIDSIZE.half_length, 0.0)


def test_the_incumbent_striker_keeps_the_role_within_the_margin() -> None:
    a = Player(1, 0.0, 0.0, 5.0, Role.STRIKER)
    b = Player(2, 0.0, 1.0, 4.5, Role.SUPPORTER)
    assert assign_roles([a, b], RULES)[1] == Role.STRIKER  # 0.5 s faster: not enough
    b = Player(2, 0.0, 1.0, 3.9, Role.SUPPORTER)
    assert assign_roles([a, b], RULES)[2] == Role.STRIKER  # 1.1 s faster: takes it
    no_margin = RoleRules(margin_s=0.0)
    b = Player(2, 0.0, 1.0, 4.99, Role.SUPPORTER)
    assert assign_roles([a, b], no_margin)[2] == Role.STRIKER
    # ties go to the lower number, on every robot alike
    tie = [Player(3, 0.0, 0.0, 5.0), Player(2, 1.0, 0.0, 5.0)]
    assert assign_roles(tie, no_margin)[2] == Role.STRIKER


def test_a_role_is_held_for_the_minimum_time() -> None:
    keeper = RoleKeeper(min_hold_s=2.0)
    assert keeper.update(Role.STRIKER, 0) == Role.STRIKER  # the first role: no switch
    assert keeper.update(Role.SUPPORTER, 1_000_000_000) == Role.STRIKER
    assert keeper.update(Role.SUPPORTER, 2_000_000_000) == Role.SUPPORTER
    assert keeper.switches == 1
    assert Role.from_wire(Role.DEFENDER.wire) == Role.DEFENDER
    assert Role.from_wire(99) == Role.UNDEFINED
    assert Role.GOALIE.wire == TeamMessage.ROLE_GOALIE  # the enum follows the message


# -- the component --------------------------------------------------------------------------


def _pose(x: float, y: float, theta: float, sigma: float) -> PoseWithCovarianceStamped:
    msg = PoseWithCovarianceStamped()
    msg.header.frame_id = "field"
    msg.pose.pose.position.x, msg.pose.pose.position.y = x, y
    msg.pose.pose.orientation.z, msg.pose.pose.orientation.w = (math.sin(theta / 2),
                                                               math.cos(theta / 2))
    cov = [0.0] * 36
    cov[0] = cov[7] = sigma * sigma
    msg.pose.covariance = cov
    return msg


class Robot:
    """One robot's TeamComm on a test handle of its own (its own bus and manual clock)."""

    def __init__(self, player: int, **parameters: object) -> None:
        self.node = TestHandle(f"team_{player}", parameters={
            "team_number": 1, "player_number": player, **parameters})
        self.comm = TeamComm(self.node)
        self.player = player

    def place(self, x: float, y: float, theta: float, *, sigma: float = 0.1) -> None:
        self.node.inject("localization/pose", _pose(x, y, theta, sigma))

    def see_ball(self, bx: float, by: float) -> None:
        """The ball model reports the field point (bx, by) relative to the robot's pose."""
        assert self.comm.pose is not None
        x, y, theta = self.comm.pose
        dx, dy = bx - x, by - y
        c, s = math.cos(theta), math.sin(theta)
        msg = PointStamped()
        msg.header.stamp = to_msg(self.node.now_ns())
        msg.header.frame_id = "base_footprint"
        msg.point.x, msg.point.y = c * dx + s * dy, -s * dx + c * dy
        self.node.inject("ball/position", msg)

    def sent(self) -> list[TeamMessage]:
        return [m for m in self.node.published(MESSAGES_TOPIC)
                if m.player_number == self.player]

    def roles(self) -> list[str]:
        return [m.data for m in self.node.published("role")]


def test_a_robot_that_cannot_see_the_ball_knows_where_it_is_from_a_teammate() -> None:
    me = Robot(1)
    me.place(-2.0, 0.0, 0.0, sigma=0.1)
    me.node.advance(1.0)
    assert me.node.published("team_ball") == []  # nobody has seen the ball yet
    mate = encode(_state(player=2, team=1, pose_sigma=0.2, ball=OwnBall(1.5, 0.5, 0.1, 0.5)))
    me.node.inject(MESSAGES_TOPIC, mate)
    me.node.advance(0.15)  # the next update, at 1.1 s
    ball = me.node.published("team_ball")[-1]
    assert ball.header.frame_id == "field"
    assert (ball.pose.pose.position.x, ball.pose.pose.position.y) == pytest.approx((1.5, 0.5))
    # its sigma: the teammate's ball and pose sigmas, grown by 0.6 s of age at 0.3 m/s
    expected = math.hypot(0.1, 0.2, 0.3 * 0.6)
    assert math.sqrt(ball.pose.covariance[0]) == pytest.approx(expected, rel=0.02)
    assert me.comm.ball is not None and me.comm.ball.sources == (2,)
    # this robot's time to that ball goes out in its own message, with no ball of its own
    me.node.advance(0.5)
    (mine,) = me.sent()[-1:]
    assert not mine.ball_known and math.isfinite(mine.time_to_ball_s)


def test_the_team_message_says_what_the_robot_knows_at_its_rate() -> None:
    me = Robot(3, team_number=5, send_hz=2.0)
    me.place(1.0, 1.0, math.pi / 2, sigma=0.3)
    me.see_ball(1.0, 2.0)  # 1 m straight ahead
    me.node.inject("fall/state", String(data="standing"))
    me.node.inject("behaviour/state", String(data="approach"))
    me.node.advance(5.0)
    sent = me.sent()
    assert len(sent) == 10  # 2 Hz
    last = decode(sent[-1])
    assert (last.team, last.player, last.intention, last.fallen) == (
        5, 3, Intention.GO_TO_BALL, False)
    assert (last.x, last.y, last.theta, last.pose_sigma) == pytest.approx(
        (1.0, 1.0, math.pi / 2, 0.3), abs=1e-5)
    assert last.ball is not None
    assert (last.ball.x, last.ball.y) == pytest.approx((1.0, 2.0), abs=1e-5)
    assert last.ball.sigma == pytest.approx(0.05 + 0.1 * 1.0, abs=1e-6)  # its own, no pose
    assert last.ball.age_s == pytest.approx(5.0, abs=0.01)  # seen at 0, sent at 5 s
    assert last.time_to_ball_s == pytest.approx(1.0 / 0.15, abs=0.01)
    assert last.role == Role.STRIKER  # alone
    me.node.inject("fall/state", String(data="fallen"))
    me.node.advance(0.5)
    assert decode(me.sent()[-1]).fallen


def test_own_echo_other_team_malformed_and_stale_messages_are_dropped() -> None:
    me = Robot(1, teammate_timeout_s=3.0)
    me.place(0.0, 0.0, 0.0)
    me.node.advance(1.0)  # its own messages come back on the shared topic
    assert me.comm.teammates.drops["own"] == 2
    me.node.inject(MESSAGES_TOPIC, encode(_state(player=2, team=9)))
    bad = encode(_state(player=3, team=1))
    bad.x = math.nan
    me.node.inject(MESSAGES_TOPIC, bad, bad)
    good = encode(_state(player=2, team=1, stamp_ns=5))
    me.node.inject(MESSAGES_TOPIC, good, encode(_state(player=2, team=1, stamp_ns=4)))
    drops = me.comm.teammates.drops
    assert (drops["other_team"], drops["malformed"], drops["out_of_order"]) == (1, 2, 1)
    warned = [text for _, text in me.node.records if "not finite" in text]
    assert len(warned) == 1 and "player 3" in warned[0]  # once per sender, then counted
    assert [m.state.player for m in me.comm.teammates.fresh(me.node.now_ns())] == [2]
    me.node.advance(3.1)
    assert me.comm.teammates.fresh(me.node.now_ns()) == []
    assert drops["timed_out"] == 1


def test_wrong_parameters_are_refused_and_right_ones_apply_at_once() -> None:
    with pytest.raises(ValueError, match="player_number"):
        Robot(0)
    me = Robot(1)
    with pytest.raises(ParameterError):
        me.node.set_parameter("role_margin_s", -1.0)
    # the hysteresis can be turned down on a running robot
    me.node.set_parameter("role_min_hold_s", 0.0)
    me.node.set_parameter("teammate_timeout_s", 1.0)
    assert me.comm.keeper.min_hold_ns == 0 and me.comm.teammates.timeout_ns == 1_000_000_000


Relay = Callable[[], None]


def _relay(robots: list[Robot]) -> Relay:
    """Hand every robot's new team messages to the others: the team link's stand-in."""
    seen = {r.player: 0 for r in robots}

    def relay() -> None:
        for sender in robots:
            sent = sender.sent()
            for msg in sent[seen[sender.player]:]:
                for receiver in robots:
                    if receiver is not sender:
                        receiver.node.inject(MESSAGES_TOPIC, msg)
            seen[sender.player] = len(sent)

    return relay


def _play(robots: list[Robot], relay: Relay | None, seconds: float,
          step: Callable[[float], None], dt: float = 0.1) -> None:
    t = 0.0
    while t < seconds - 1e-9:
        step(t)
        for r in robots:
            r.node.advance(dt)
        if relay is not None:
            relay()
        t += dt


def _crossing(**hysteresis: float) -> tuple[Robot, Robot]:
    """Two robots on either side of the ball; robot 2 sways so that the two times to the
    ball cross back and forth every two seconds (0.33 s either way)."""
    a, b = Robot(1, **hysteresis), Robot(2, **hysteresis)
    relay = _relay([a, b])

    def step(t: float) -> None:
        a.place(-1.0, 0.0, 0.0)
        b.place(1.0 + 0.05 * math.sin(2 * math.pi * t / 4.0), 0.0, math.pi)
        a.see_ball(0.0, 0.0)
        b.see_ball(0.0, 0.0)

    _play([a, b], relay, 40.0, step)
    return a, b


def test_roles_oscillate_without_hysteresis_and_hold_with_it() -> None:
    still = _crossing(role_margin_s=1.0, role_min_hold_s=2.0)
    restless = _crossing(role_margin_s=0.0, role_min_hold_s=0.0)
    calm_switches = [r.comm.keeper.switches for r in still]
    wild_switches = [r.comm.keeper.switches for r in restless]
    # the times cross 20 times in 40 s: without hysteresis the roles follow (Fig. 5.11)
    assert min(wild_switches) >= 10, wild_switches
    assert max(calm_switches) <= 1, calm_switches
    # ... and the role topic shows it: one message per change
    assert [len(r.roles()) for r in restless] == [s + 1 for s in wild_switches]
    # with hysteresis, one striker and one supporter
    assert sorted(r.comm.keeper.role.value for r in still) == ["striker", "supporter"]


def test_a_cut_link_makes_every_robot_a_striker() -> None:
    robots = [Robot(n, goalie_number=1, teammate_timeout_s=2.0, role_min_hold_s=0.5)
              for n in (1, 2, 3)]

    def step(t: float) -> None:
        for n, r in enumerate(robots):
            r.place(-3.0 + 1.5 * n, 0.5 * n, 0.0)
            r.see_ball(1.0, 0.0)

    _play(robots, _relay(robots), 4.0, step)
    # robot 3 is nearest the ball, robot 1 the fixed goalie
    assert [r.comm.keeper.role for r in robots] == [Role.GOALIE, Role.SUPPORTER,
                                                    Role.STRIKER]
    _play(robots, None, 3.0, step)  # the link is cut: nothing crosses
    assert [r.comm.keeper.role for r in robots] == [Role.STRIKER] * 3
    assert all(r.comm.teammates.fresh(r.node.now_ns()) == [] for r in robots)
    assert [r.roles()[-1] for r in robots] == ["striker"] * 3


def test_a_container_loads_it_by_its_plugin_name() -> None:
    with test_container() as container:
        loaded = container.load(ComponentSpec(
            class_path="humanoid_sim::TeamComm", name="team_comm",
            parameters={"team_number": 2, "player_number": 3, "goalie_number": 1}))
        assert isinstance(loaded.instance, TeamComm)
        assert (loaded.instance.p.team_number, loaded.instance.p.goalie_number) == (2, 1)
