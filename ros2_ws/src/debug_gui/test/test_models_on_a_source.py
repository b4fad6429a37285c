"""Every view's model driven by debug_gui.testing.FakeSource: no DDS, no browser.

What a playback asks of the models (issue 21, point 1): they forget on a seek, judge ages
by the messages' stamps on the source's clock (a paused source ages nothing, a jump
forward ages everything, a stamp older than the robot's newest is that much older), and
say "not live" for a call a log cannot answer, before calling.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import pytest
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import PointStamped
from nav_msgs.msg import Odometry
from rcl_interfaces.msg import Log, Parameter, ParameterEvent, ParameterType, ParameterValue
from sensor_msgs.msg import CompressedImage
from std_msgs.msg import String

from debug_gui import AccessPolicy, InvalidInput, NotLive, RobotId
from debug_gui.models.components import STALE_AFTER_S, ComponentsModel
from debug_gui.models.image import GRACE_S, IMAGE_TOPIC, MARKERS_TOPIC, ImageModel
from debug_gui.models.logs import LogsModel
from debug_gui.models.parameters import ParametersModel
from debug_gui.models.recorder import RecorderModel, RecorderTeam
from debug_gui.models.topics import TopicsModel
from debug_gui.models.world import FRESH_S, STALE_S, WorldModel
from debug_gui.robots import STATS_SUFFIX
from debug_gui.testing import FakeSource
from efficient_comm import to_msg
from efficient_comm_interfaces.msg import CallbackStats, ExecutorStats
from robot_recorder_interfaces.msg import RecorderStatus
from robot_recorder_interfaces.srv import Start

T0 = 1000.0  # the log's time at the cursor when a test starts (s)
ROBOT = RobotId(3, "/robot1")
POLICY = AccessPolicy.for_server(token="t0ken-for-tests-0123456789")


def _stamp(msg: Any, t: float) -> Any:
    msg.header.stamp = to_msg(round(t * 1e9))
    return msg


def _stats(t: float, pid: int = 1) -> ExecutorStats:
    return ExecutorStats(
        stamp=to_msg(round(t * 1e9)), process_name="robot", hostname="h", pid=pid,
        callbacks=[CallbackStats(node="/robot1/detector", kind="subscription",
                                 name="/robot1/camera/image_raw", rate_hz=30.0, mean_ns=1000,
                                 p95_ns=1000, max_ns=1000)])


def _odom(t: float, x: float = 1.0) -> Odometry:
    msg = _stamp(Odometry(), t)
    msg.pose.pose.position.x, msg.pose.pose.orientation.w = x, 1.0
    return msg


def _ball(t: float) -> PointStamped:
    msg = _stamp(PointStamped(), t)
    msg.point.x, msg.point.z = 0.0, 1.0  # straight ahead, 1 m
    return msg


def _frame(t: float) -> CompressedImage:
    return _stamp(CompressedImage(format="jpeg", data=b"\xff\xd8jpeg"), t)


def _status(t: float) -> RecorderStatus:
    return RecorderStatus(stamp=to_msg(round(t * 1e9)), state=RecorderStatus.RECORDING,
                          bag="/bags/a", messages=12)


def _event(node: str, name: str, value: int) -> ParameterEvent:
    return ParameterEvent(node=node, changed_parameters=[Parameter(
        name=name, value=ParameterValue(type=ParameterType.PARAMETER_INTEGER,
                                        integer_value=value))])


def _source(*, live: bool = True) -> FakeSource:
    source = FakeSource(live=live, start_s=T0)
    source.add_robot(ROBOT, topics={
        "odom": "nav_msgs/msg/Odometry", IMAGE_TOPIC: "sensor_msgs/msg/CompressedImage",
        "recorder/status": "robot_recorder_interfaces/msg/RecorderStatus",
        "odom_text": "std_msgs/msg/String",
    }, services={"recorder/start": "robot_recorder_interfaces/srv/Start"},
        nodes=["detector"])
    return source


@dataclass
class Case:
    """A model, what feeds it one instant's data, and what it holds of it."""

    make: Callable[[FakeSource], Any]
    feed: Callable[[FakeSource, Any], object]
    holds: Callable[[Any], object]


