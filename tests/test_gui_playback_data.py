"""debug_gui's Playback, a merged team log as the views' Source, driven without a browser.

The logs are written with log_analysis's LogBuilder (a real rosbag2 bag, read as a match's
merged log is). Deliveries are awaited with ``Playback.settle`` (the playing thread says
when it delivered what was asked), never with sleeps.
"""

from __future__ import annotations

import threading
import time
from pathlib import Path
from typing import Any

import pytest
from geometry_msgs.msg import PoseStamped
from rcl_interfaces.srv import GetParameters
from std_msgs.msg import String

from debug_gui import NotLive, RobotId
from debug_gui.errors import InvalidInput, LogUnreadable
from debug_gui.layout import Layout, Panel
from debug_gui.playback import Playback, filter_events, next_event, previous_event, rebind
from log_analysis import Event
from log_analysis.testing import LogBuilder

EPOCH = 1000.0
BLUE1 = RobotId(0, "/blue1")
RED1 = RobotId(0, "/red1")


def pose(x: float) -> PoseStamped:
    msg = PoseStamped()
    msg.pose.position.x = x
    return msg


@pytest.fixture
def log(tmp_path: Path) -> Path:
    """Two robots and the world, 4 s: blue1's pose at 10 Hz (x = t), red1's at 5 Hz
    (x = -t), blue1's role changing at 1.0 and 3.0 s, /rosout of blue1 once."""
    path = tmp_path / "merged"
    with LogBuilder(path, epoch_s=EPOCH) as b:
        for i in range(41):
            b.add("blue1", "ground_truth/pose", pose(i / 10), t=i / 10)
            if i % 2 == 0:
                b.add("red1", "ground_truth/pose", pose(-i / 10), t=i / 10)
        b.add("world", "ground_truth/ball", pose(0.5), t=0.0)
        b.add("blue1", "role", String(data="striker"), t=1.0)
        b.add("blue1", "role", String(data="supporter"), t=3.0)
        b.add("blue1", "rosout", String(data="hello"), t=2.0)
    return path


class Recorder:
    """What a view's model would keep: every message with the cursor when it came."""

    def __init__(self, playback: Playback) -> None:
        self.playback = playback
        self.got: list[tuple[float, Any]] = []
        self.lock = threading.Lock()

    def __call__(self, msg: Any) -> None:
        with self.lock:
            self.got.append((self.playback.now(), msg))

    def xs(self) -> list[float]:
        with self.lock:
            return [round(m.pose.position.x, 3) for _, m in self.got]


def test_the_log_is_a_source_named_as_the_match_is_live(log: Path) -> None:
    with Playback(log, domains={"red1": 14}) as p:
        red1 = RobotId(14, "/red1")
        assert p.robots() == [BLUE1, red1]  # the world is no robot: live it is not watched
        assert p.live is False
        assert p.now() == pytest.approx(EPOCH)
        assert "/blue1/ground_truth/pose" in p.topics(BLUE1)
        assert p.topics(BLUE1)["/blue1/role"] == ["std_msgs/msg/String"]
        assert p.publishes(BLUE1, "role") and not p.publishes(red1, "role")
        assert p.publishes(BLUE1, "/rosout")  # merged under the robot's namespace
        assert not p.publishes_statistics(BLUE1)
        with pytest.raises(NotLive, match="recorded: not live: a log does not answer"):
            p.call(BLUE1, "/blue1/x/get_parameters", GetParameters, GetParameters.Request())


