"""Playing a bag into a running system: timing, rate, pause, seek, step, loop, selection,
remapping, stamps, remote control, and a recorded camera replacing a live detector's input.

All on a manual clock (test containers), so timings are exact.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from geometry_msgs.msg import PointStamped
from rclpy.serialization import serialize_message
from sensor_msgs.msg import Image
from std_msgs.msg import String

from efficient_comm import from_msg, to_msg
from efficient_comm.handle import NodeHandle
from efficient_comm.testing import TestHandle, test_container, unique_topic
from robot_recorder import PlaybackError, Player, Recorder, RecorderConfigError

MS = 1_000_000


def _record(tmp_path: Path, n: int = 50) -> tuple[Path, str, str]:
    """A bag of ``n`` strings on one topic and ``n`` stamped points on another, 10 ms apart,
    recorded from t = 1 s (stamps: the time of publishing)."""
    text, point = unique_topic("text"), unique_topic("point")
    container = test_container()
    talker = TestHandle("talker", container=container)
    pub_text = talker.create_publisher(String, text, qos=100)
    pub_point = talker.create_publisher(PointStamped, point, qos=100)
    recorder = Recorder(TestHandle("recorder", container=container), topics=[text, point],
                        output_dir=tmp_path)
    container.advance(1.0)
    bag = recorder.start(tmp_path / "bag").result(10)
    for i in range(n):
        pub_text.publish(String(data=str(i)))
        msg = PointStamped()
        msg.header.stamp = to_msg(talker.now_ns())
        msg.point.x = float(i)
        pub_point.publish(msg)
        container.advance(0.01)
    recorder.close()
    return bag, text, point


class Sink:
    """Records (clock time, message) of what arrives on a topic."""

    def __init__(self, node: NodeHandle, topic: str, msg_type: type) -> None:
        self.node = node
        self.got: list[tuple[int, Any]] = []
        node.create_subscription(msg_type, topic, self._on, qos=100)

    def _on(self, msg: Any) -> None:
        self.got.append((self.node.clock.now_ns(), msg))

    def texts(self) -> list[str]:
        return [m.data for _, m in self.got]


def _player(bag: Path, **options: Any) -> tuple[Any, Player]:
    container = test_container()
    return container, Player(TestHandle("player", container=container), bag=bag, **options)


def _run(container: Any, seconds: float) -> None:
    for _ in range(round(seconds / 0.001)):
        container.advance(0.001)


def test_plays_with_the_recorded_timing_and_at_a_rate(tmp_path: Path) -> None:
    bag, text, _ = _record(tmp_path)
    for rate in (1.0, 2.5):
        container, player = _player(bag, rate=rate)
        sink = Sink(TestHandle("sink", container=container), text, String)
        _run(container, 0.6 / rate)
        assert sink.texts() == [str(i) for i in range(50)]
        start = sink.got[0][0]
        for i, (t, _) in enumerate(sink.got):  # 10 ms apart / rate, within one 1 ms tick
            assert abs((t - start) - i * 10 * MS / rate) <= 1 * MS, (rate, i, t - start)
        assert player.finished and player.published == 100


def test_pause_resume_step_seek_and_loop(tmp_path: Path) -> None:
    bag, text, _ = _record(tmp_path, n=10)
    container, player = _player(bag, topics=[text], start_paused=True)
    sink = Sink(TestHandle("sink", container=container), text, String)
    _run(container, 0.2)
    assert sink.texts() == []  # paused from the start
    assert player.step() and player.step()
    assert sink.texts() == ["0", "1"]
    player.resume()
    _run(container, 0.025)
    player.pause()
    assert sink.texts() == ["0", "1", "2", "3", "4"]  # due at 0, 10, 20 ms after resuming
    _run(container, 0.2)
    assert len(sink.got) == 5
    player.seek(player.start_ns + 70 * MS)
    player.resume()
    _run(container, 0.2)
    assert sink.texts()[5:] == ["7", "8", "9"] and player.finished
    assert not player.step()  # at the end
    container2, looping = _player(bag, topics=[text], loop=True)
    sink2 = Sink(TestHandle("sink", container=container2), text, String)
    _run(container2, 0.25)  # 10 messages per 100 ms, and the loop starts over at once
    assert sink2.texts()[:25] == [str(i % 10) for i in range(25)]
    assert not looping.finished


def test_topic_selection_and_remapping(tmp_path: Path) -> None:
    bag, text, point = _record(tmp_path, n=5)
    target = unique_topic("replayed")
    container, _ = _player(bag, topics=[point], remappings=[f"{point}:={target}"])
    sink_text = Sink(TestHandle("a", container=container), text, String)
    sink_point = Sink(TestHandle("b", container=container), target, PointStamped)
    _run(container, 0.1)
    assert sink_text.got == []
    assert [m.point.x for _, m in sink_point.got] == [0.0, 1.0, 2.0, 3.0, 4.0]


class _Skewed:
    """A clock model: this robot's clock is 250 ms behind the team's."""

    def to_reference(self, local_ns: int) -> int:
        return local_ns + 250 * MS


@pytest.mark.parametrize("stamps", ["original", "aligned", "shifted"])
def test_stamps_original_aligned_or_shifted(tmp_path: Path, stamps: str) -> None:
    bag, _, point = _record(tmp_path, n=5)
    container = test_container()
    container.advance(100.0)  # playback clock far from the recording's
    Player(TestHandle("player", container=container), bag=bag, topics=[point], stamps=stamps,
           offset_model=_Skewed() if stamps == "aligned" else None)
    sink = Sink(TestHandle("sink", container=container), point, PointStamped)
    _run(container, 0.1)
    recorded = [1000 * MS + i * 10 * MS for i in range(5)]
    got = [from_msg(m.header.stamp) for _, m in sink.got]
    if stamps == "original":
        assert got == recorded
    elif stamps == "aligned":
        assert got == [t + 250 * MS for t in recorded]
    else:  # as old as they were on arrival, relative to the playback clock
        assert got == [t for t, _ in sink.got]


def test_remote_control_service(tmp_path: Path) -> None:
    from robot_recorder_interfaces.srv import PlayerControl

    bag, text, _ = _record(tmp_path, n=10)
    container, player = _player(bag, topics=[text])
    client = TestHandle("laptop", container=container).create_client(
        PlayerControl, "/player/control")

    def call(command: int, **fields: Any) -> Any:
        future = client.call_async(PlayerControl.Request(command=command, **fields))
        container.advance(0.0)
        assert future.done()
        return future.result()

    reply = call(PlayerControl.Request.PAUSE)
    assert reply.success and reply.paused and player.paused
    reply = call(PlayerControl.Request.SEEK, time_ns=player.start_ns + 50 * MS)
    assert reply.position_ns == player.start_ns + 50 * MS
    assert call(PlayerControl.Request.STEP).position_ns == player.start_ns + 60 * MS
    assert call(PlayerControl.Request.SET_RATE, rate=2.0).success and player.rate == 2.0
    reply = call(PlayerControl.Request.SET_RATE, rate=0.0)
    assert not reply.success and "rate" in reply.message
    reply = call(PlayerControl.Request.RESUME)
    assert reply.success and not reply.paused
    assert not call(99).success


def test_bad_input_is_refused_with_a_reason(tmp_path: Path) -> None:
    bag, _, _ = _record(tmp_path, n=3)
    with pytest.raises(PlaybackError, match="no bag"):
        _player(tmp_path / "missing")
    with pytest.raises(PlaybackError, match="no messages"):
        _player(bag, topics=["/nothing_here"])
    with pytest.raises(RecorderConfigError, match="FROM:=TO"):
        _player(bag, remappings=["/a=/b"])
    with pytest.raises(RecorderConfigError, match="stamps"):
        _player(bag, stamps="local")
    with pytest.raises(RecorderConfigError, match="rate"):
        _player(bag, rate=-1.0)
    with pytest.raises(RecorderConfigError, match="tick_s"):
        Player(TestHandle("player", parameters={"tick_s": 0.0}), bag=bag)


# -- a recorded camera replaces the live camera as the live ball detector's input --------------


def _ball_image(u: int, v: int) -> Image:
    rgb = np.full((120, 160, 3), (40, 120, 40), dtype=np.uint8)  # grass
    yy, xx = np.mgrid[0:120, 0:160]
    rgb[(xx - u) ** 2 + (yy - v) ** 2 <= 36] = (255, 120, 0)  # an orange ball, radius 6
    return Image(height=120, width=160, encoding="rgb8", step=480, data=rgb.tobytes())


class BallCamera:
    """A camera seeing the ball at a fixed pixel, 30 frames a second."""

    def __init__(self, node: NodeHandle, u: int, v: int) -> None:
        self.node = node
        self.image = _ball_image(u, v)
        self.pub = node.create_publisher(Image, "camera/image_raw", qos=5)
        node.create_timer(1 / 30, self._tick)

    def _tick(self) -> None:
        self.image.header.stamp = to_msg(self.node.clock.now_ns())
        self.pub.publish(self.image)


def test_recorded_camera_feeds_the_live_ball_detector(tmp_path: Path) -> None:
    vision = pytest.importorskip("humanoid_sim.soccer.vision")
    ns = unique_topic("robot")
    # 1. Record a camera that sees the ball at the left (u = 40).
    container = test_container()
    container.add(lambda n: BallCamera(n, 40, 60), name="camera", namespace=ns)
    recorder = container.add(
        lambda n: Recorder(n, topics=[f"{ns}/camera/image_raw"], output_dir=tmp_path),
        name="recorder")
    bag = recorder.start(tmp_path / "bag").result(10)
    container.advance(1.0)
    recorder.close()
    # 2. A running robot whose live camera sees the ball at the right (u = 120); its
    #    detector is fed the recording instead, the rest (camera, consumers) runs as usual.
    live = test_container()
    live.add(lambda n: BallCamera(n, 120, 60), name="camera", namespace=ns)
    detector = live.add(vision.BallDetector, name="detector", namespace=ns,
                        remappings={"camera/image_raw": "replay/image_raw"})
    sink = live.add(lambda n: Sink(n, f"{ns}/ball/detection", PointStamped), name="sink")
    live_frames = live.add(lambda n: Sink(n, f"{ns}/camera/image_raw", Image), name="watch")
    live.add(lambda n: Player(n, bag=bag, remappings=[
        f"{ns}/camera/image_raw:={ns}/replay/image_raw"], stamps="shifted"), name="player")
    _run(live, 1.2)
    assert len(live_frames.got) >= 30  # the live camera kept running
    assert detector.frames == 30 and detector.detections == 30  # every recorded frame
    # The bearing of the recorded ball (u = 40) with the detector's own intrinsics; the live
    # ball (u = 120) would be as far on the other side.
    left = math.atan2(detector.cx - 40, detector.fx)
    assert left > 0.1
    assert all(abs(m.point.x - left) < 0.02 for _, m in sink.got), sink.got[0][1].point


def test_aligned_stamps_from_the_clock_estimate_recorded_in_the_bag(tmp_path: Path) -> None:
    clock_msgs = pytest.importorskip("team_clock_interfaces.msg")
    pytest.importorskip("team_clock.model")
    point = unique_topic("point")
    container = test_container()
    talker = TestHandle("talker", container=container)
    pub_clock = talker.create_publisher(clock_msgs.ClockOffset, "/team_clock/offset")
    pub_point = talker.create_publisher(PointStamped, point)
    recorder = Recorder(TestHandle("recorder", container=container), topics=[point],
                        output_dir=tmp_path)  # the clock topic is recorded unasked
    container.advance(1.0)
    bag = recorder.start(tmp_path / "bag").result(10)
    estimate = clock_msgs.ClockOffset(robot="r1", reference="r0", source="r0",
                                      offset_ns=-400 * MS, drift_ppm=0.0, uncertainty_ns=MS,
                                      hops=1, samples=8, valid=True)
    estimate.stamp = to_msg(talker.now_ns())
    pub_clock.publish(estimate)
    sent = []
    for _ in range(3):
        msg = PointStamped()
        msg.header.stamp = to_msg(talker.now_ns())
        sent.append(talker.now_ns())
        pub_point.publish(msg)
        container.advance(0.01)
    recorder.close()
    # No offset_model given: the player asks team_clock for the one recorded in the bag.
    container2, _ = _player(bag, topics=[point], stamps="aligned")
    sink = Sink(TestHandle("sink", container=container2), point, PointStamped)
    _run(container2, 0.05)
    assert [from_msg(m.header.stamp) for _, m in sink.got] == [t - 400 * MS for t in sent]


def test_looping_a_one_message_bag_publishes_once_per_tick(tmp_path: Path) -> None:
    bag, text, _ = _record(tmp_path, n=1)
    container, _ = _player(bag, topics=[text], loop=True)
    sink = Sink(TestHandle("sink", container=container), text, String)
    _run(container, 0.01)
    assert 9 <= len(sink.got) <= 11  # not an endless loop inside one timer callback


def test_the_player_offers_transient_local_where_the_recording_says_so(tmp_path: Path) -> None:
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

    from rosbag2_layout import BagWriter, qos_dict

    topic, volatile_topic = unique_topic("map"), unique_topic("chatter")
    latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL)
    bag = tmp_path / "bag"
    with BagWriter(bag, min_free_bytes=0) as writer:
        writer.add_topic(topic, "std_msgs/msg/String", qos_profiles=[qos_dict(latched)])
        writer.write(topic, "std_msgs/msg/String", bytes(serialize_message(String(data="map"))),
                     1_000)
        writer.write(volatile_topic, "std_msgs/msg/String",
                     bytes(serialize_message(String(data="hi"))), 1_001)
    container = test_container()
    player = Player(TestHandle("player", container=container), bag=bag)
    container.advance(1.0)
    assert player.finished and player.published == 2
    # A late joiner asking for transient local gets the last message, as from the original.
    got: list[str] = []
    late = TestHandle("late", container=container)
    late.create_subscription(String, topic, lambda m: got.append(m.data), qos=latched)
    late.create_subscription(String, volatile_topic, lambda m: got.append(m.data), qos=10)
    container.advance(0.1)
    assert got == ["map"]