def _feed_params(source: FakeSource, model: ParametersModel) -> None:
    with pytest.raises(NotLive, match="recorded: not live"):
        model.load("/robot1/detector")  # chosen all the same: its recorded events show
    source.publish(ROBOT, "/parameter_events", _event("/robot1/detector", "threshold", 7))


CASES = {
    "components": Case(
        lambda s: ComponentsModel(s, ROBOT),
        lambda s, m: s.publish(ROBOT, STATS_SUFFIX, _stats(T0)),
        lambda m: [r.node for r in m.rows()]),
    "image": Case(
        lambda s: ImageModel(s, ROBOT),
        lambda s, m: [s.publish(ROBOT, IMAGE_TOPIC, _frame(T0 - 1 + k / 10)) for k in range(3)],
        lambda m: [f.stamp_ns for f in m.frames()]),
    "logs": Case(
        lambda s: LogsModel(s, ROBOT),
        lambda s, m: (s.publish(ROBOT, "/rosout", Log(name="robot1.detector", msg="seen",
                                                       level=20)),
                      s.publish(ROBOT, "/diagnostics", DiagnosticArray(status=[
                          DiagnosticStatus(name="/robot1/detector: camera", message="ok")]))),
        lambda m: [e.text for e in m.logs()] + [s.name for s in m.statuses()]),
    "parameters": Case(
        lambda s: ParametersModel(s, ROBOT, policy=POLICY, token=None),
        _feed_params,
        lambda m: [(p.name, p.value) for p in m.parameters()]),
    "recorder": Case(
        lambda s: RecorderModel(s, ROBOT, policy=POLICY, token=None),
        lambda s, m: s.publish(ROBOT, "recorder/status", _status(T0)),
        lambda m: [st.statuses for st in m.states() if st.state != "waiting"]),
    "topics": Case(
        lambda s: TopicsModel(s, ROBOT),
        lambda s, m: (m.echo("odom", "nav_msgs/msg/Odometry"),
                      s.publish(ROBOT, STATS_SUFFIX, _stats(T0)),
                      s.publish(ROBOT, "odom", _odom(T0))),
        lambda m: (m.last(), [t["rate_hz"] for t in m.topics() if t["rate_hz"]])),
    "world": Case(
        lambda s: WorldModel(s, [ROBOT]),
        lambda s, m: (s.publish(ROBOT, "odom", _odom(T0)), s.publish(ROBOT, "ball/estimate",
                                                                      _ball(T0))),
        lambda m: [(st.pose, st.ball) for st in m.states() if st.pose or st.ball]),
}


def _empty(held: object) -> bool:
    if isinstance(held, tuple):
        return all(_empty(h) for h in held)
    return not held


# A live parameters model loads by service (tests/test_gui_parameters_data.py); reset is
# the same code either way.
@pytest.mark.parametrize(("kind", "live"), [
    (kind, live) for kind in sorted(CASES) for live in (True, False)
    if live is False or kind != "parameters"])
def test_every_model_forgets_on_a_seek_and_stops_listening_when_deactivated(
        kind: str, live: bool) -> None:
    case = CASES[kind]
    source = _source(live=live)
    model = case.make(source)
    model.activate()
    case.feed(source, model)
    assert not _empty(case.holds(model)), f"{kind}: fed nothing"
    source.set_time(T0 - 30.0)  # a seek backwards: what was delivered no longer holds
    source.reset()
    assert _empty(case.holds(model)), f"{kind} kept {case.holds(model)!r} across a seek"
    source.set_time(T0)
    case.feed(source, model)  # the playback delivers the new instant's messages
    held = case.holds(model)
    assert not _empty(held)
    model.deactivate()
    assert source.streams() == []
    source.reset()  # no longer its business: a hidden view keeps what it showed
    assert case.holds(model) == held