def test_a_subscription_gets_the_instant_and_play_delivers_in_order_at_the_rate(
        log: Path) -> None:
    with Playback(log) as p:
        every, slow = Recorder(p), Recorder(p)
        p.subscribe(BLUE1, "ground_truth/pose", PoseStamped, every)
        p.subscribe(BLUE1, "ground_truth/pose", PoseStamped, slow, rate_hz=2.0)
        assert p.settle()
        assert every.xs() == [0.0] and slow.xs() == [0.0]  # the instant, as latched
        p.set_rate(8.0)
        p.play()
        started = time.monotonic()
        assert p.wait_stopped(20.0), "the playback did not reach the end of the log"
        assert p.cursor_ns == p.end_ns
        wall = time.monotonic() - started
        assert every.xs() == [round(i / 10, 3) for i in range(41)]  # in order, none lost
        # 2 Hz in log time: one message per half second of log, whatever the playback rate.
        assert slow.xs() == [0.0, 0.5, 1.0, 1.5, 2.0, 2.5, 3.0, 3.5, 4.0]
        # Each message came when the cursor had reached it, never before.
        assert all(now >= EPOCH + x - 1e-6 for now, x in
                   ((n, m.pose.position.x) for n, m in every.got))
        assert wall >= 4.0 / 8.0 * 0.9  # paced at 8x real time, not as fast as it reads


def test_seek_resets_the_views_then_delivers_the_instant(log: Path) -> None:
    with Playback(log) as p:
        order: list[str] = []
        p.on_reset(lambda: order.append("reset"))
        blue, red, roles = Recorder(p), Recorder(p), Recorder(p)
        p.subscribe(BLUE1, "ground_truth/pose", PoseStamped, blue)
        p.subscribe(RED1, "ground_truth/pose", PoseStamped, red)

        def on_role(msg: String) -> None:
            order.append(msg.data)
            roles(msg)

        p.subscribe(BLUE1, "role", String, on_role)
        assert p.settle()
        assert order == []  # no role before 1.0 s
        p.seek(EPOCH + 2.55)
        assert p.settle()
        assert p.now() == pytest.approx(EPOCH + 2.55)
        assert order == ["reset", "striker"]  # reset first, then the last role before 2.55
        assert blue.xs()[-1] == 2.5 and red.xs()[-1] == -2.4
        p.seek(EPOCH + 0.5)  # back: the role of 1.0 s is not yet
        assert p.settle()
        assert order == ["reset", "striker", "reset"]
        assert blue.xs()[-1] == 0.5
        p.seek(EPOCH + 99)  # beyond the end: the end
        assert p.settle()
        assert p.cursor_ns == p.end_ns and order[-1] == "supporter"


def test_step_moves_to_the_next_message_or_by_a_span(log: Path) -> None:
    with Playback(log) as p:
        roles: list[str] = []
        p.subscribe(BLUE1, "role", String, lambda m: roles.append(m.data))
        assert p.settle()
        p.step()
        assert p.settle()
        assert p.now() == pytest.approx(EPOCH + 1.0) and roles == ["striker"]
        p.step()
        assert p.settle()
        assert p.now() == pytest.approx(EPOCH + 3.0) and roles == ["striker", "supporter"]
        p.step(back=True)
        assert p.settle()
        assert p.now() == pytest.approx(EPOCH + 1.0) and roles[-1] == "striker"
        p.step(-0.5)
        assert p.settle()
        assert p.now() == pytest.approx(EPOCH + 0.5)
        p.step(2.7)  # forward by a span: delivers what it passes
        assert p.settle()
        assert p.now() == pytest.approx(EPOCH + 3.2) and roles[-2:] == ["striker", "supporter"]


def test_pause_holds_the_cursor_and_rates_are_checked(log: Path) -> None:
    with Playback(log) as p:
        p.set_rate(4.0)
        p.play()
        p.pause()
        held = p.now()
        assert p.settle()
        assert p.now() == held and not p.playing
        with pytest.raises(InvalidInput):
            p.set_rate(0)
        with pytest.raises(InvalidInput):
            p.set_rate(1000.0)


