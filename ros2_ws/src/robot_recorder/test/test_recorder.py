"""The recorder composed with other components: what is published is what the bag holds.

No DDS here (a test container); bags are read back with rosbags and with the mcap reader,
both decoding from the schemas stored in the file, as a tool without our packages would.
"""

from __future__ import annotations

import threading
from pathlib import Path
from typing import Any

import pytest
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import PointStamped, Pose, PoseArray
from sensor_msgs.msg import Image, JointState
from std_msgs.msg import Empty, String

from efficient_comm.handle import NodeHandle
from efficient_comm.testing import TestHandle, isolated_domain_id, test_container, unique_topic
from robot_recorder import (
    Recorder,
    RecorderConfigError,
    TopicSelection,
    parse_selection,
)
from robot_recorder.bag import read_messages, read_metadata_records
from robot_recorder.testing import drained, read_mcap, read_rosbags
from rosbag2_layout import UnknownTypeError as BagTypeError
from rosbag2_layout import full_definition
from throttle_publisher import ThrottledPublisher


class Robot:
    """Publishes strings, images and joint states, the kinds a robot logs."""

    def __init__(self, node: NodeHandle, prefix: str) -> None:
        self.text = node.create_publisher(String, f"{prefix}/text", qos=100)
        self.image = node.create_publisher(Image, f"{prefix}/image", qos=100)
        self.joints = node.create_publisher(JointState, f"{prefix}/joints", qos=100)
        self.sent: list[tuple[str, Any]] = []

    def step(self, i: int) -> None:
        text = String(data=f"hello {i} äö")
        image = Image(height=2, width=3, encoding="rgb8", step=9,
                      data=bytes((i + k) % 256 for k in range(18)))
        image.header.stamp.sec, image.header.frame_id = i, "cam"
        joints = JointState(name=["a", "b"], position=[i * 0.5, -1.0], velocity=[], effort=[])
        for pub, msg in ((self.text, text), (self.image, image), (self.joints, joints)):
            pub.publish(msg)
            self.sent.append((pub.topic_name, msg))


def _compose(tmp_path: Path, prefix: str, **options: Any) -> tuple[Any, Robot, Recorder]:
    container = test_container()
    robot = Robot(TestHandle("robot", container=container), prefix)
    recorder = Recorder(TestHandle("recorder", container=container),
                        output_dir=tmp_path, **options)
    return container, robot, recorder


def _plain(value: Any, like: Any) -> Any:
    """``value`` (decoded by any reader) as plain Python, shaped by the published ``like``."""
    if hasattr(like, "get_fields_and_field_types"):
        return {n: _plain(getattr(value, n), getattr(like, n))
                for n in like.get_fields_and_field_types()}
    if hasattr(value, "tolist"):
        value = value.tolist()
    if isinstance(value, bytes | bytearray | list | tuple) or type(value).__name__ == "array":
        return [_plain(v, v) for v in value]
    return value


def _same(sent: Any, got: Any) -> bool:
    """A published rclpy message equals a decoded one, field by field."""
    return bool(_plain(sent, sent) == _plain(got, sent))


def test_bag_holds_what_was_published_read_by_rosbags_and_mcap(tmp_path: Path) -> None:
    prefix = unique_topic("robot")
    container, robot, recorder = _compose(
        tmp_path, prefix, topics=[f"{prefix}/text", f"{prefix}/image", f"{prefix}/joints"])
    bag = recorder.start(tmp_path / "bag").result(10)
    for i in range(50):
        robot.step(i)
        container.advance(0.01)
    drained(recorder.writer)
    assert recorder.stop().result(10) == bag
    recorder.close()

    decoded = read_rosbags(bag)
    assert [t for t, _ in decoded] == [t for t, _ in robot.sent]
    assert all(_same(sent, got) for (_, sent), (_, got) in zip(robot.sent, decoded, strict=True))
    files = sorted(bag.glob("*.mcap"))
    assert len(files) == 1
    via_mcap = read_mcap(files[0])
    assert [t for t, _ in via_mcap] == [t for t, _ in robot.sent]
    assert all(_same(sent, got) for (_, sent), (_, got) in zip(robot.sent, via_mcap, strict=True))
    status = recorder.status()
    assert status.messages == 150 and status.drops == 0
    assert {t.name: t.messages for t in status.topics} == {
        f"{prefix}/{k}": 50 for k in ("text", "image", "joints")}