def test_a_paused_source_keeps_the_last_pose_and_ball_fresh_a_jump_forward_ages_them() -> None:
    source = _source(live=False)
    model = WorldModel(source, [ROBOT])
    model.activate()
    source.publish(ROBOT, "odom", _odom(T0))
    source.publish(ROBOT, "ball/estimate", _ball(T0))
    for _ in range(3):  # paused: the clock stands, however long the user looks
        [state] = model.states()
        assert state.pose_age_s == 0.0 and not state.pose_stale
        assert state.ball is not None and state.ball_age_s == 0.0
    source.advance(FRESH_S + 0.5)  # a step forward with nothing new: older, still drawn
    [state] = model.states()
    assert state.ball is not None and state.ball_age_s == pytest.approx(FRESH_S + 0.5)
    assert model.team_ball() is None  # no longer fresh enough to fuse
    source.advance(STALE_S)  # a jump forward: the robot said nothing since
    [state] = model.states()
    assert state.pose_stale and state.pose_age_s == pytest.approx(STALE_S + FRESH_S + 0.5)
    assert state.ball is None


def test_a_stamp_older_than_the_robots_newest_shows_as_old() -> None:
    """After a seek the playback delivers the last messages at one instant: the ball
    estimate stamped 2 s before the odometry is 2 s old, not fresh."""
    source = _source(live=False)
    model = WorldModel(source, [ROBOT])
    model.activate()
    source.publish(ROBOT, "ball/estimate", _ball(T0 - 2.0))
    source.publish(ROBOT, "odom", _odom(T0))
    [state] = model.states()
    assert state.ball_age_s == pytest.approx(2.0) and state.pose_age_s == 0.0


def test_components_drop_a_process_by_its_stamp_and_follow_the_source_clock() -> None:
    source = _source()
    model = ComponentsModel(source, ROBOT)
    model.activate()
    source.publish(ROBOT, STATS_SUFFIX, _stats(T0 - STALE_AFTER_S - 1, pid=1))  # ended long ago
    source.advance(1.0)  # the stream's 1 Hz lets the next one through
    source.publish(ROBOT, STATS_SUFFIX, _stats(T0 + 1.0, pid=2))
    assert [r.process for r in model.rows()] == ["robot (h:2)"]
    assert model.age_s() == 0.0
    source.advance(STALE_AFTER_S)  # paused this long: still there
    assert len(model.rows()) == 1 and model.age_s() == pytest.approx(STALE_AFTER_S)
    source.advance(0.5)
    assert model.rows() == []


def test_recorder_status_ages_on_the_source_clock() -> None:
    source = _source(live=False)
    model = RecorderModel(source, ROBOT, policy=POLICY, token=POLICY.token)
    model.activate()
    assert model.discover() == ["/robot1/recorder"]  # recorded: found by its status alone
    source.publish(ROBOT, "recorder/status", _status(T0))
    [state] = model.states()
    assert state.state == "recording" and state.age_s == 0.0
    source.advance(4.0)
    [state] = model.states()
    assert state.age_s == pytest.approx(4.0)


def test_a_frame_waits_for_its_drawing_on_the_source_clock_and_by_stamps() -> None:
    source = _source(live=True)
    model = ImageModel(source, ROBOT)
    model.activate()
    source.publish(ROBOT, IMAGE_TOPIC, _frame(T0))
    assert model.current() is None  # waiting for its drawing
    source.advance(GRACE_S + 0.01)
    shown = model.current()
    assert shown is not None and shown[0].stamp_ns == round(T0 * 1e9)
    # Frames delivered in a burst: the older ones have had their time by their stamps, the
    # newest still waits for its drawing.
    for k in range(3):
        assert source.publish(ROBOT, IMAGE_TOPIC, _frame(T0 + 5 + k * 2 * GRACE_S)) == 1
        source.advance(1 / 25)  # within the burst, as fast as the view's 30 Hz lets it
    shown = model.current()
    assert shown is not None and shown[0].stamp_ns == round((T0 + 5 + 2 * GRACE_S) * 1e9)