def test_a_damaged_log_is_a_clear_error(tmp_path: Path, log: Path) -> None:
    junk = tmp_path / "junk.mcap"
    junk.write_bytes(b"\x89MCAP0\r\n" + b"not a log at all" * 10)
    with pytest.raises(LogUnreadable, match=r"cannot play back .*junk\.mcap"):
        Playback(junk)
    with pytest.raises(LogUnreadable, match="cannot play back"):
        Playback(tmp_path / "nowhere")
    # Damaged in the middle: refused at once, or played up to the damage, which it says
    # (rosbag2_layout reads a damaged file up to its last complete record). Never a
    # traceback at the user, never a playback thread that dies.
    mcap = next(log.glob("*.mcap"))
    data = bytearray(mcap.read_bytes())
    quarter = len(data) // 4
    data[quarter:3 * quarter] = b"\xff" * (2 * quarter)
    mcap.write_bytes(bytes(data))
    try:
        p = Playback(log)
    except LogUnreadable as exc:
        assert "cannot play back" in str(exc) and "merged" in str(exc)
        return
    with p:
        got: list[PoseStamped] = []
        p.subscribe(BLUE1, "ground_truth/pose", PoseStamped, got.append)
        p.set_rate(100.0)
        p.play()  # through the whole log: it meets the damage
        assert p.wait_stopped(20.0)
        assert p.error is not None or p.problems, "the damage went unsaid"
        assert len(got) < 41
        p.seek(EPOCH + 1.0)  # and it still answers
        assert p.settle()


def test_a_layout_saved_live_opens_on_the_log_by_namespace() -> None:
    live = Layout((Panel(kind="world", robot=RobotId(13, "/blue1")), Panel(kind="components"),
                   Panel(kind="logs", robot=RobotId(15, "/green9"))))
    moved = rebind(live, [RobotId(0, "/blue1"), RobotId(0, "/red1")])
    assert [p.robot for p in moved.panels] == [RobotId(0, "/blue1"), None,
                                               RobotId(15, "/green9")]


def test_the_event_list_filters_and_navigates() -> None:
    events = [Event("fell", 3, 4, "blue1", "blue1 fell over", generator="falls"),
              Event("ball lost", 1, 2, "", "nobody saw the ball", generator="ball_lost"),
              Event("fell", 7, 7, "red1", "red1 fell", generator="falls")]
    assert [e.start_ns for e in filter_events(events)] == [1, 3, 7]
    assert [e.robot for e in filter_events(events, text="FELL")] == ["blue1", "red1"]
    assert [e.start_ns for e in filter_events(events, robot="red1")] == [7]
    assert [e.name for e in filter_events(events, generator="ball_lost")] == ["ball lost"]
    ordered = filter_events(events)
    assert next_event(ordered, 3) is ordered[2] and next_event(ordered, 7) is None
    assert previous_event(ordered, 3) is ordered[0] and previous_event(ordered, 1) is None


def test_the_views_models_show_the_instant_of_a_seek(tmp_path: Path) -> None:
    """The world, logs and topics views' models, as live, on a Playback: after a seek they
    hold the seek's instant (the same models the browser's views poll)."""
    from geometry_msgs.msg import PoseWithCovarianceStamped
    from rcl_interfaces.msg import Log

    from debug_gui.models.logs import LogsModel
    from debug_gui.models.topics import TopicsModel
    from debug_gui.models.world import WorldModel

    path = tmp_path / "merged"
    with LogBuilder(path, epoch_s=EPOCH) as b:
        for i in range(41):
            belief = PoseWithCovarianceStamped()
            belief.pose.pose.position.x = i / 10
            belief.pose.pose.orientation.w = 1.0
            b.add("blue1", "localization/pose", belief, t=i / 10)
        b.add("blue1", "role", String(data="striker"), t=1.0)
        b.add("blue1", "role", String(data="goalie"), t=3.0)
        b.add("blue1", "rosout", Log(name="blue1.kick", msg="kicked", level=20), t=2.0)
    with Playback(path) as p:
        world = WorldModel(p, p.robots(), clock=p.now)
        logs = LogsModel(p, BLUE1)
        topics = TopicsModel(p, BLUE1, clock=p.now)
        world.activate()
        logs.activate()
        topics.echo("/blue1/role", "std_msgs/msg/String")
        assert p.settle()
        p.seek(EPOCH + 2.5)
        assert p.settle()
        state = next(s for s in world.states() if s.robot == BLUE1)
        assert state.pose is not None and state.pose.x == pytest.approx(2.5)
        assert state.role == "striker"
        assert [e.text for e in logs.logs()][-1:] == ["kicked"]
        assert topics.last()["data"] == "striker"
        p.seek(EPOCH + 3.5)
        assert p.settle()
        state = next(s for s in world.states() if s.robot == BLUE1)
        assert state.pose is not None and state.pose.x == pytest.approx(3.5)
        assert state.role == "goalie" and topics.last()["data"] == "goalie"