def test_callback_only_enqueues_the_very_object(tmp_path: Path) -> None:
    prefix = unique_topic("robot")
    _, robot, recorder = _compose(tmp_path, prefix, topics=[f"{prefix}/text"])
    gate = threading.Event()
    recorder.writer._command(gate.wait)  # stall the writer so the queue can be looked at
    recorder.start(tmp_path / "bag")
    robot.step(0)
    queued = [item for item in recorder.writer._queue if isinstance(item, tuple)]
    gate.set()
    recorder.close()
    # Nothing serialized or copied on the callback path: the very object, and its time.
    assert len(queued) == 1 and queued[0][1] is robot.sent[0][1]
    assert queued[0][2] == 0  # receive time from the node's (manual) clock


def test_full_queue_drops_are_counted_per_topic_and_the_rest_is_written(tmp_path: Path) -> None:
    prefix = unique_topic("robot")
    _, robot, recorder = _compose(
        tmp_path, prefix, topics=[f"{prefix}/text", f"{prefix}/image", f"{prefix}/joints"])
    gate = threading.Event()
    recorder.writer._command(gate.wait)  # stall the writer thread
    recorder.start(tmp_path / "bag")
    for i in range(500):  # 1500 messages against a queue of 1000 while the writer waits
        robot.step(i)
    gate.set()
    drained(recorder.writer)
    states = recorder.topic_states()
    drops = sum(s.drops for s in states.values())
    written = sum(s.messages for s in states.values())
    assert drops == 1500 - 999  # the start command holds one place of the 1000
    assert written + drops == 1500
    status = recorder.status()
    assert status.drops == drops and {t.name: t.drops for t in status.topics} == {
        n: s.drops for n, s in states.items()}
    recorder.close()
    assert len(list(read_messages(tmp_path / "bag"))) == written


def test_throttled_topic_takes_only_every_nth_from_a_throttled_publisher(tmp_path: Path) -> None:
    topic = unique_topic("camera")
    container = test_container()
    source = ThrottledPublisher(TestHandle("camera", container=container), String, topic)
    recorder = Recorder(TestHandle("recorder", container=container), output_dir=tmp_path,
                        topics=[f"{topic} std_msgs/msg/String every_nth=3"])
    bag = recorder.start(tmp_path / "bag").result(10)
    container.advance(0.0)
    for i in range(30):
        if source.wants():
            source.publish(String(data=str(i)))
        else:
            source.skip()
        container.advance(0.01)
    recorder.close()
    got = [int(m.data) for _, m in read_rosbags(bag)]
    assert got == list(range(0, 30, 3))
    sent = sum(s.sent for s in source.stats().values())
    assert sent == 10  # the other samples never left the publisher


def test_throttled_topic_of_a_plain_publisher_is_subsampled_by_the_recorder(
        tmp_path: Path) -> None:
    """A plain publisher ignores throttle requests: the recorder drops the surplus itself
    (issue 18, 4c; it used to record nothing while saying it recorded the topic)."""
    topic = unique_topic("plain")
    container = test_container()
    source = TestHandle("plain", container=container).create_publisher(String, topic)
    recorder = Recorder(TestHandle("recorder", container=container), output_dir=tmp_path,
                        topics=[f"{topic} std_msgs/msg/String every_nth=4",
                                f"{topic}_fast std_msgs/msg/String max_rate_hz=10"])
    fast = TestHandle("fast", container=container).create_publisher(String, f"{topic}_fast")
    bag = recorder.start(tmp_path / "bag").result(10)
    container.advance(0.0)
    for i in range(40):  # 100 Hz for 0.4 s
        source.publish(String(data=str(i)))
        fast.publish(String(data=str(i)))
        container.advance(0.01)
    recorder.close()
    got: dict[str, list[int]] = {}
    for name, msg in read_rosbags(bag):
        got.setdefault(name, []).append(int(msg.data))
    assert got[topic] == list(range(0, 40, 4))
    assert got[f"{topic}_fast"] == list(range(0, 40, 10))  # 10 Hz of 100 Hz