def test_a_recorded_frame_shows_paused_and_the_drawn_one_while_its_drawing_lags() -> None:
    """Recorded, nothing waits on the clock (paused, it never moves): the frame of a seek's
    instant shows at once; once frames have drawings, the newest drawn one shows rather
    than a newer one whose drawing is still to come (the overlay does not blink)."""
    from efficient_comm_interfaces.msg import ImageMarkerArray

    source = _source(live=False)
    model = ImageModel(source, ROBOT)
    model.activate()
    source.publish(ROBOT, IMAGE_TOPIC, _frame(T0))
    shown = model.current()
    assert shown is not None and shown == (model.frames()[-1], None)
    assert source.publish(ROBOT, MARKERS_TOPIC, _stamp(ImageMarkerArray(), T0)) == 1
    source.publish(ROBOT, IMAGE_TOPIC, _frame(T0 + 0.04))  # its drawing not yet there
    shown = model.current()
    assert shown is not None and shown[0].stamp_ns == round(T0 * 1e9)
    assert shown[1] is not None and shown[1].stamp_ns == round(T0 * 1e9)
    source.reset()  # a seek
    assert model.current() is None


def test_the_topics_plot_puts_messages_at_their_stamps() -> None:
    source = _source(live=False)
    model = TopicsModel(source, ROBOT)
    model.activate()
    model.echo("odom", "nav_msgs/msg/Odometry")
    source.publish(ROBOT, "odom", _odom(T0 - 2.0, x=0.0))
    model.plot("pose.pose.position.x")
    [stream] = source.streams(ROBOT, "odom")
    stream.set_rate(None)  # every message, as a playback catching up delivers them
    for t, x in ((T0 - 1.0, 1.0), (T0 - 0.5, 2.0), (T0, 3.0)):  # delivered at one instant
        source.publish(ROBOT, "odom", _odom(t, x=x))
    assert model.series() == [(pytest.approx(-1.0), 1.0), (pytest.approx(-0.5), 2.0),
                              (0.0, 3.0)]


# -- calls a log cannot answer ---------------------------------------------------------------


def test_calls_of_a_recorded_source_say_not_live_and_name_what_cannot_be_done() -> None:
    source = _source(live=False)
    # Were a call made, it would answer: the models must refuse before calling.
    source.answer(ROBOT, "recorder/start", Start.Response(success=True, bag="/bags/b"))
    image = ImageModel(source, ROBOT)
    with pytest.raises(NotLive, match="recorded: not live: a log cannot read the JPEG quality"):
        image.quality()
    with pytest.raises(NotLive, match="cannot set the JPEG quality"):
        image.set_quality(80)
    recorder = RecorderModel(source, ROBOT, policy=POLICY, token=POLICY.token)
    with pytest.raises(NotLive, match="recorded: not live: a log's recorder cannot start"):
        recorder.start()
    [result] = RecorderTeam([recorder]).for_all("stop")
    assert not result.success and "not live" in result.text
    params = ParametersModel(source, ROBOT, policy=POLICY, token=POLICY.token)
    params.activate()
    with pytest.raises(NotLive):
        params.load("/robot1/detector")
    source.publish(ROBOT, "/parameter_events", _event("/robot1/detector", "threshold", 7))
    assert params.nodes() == ["/robot1/detector"]  # as the log's events name them
    [param] = params.parameters()
    assert (param.name, param.value) == ("threshold", 7)
    outcome = params.set("threshold", "9")
    assert not outcome.ok and "recorded: not live: a log cannot set threshold" in outcome.message


def test_a_live_source_answers_the_same_calls() -> None:
    source = _source()
    source.answer(ROBOT, "recorder/start", lambda req: Start.Response(
        success=True, bag=req.bag or "/bags/b"))
    recorder = RecorderModel(source, ROBOT, policy=POLICY, token=POLICY.token)
    result = recorder.start(bag="/bags/mine")
    assert result.success and result.bag == "/bags/mine"


# -- the double itself -----------------------------------------------------------------------


def test_the_fake_source_honours_each_streams_rate_on_its_own_clock() -> None:
    source = _source()
    got: list[str] = []
    slow = source.subscribe(ROBOT, "odom_text", String, lambda m: got.append(f"slow {m.data}"),
                            rate_hz=2.0)
    source.subscribe(ROBOT, "/robot1/odom_text", String, lambda m: got.append(f"all {m.data}"))
    for k in range(3):
        source.publish(ROBOT, "odom_text", String(data=str(k)))
        source.advance(0.25)
    assert got == ["slow 0", "all 0", "all 1", "slow 2", "all 2"]
    assert slow.received == 2
    with pytest.raises(InvalidInput, match="subscribed as String"):
        source.publish(ROBOT, "odom_text", Odometry())