def test_the_command_refuses_a_bad_log_or_video_in_one_line(tmp_path: Path, log: Path) -> None:
    """``debug_gui --log`` as a user types it: a damaged log, a missing video: one line,
    no traceback, exit status 2 (it never starts serving)."""
    import subprocess

    junk = tmp_path / "junk.mcap"
    junk.write_bytes(b"\x89MCAP0\r\n" + b"garbage" * 50)
    for args, reason in [(["--log", str(junk)], "cannot play back"),
                         (["--log", str(log), "--video", str(tmp_path / "none.mp4")],
                          "no video at")]:
        done = subprocess.run(["ros2", "run", "debug_gui", "debug_gui", "--port", "0", *args],
                              capture_output=True, text=True, timeout=120)
        assert done.returncode == 2, done.stderr
        lines = done.stderr.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("debug_gui: error: "), done.stderr
        assert reason in lines[0]


def test_the_image_view_shows_the_recorded_frame_of_the_instant(tmp_path: Path) -> None:
    from debug_gui.models.image import ImageModel
    from log_analysis.testing import seen_ball

    # Ten JPEG images of blue1's camera at 2 Hz from 1 s, stamped with their time.
    path = seen_ball(tmp_path / "seen", robot="blue1",
                     frames=[(1 + k / 2, float(k), False) for k in range(10)])
    with Playback(path) as p:
        image = ImageModel(p, BLUE1, clock=p.now)
        image.activate()
        p.seek(3.2)
        assert p.settle()
        # The frame of the instant is the one shown, paused, though it has no drawing
        # (a live frame would wait for one; a recorded one's drawing never comes).
        shown = image.current()
        assert shown is not None and shown[1] is None
        assert shown[0].stamp_ns == 3_000_000_000 and shown[0].jpeg.startswith(b"\xff\xd8")


def test_a_video_without_a_fit_is_shown_from_the_log_start_and_anchored_by_hand(
        tmp_path: Path) -> None:
    from debug_gui.security import AccessPolicy
    from debug_gui.ui.playback import PlaybackSetup, sync_path
    from log_analysis import ExternalVideo, VideoFit
    from log_analysis.testing import film_ball

    # The camera's clock 2 s ahead of the log's; its first frame at camera time 2 s.
    log, path = film_ball(tmp_path, lambda t: (t - 2.0, 0.5), seconds=4.0, offset_s=2.0,
                          drift_ppm=0.0, fps=5)
    video = ExternalVideo(path)
    with Playback(log) as p:
        setup = PlaybackSetup(playback=p, policy=AccessPolicy.for_server(host="127.0.0.1",
                                                                          token=None),
                              video=video)
        try:
            # No fit: the first frame at the log's start.
            assert setup.camera_ns(p.start_ns + 10**9) == video.start_ns + 10**9
            # The user sees, at log time 1 s, the frame of camera time 1.4 s later than
            # the one shown (offset +0.4 s) is the right one.
            fit = setup.anchor(p.start_ns + 10**9, offset_s=0.4)
            assert setup.camera_ns(p.start_ns + 10**9) == video.start_ns + 1_400_000_000
            kept = VideoFit.load(sync_path(path))  # kept beside the video
            assert (kept.offset_ns, kept.method) == (fit.offset_ns, "anchors")
            jpeg = setup.jpeg(p.start_ns + 10**9)
            assert jpeg is not None and jpeg.startswith(b"\xff\xd8")
        finally:
            setup.close()