def test_a_relative_output_dir_is_reported_absolute(tmp_path: Path,
                                                     monkeypatch: pytest.MonkeyPatch) -> None:
    """A viewer cannot know the recorder's working directory (issue 18, 4d)."""
    monkeypatch.chdir(tmp_path)
    recorder = Recorder(TestHandle("recorder", parameters={"snapshot_bytes": 1 << 16}),
                        output_dir="rel", topics=[])
    try:
        bag = recorder.start().result(10)
        named = recorder.snapshot("named").result(10)[0]
        status = recorder.status()
    finally:
        recorder.close()
    assert bag.is_absolute() and bag.parent == tmp_path / "rel", bag
    assert named == tmp_path / "named"
    assert status.bag == str(bag)


def test_set_topics_changes_what_is_recorded_at_run_time(tmp_path: Path) -> None:
    prefix = unique_topic("robot")
    _, robot, recorder = _compose(tmp_path, prefix, topics=[f"{prefix}/text"])
    bag = recorder.start(tmp_path / "bag").result(10)
    robot.step(0)
    recorder.set_topics([TopicSelection(name=f"{prefix}/joints")])
    robot.step(1)
    recorder.close()
    got = [(t, getattr(m, "data", None)) for t, m in read_rosbags(bag)]
    assert got == [(f"{prefix}/text", "hello 0 äö"), (f"{prefix}/joints", None)]


def test_topic_without_publisher_is_subscribed_once_it_appears(tmp_path: Path) -> None:
    topic = unique_topic("late")
    container = test_container()
    recorder = Recorder(TestHandle("recorder", container=container), output_dir=tmp_path,
                        topics=[topic])
    bag = recorder.start(tmp_path / "bag").result(10)
    assert recorder.topic_states() == {}
    pub = TestHandle("late", container=container).create_publisher(String, topic)
    container.advance(1.0)  # the status timer looks for types again
    pub.publish(String(data="x"))
    recorder.close()
    assert [m.data for _, m in read_rosbags(bag)] == ["x"]


def test_clock_offset_topic_is_recorded_and_stored_as_file_metadata(tmp_path: Path) -> None:
    clock_msgs = pytest.importorskip("team_clock_interfaces.msg")
    topic = unique_topic("team_clock")
    container = test_container()
    pub = TestHandle("sync", container=container).create_publisher(clock_msgs.ClockOffset, topic)
    recorder = Recorder(TestHandle("recorder", container=container), output_dir=tmp_path,
                        topics=[], clock_topic=topic)
    bag = recorder.start(tmp_path / "bag").result(10)
    for offset in (-400_000_000, 250_000_000):
        pub.publish(clock_msgs.ClockOffset(robot="r1", reference="r0", offset_ns=offset,
                                           drift_ppm=50.0, valid=True))
    recorder.close()
    assert [m.offset_ns for _, m in read_rosbags(bag)] == [-400_000_000, 250_000_000]
    meta = read_metadata_records(bag)["team_clock"]
    assert meta["offset_ns"] == "250000000" and meta["robot"] == "r1"
    assert meta["topic"] == topic and meta["stamp.sec"] == "0"


def test_selection_strings_and_bad_input() -> None:
    s = parse_selection("/a sensor_msgs/msg/Image max_rate_hz=5 every_nth=2")
    assert (s.name, s.type, s.max_rate_hz, s.every_nth) == ("/a", "sensor_msgs/msg/Image", 5, 2)
    for bad in ["", "/a x y", "/a max_rate_hz=fast", "/a every_nth=0", "/a colour=red"]:
        with pytest.raises(RecorderConfigError):
            parse_selection(bad)
    with pytest.raises(RecorderConfigError):
        Recorder(TestHandle("r"), topics=["/a", "/a"])


def test_unknown_type_is_reported_not_recorded(tmp_path: Path) -> None:
    recorder = Recorder(TestHandle("r"), output_dir=tmp_path,
                        topics=["/x nosuch_msgs/msg/Thing"])
    try:
        assert recorder.topic_states() == {}
        assert "nosuch_msgs" in recorder.status().error
    finally:
        recorder.close()
    with pytest.raises(BagTypeError):
        full_definition("std_msgs/msg/NoSuchType")


def test_full_definition_has_every_dependency_once() -> None:
    text = full_definition("sensor_msgs/msg/JointState")
    names = [line for line in text.splitlines() if line.startswith("MSG: ")]
    assert names == ["MSG: std_msgs/msg/Header", "MSG: builtin_interfaces/msg/Time"]
    assert text.count("=" * 80) == 2