def test_restoring_a_layout_saved_live_rebinds_it_to_the_log(tmp_path: Path, log: Path) -> None:
    from debug_gui.security import AccessPolicy
    from debug_gui.ui import registry
    from debug_gui.ui.playback import PlaybackShell

    registry.load_views()
    saved = tmp_path / "layout.json"
    saved.write_text(Layout((Panel(kind="world", robot=RobotId(13, "/red1")),)).to_json())
    with Playback(log) as p:
        shell = PlaybackShell(source=p, policy=AccessPolicy.for_server(host="127.0.0.1",
                                                                       token=None),
                              layout=Layout(), layout_path=saved)
        assert [panel.robot for panel in shell.restore().panels] == [RED1]
        assert shell.layout.panels[0].robot == RED1


def test_recorded_parameters_show_as_of_the_cursor_and_answer_no_call(tmp_path: Path) -> None:
    """The parameters view's model on a log: after a seek, a node's parameters are all its
    recorded events up to the instant (a parameter set once at the start is still there
    after a later event changed another one); a call is NotLive."""
    from rcl_interfaces.msg import Parameter, ParameterEvent, ParameterValue

    from debug_gui import AccessPolicy, params
    from debug_gui.models.parameters import ParametersModel

    def event(**changes: float) -> ParameterEvent:
        ps = [Parameter(name=k, value=ParameterValue(type=3, double_value=v))
              for k, v in changes.items()]
        return ParameterEvent(node="/blue1/walk", changed_parameters=ps)

    path = tmp_path / "merged"
    with LogBuilder(path, epoch_s=EPOCH) as b:
        b.add("blue1", "parameter_events", event(step=0.1, height=0.3), t=0.5)
        b.add("blue1", "parameter_events", event(step=0.2), t=2.0)
        b.add("red1", "role", String(data="striker"), t=0.0)
    with Playback(path) as p:
        assert p.nodes(BLUE1) == ["/blue1/walk"] and p.nodes(RED1) == []
        assert p.services(BLUE1) == {}
        model = ParametersModel(p, BLUE1, policy=AccessPolicy.for_server(token=None),
                                token=None)
        model.activate()
        try:
            with pytest.raises(NotLive):
                model.load("/blue1/walk")  # chosen all the same: its recorded events show

            def shown() -> dict[str, Any]:
                return {d.name: d.value for d in model.parameters()}

            p.seek(EPOCH + 1.0)
            assert p.settle()
            assert shown() == {"step": 0.1, "height": 0.3}
            p.seek(EPOCH + 3.0)
            assert p.settle()
            assert shown() == {"step": 0.2, "height": 0.3}
            assert model.nodes() == ["/blue1/walk"]
            p.seek(EPOCH + 0.2)  # before the first event: nothing recorded yet
            assert p.settle()
            assert shown() == {} and model.nodes() == []
        finally:
            model.deactivate()
        with pytest.raises(NotLive):
            params.describe(p, BLUE1, "/blue1/walk")


def test_an_event_at_a_wall_clock_epoch_is_sought_exactly(tmp_path: Path) -> None:
    """Log times since 1970 (a real robot's clock): an event's start is reached to the
    nanosecond, so its message is delivered and the next event is the next one."""
    path = tmp_path / "merged"
    epoch = 1_764_000_000.123456789
    with LogBuilder(path, epoch_s=epoch) as b:
        b.add("blue1", "role", String(data="striker"), t=0.0)
        b.add("blue1", "role", String(data="goalie"), t=1.000000007)
        start = b.ns(1.000000007)
    events = [Event("role", start, start, "blue1")]
    with Playback(path) as p:
        roles: list[str] = []
        p.subscribe(BLUE1, "role", String, lambda m: roles.append(m.data))
        p.seek_ns(events[0].start_ns)
        assert p.settle()
        assert p.cursor_ns == start and roles[-1] == "goalie"
        assert next_event(events, p.cursor_ns) is None