@pytest.mark.parametrize("msg", [
    JointState(), JointState(name=["a", "bb"], position=[1.0], velocity=[1.0, 2.0]),
    Image(height=2, width=3, step=9, encoding="rgb8", data=bytes(18)),
    String(data="héllo"), PointStamped(), PoseArray(poses=[Pose(), Pose()]), Empty(),
    DiagnosticArray(status=[DiagnosticStatus(name="x", values=[KeyValue(key="k", value="v")])]),
], ids=lambda m: type(m).__name__)
def test_serialized_length_is_exact(msg: Any) -> None:
    """serialize_message returns rmw's size estimate; the recorder cuts at the real end,
    which is where rosbags' own serializer ends too."""
    from rclpy.serialization import serialize_message
    from rosbags.typesys import Stores, get_typestore

    from rosbag2_layout import trim, type_name

    store = get_typestore(Stores.ROS2_JAZZY)
    data = trim(msg, serialize_message(msg))
    name = type_name(type(msg))
    assert len(store.serialize_cdr(store.deserialize_cdr(data, name), name)) == len(data)


def test_timer_pacer_holds_the_writer_back_around_deadlines() -> None:
    """The pacer reads the executor's next timer deadline: hold back from 2 ms before it
    until 1 ms after it, else go."""
    from efficient_comm import Container, ManualClock
    from robot_recorder.recorder import _pacer, _timer_pacer

    container = test_container()
    clock = container.executor.clock
    assert isinstance(clock, ManualClock)
    ticks: list[int] = []
    TestHandle("loop", container=container).create_timer(0.01, lambda: ticks.append(1))
    pace = _pacer(container.executor, 2_000_000, 1_000_000)
    clock.set_ns(7_000_000)
    assert pace() == 0.0  # 3 ms ahead: go
    clock.set_ns(8_500_000)
    assert pace() == pytest.approx(0.0025)  # until 1 ms after the deadline
    container.advance(0.0015)  # the timer runs and is rescheduled to 20 ms
    assert ticks == [1] and container.executor.next_timer_due_ns() == 20_000_000
    clock.set_ns(10_400_000)
    assert pace() == pytest.approx(0.0006)  # still inside the round after the deadline
    clock.set_ns(11_100_000)
    assert pace() == 0.0
    assert _pacer(test_container().executor, 2_000_000, 1_000_000)() == 0.0  # no timers
    assert _timer_pacer(TestHandle("manual"), 0.002, 0.001) is None  # manual clock: no pacing
    with Container("real", dds=False, serve=False) as real:
        node = TestHandle("paced", container=real)
        assert _timer_pacer(node, 0.002, 0.001) is not None  # composed on a real clock
        assert _timer_pacer(node, 0.0, 0.0) is None  # turned off
    with Container("sim", sim_time=True, domain_id=isolated_domain_id(), serve=False,
                   stats_period_s=0) as sim:  # simulated time from /clock: no wall deadlines
        assert _timer_pacer(TestHandle("sim_paced", container=sim), 0.002, 0.001) is None


def test_switch_interval_is_shared_by_recorders_and_given_back(tmp_path: Path) -> None:
    """The interval is process-wide: the shortest asked for applies while recorders live,
    the interpreter's own comes back when the last closes (or construction fails)."""
    import sys

    before = sys.getswitchinterval()
    assert before > 0.001
    first = Recorder(TestHandle("first"), output_dir=tmp_path, topics=[])  # 0.2 ms default
    second = Recorder(TestHandle("second", parameters={"gil_switch_interval_s": 0.001}),
                      output_dir=tmp_path, topics=[])
    assert sys.getswitchinterval() == pytest.approx(0.0002)
    first.close()
    assert sys.getswitchinterval() == pytest.approx(0.001)
    second.close()
    assert sys.getswitchinterval() == before
    with pytest.raises(RecorderConfigError):
        Recorder(TestHandle("broken"), output_dir=tmp_path, topics=["/a", "/a"])
    assert sys.getswitchinterval() == before
    off = Recorder(TestHandle("off", parameters={"gil_switch_interval_s": 0.0}),
                   output_dir=tmp_path, topics=[])
    assert sys.getswitchinterval() == before
    off.close()
