"""rosbag2_layout alone: what rosbags reads back, recovery, QoS in metadata.yaml, bad input."""

from __future__ import annotations

from pathlib import Path
from typing import IO, Any

import pytest
import yaml
from mcap.reader import make_reader
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import serialize_message
from rosbags.highlevel import AnyReader
from rosbags.rosbag2 import Reader as Rosbag2Reader
from std_msgs.msg import String

from rosbag2_layout import (
    BagFormatError,
    BagNotFoundError,
    BagReader,
    BagWriter,
    FileSystem,
    UnknownTypeError,
    import_service,
    qos_dict,
    qos_profile,
    recover,
    service_definitions,
)

STRING = "std_msgs/msg/String"


def _data(text: str) -> bytes:
    return bytes(serialize_message(String(data=text)))


def _latched() -> QoSProfile:
    return QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL,
                      reliability=ReliabilityPolicy.RELIABLE)


class _Streams(FileSystem):
    """Keeps the files it opens, so a test can drop them as a killed process would."""

    def __init__(self) -> None:
        self.opened: list[IO[bytes]] = []

    def open_new(self, path: Path) -> IO[bytes]:
        stream = super().open_new(path)
        self.opened.append(stream)
        return stream


def _cut_bag(tmp_path: Path, *, max_file_bytes: int = 0, torn: bool = True) -> Path:
    """A bag whose writer never finished its last file, as SIGKILL leaves it; ``torn``
    also cuts the file's last bytes, as a machine losing power can (no footer at all)."""
    bag = tmp_path / "cut"
    fs = _Streams()
    writer = BagWriter(bag, min_free_bytes=0, chunk_bytes=256, max_file_bytes=max_file_bytes,
                       fs=fs)
    writer.add_topic("/latched", STRING, qos_profiles=[qos_dict(_latched())])
    writer.add_metadata("team_clock", {"robot": "a", "offset_ns": "5"})
    for i in range(50):
        writer.write("/latched", STRING, _data(f"m{i}"), 1_000 + i)
    writer.flush()
    file = writer.current_file
    assert file is not None
    for stream in fs.opened:  # the writer never finishes: dropped as a killed process
        stream.close()
    if torn:
        size = file.stat().st_size
        with open(file, "r+b") as f:
            f.truncate(size - 3)
    return bag


def test_a_bag_whose_writer_was_killed_opens_in_every_reader_with_every_message(
        tmp_path: Path) -> None:
    bag = _cut_bag(tmp_path, torn=False)
    texts = [f"m{i}" for i in range(50)]
    with Rosbag2Reader(bag) as reader:  # metadata.yaml lists the open file and its counts
        assert reader.message_count == 50
    with AnyReader([bag]) as any_reader:
        decoded: list[Any] = [any_reader.deserialize(raw, conn.msgtype)
                              for conn, _, raw in any_reader.messages()]
    assert [m.data for m in decoded] == texts
    with open(bag / "cut_0.mcap", "rb") as stream:  # mcap's seeking reader
        assert len(list(make_reader(stream).iter_messages())) == 50
    reader2 = BagReader(bag)
    assert len(list(reader2.messages())) == 50
    assert reader2.truncated == []


def test_a_file_cut_mid_record_is_read_up_to_the_cut_by_our_reader(tmp_path: Path) -> None:
    bag = _cut_bag(tmp_path)
    reader2 = BagReader(bag)
    assert len(list(reader2.messages())) > 0
    assert reader2.truncated == [bag / "cut_0.mcap"]


def test_recover_keeps_messages_qos_and_metadata_records(tmp_path: Path) -> None:
    bag = _cut_bag(tmp_path, max_file_bytes=300)  # completed files, then one cut short
    readable = len(list(BagReader(bag).messages()))
    out = tmp_path / "recovered"
    assert recover(bag, out) == readable
    reader = BagReader(out)
    assert reader.truncated == []
    assert reader.metadata_records()["team_clock"] == {"robot": "a", "offset_ns": "5"}
    assert reader.topic_records()["/latched"].qos_profiles[0]["durability"] == "transient_local"
    with AnyReader([out]) as any_reader:
        decoded: list[Any] = [any_reader.deserialize(raw, conn.msgtype)
                              for conn, _, raw in any_reader.messages()]
        texts = [m.data for m in decoded]
    assert texts == [f"m{i}" for i in range(readable)]


def test_recover_of_a_missing_bag_raises_and_leaves_nothing(tmp_path: Path) -> None:
    out = tmp_path / "out"
    with pytest.raises(BagNotFoundError):
        recover(tmp_path / "missing", out)
    assert not out.exists()


def test_recover_of_garbage_raises_and_leaves_nothing(tmp_path: Path) -> None:
    junk = tmp_path / "junk.mcap"
    junk.write_bytes(b"this is not an mcap file at all" * 10)
    out = tmp_path / "out"
    with pytest.raises(BagFormatError, match="not an MCAP file"):
        recover(junk, out)
    assert not out.exists()


def test_offered_qos_is_written_as_rosbag2_jazzy_writes_it(tmp_path: Path) -> None:
    bag = tmp_path / "qos"
    with BagWriter(bag, min_free_bytes=0) as writer:
        writer.add_topic("/latched", STRING, qos_profiles=[qos_dict(_latched())])
        writer.write("/latched", STRING, _data("x"), 5)
    info = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert info["version"] == 9
    meta = info["topics_with_message_count"][0]["topic_metadata"]
    profiles = meta["offered_qos_profiles"]
    assert isinstance(profiles, list)  # Jazzy: a YAML list, not a string
    assert profiles[0]["durability"] == "transient_local"
    assert profiles[0]["reliability"] == "reliable"
    assert profiles[0]["history"] == "keep_last"
    assert profiles[0]["depth"] == 1
    assert set(profiles[0]["deadline"]) == {"sec", "nsec"}
    with Rosbag2Reader(bag) as reader:  # rosbags reads both places the same way
        (conn,) = reader.connections
        ext: Any = conn.ext
        assert ext.offered_qos_profiles[0].durability.name == "TRANSIENT_LOCAL"
    played = qos_profile(BagReader(bag).topic_records()["/latched"].qos_profiles[0])
    assert played.durability == DurabilityPolicy.TRANSIENT_LOCAL


def test_a_listed_file_that_is_missing_is_refused(tmp_path: Path) -> None:
    bag = tmp_path / "holey"
    with BagWriter(bag, min_free_bytes=0, max_file_bytes=1) as writer:
        for i in range(3):
            writer.write("/t", STRING, _data(f"m{i}"), i + 1)
    (bag / "holey_1.mcap").unlink()
    with pytest.raises(BagNotFoundError, match="missing"):
        BagReader(bag)


def test_a_damaged_file_is_refused_or_read_up_to_the_damage(tmp_path: Path) -> None:
    bag = tmp_path / "damaged.mcap"
    with BagWriter(bag, min_free_bytes=0, chunk_bytes=64) as writer:
        for i in range(200):
            writer.write("/t", STRING, _data(f"message {i}"), i + 1)
    data = bytearray(bag.read_bytes())
    middle = len(data) // 2
    data[middle - len(data) // 4:middle + len(data) // 4] = b"\xff" * (len(data) // 2)
    damaged = tmp_path / "copy.mcap"
    damaged.write_bytes(bytes(data))
    reader = BagReader(damaged)
    try:  # damage is either refused or read up to where it starts, and said so
        readable = len(list(reader.messages()))
    except BagFormatError:
        return
    assert 0 < readable < 200
    assert reader.truncated == [damaged]
    assert len(reader.problems) == 1 and len(reader.problems[0]) < 400


def test_service_definitions_decode_what_rclpy_serializes() -> None:
    # A viewer without rcl_interfaces installed decodes a request from the schema alone.
    from mcap_ros2._dynamic import generate_dynamic
    from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue

    request_def, response_def = service_definitions("rcl_interfaces/srv/SetParameters")
    srv: Any = import_service("rcl_interfaces/srv/SetParameters")
    request = srv.Request(parameters=[Parameter(name="threshold", value=ParameterValue(
        type=ParameterType.PARAMETER_DOUBLE, double_value=0.25))])
    decode = generate_dynamic("rcl_interfaces/srv/SetParameters_Request", request_def)
    decoded = decode["rcl_interfaces/srv/SetParameters_Request"](serialize_message(request))
    assert decoded.parameters[0].name == "threshold"
    assert decoded.parameters[0].value.double_value == 0.25
    assert "MSG: rcl_interfaces/msg/SetParametersResult" in response_def
    with pytest.raises(UnknownTypeError):
        service_definitions("rcl_interfaces/msg/Parameter")
    with pytest.raises(UnknownTypeError):
        import_service("no_such_pkg/srv/Nothing")


def _timed_bag(tmp_path: Path, **options: Any) -> Path:
    """200 messages, one per 10 ms on two topics, in small chunks and (with
    ``max_file_bytes``) several files."""
    bag = tmp_path / "timed"
    with BagWriter(bag, min_free_bytes=0, chunk_bytes=512, **options) as writer:
        for i in range(200):
            writer.write("/a" if i % 2 else "/b", STRING, _data(f"m{i}"),
                         1_000_000_000 + i * 10_000_000)
    return bag


@pytest.mark.parametrize("options", [{}, {"max_file_bytes": 2048}])
def test_a_time_window_reads_the_messages_logged_in_it_and_only_its_chunks(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, options: dict[str, Any]) -> None:
    from mcap.records import Chunk

    bag = _timed_bag(tmp_path, **options)
    everything = list(BagReader(bag).messages())
    reads: list[int] = []
    real_read = Chunk.read

    def counted(stream: Any) -> Any:
        reads.append(1)
        return real_read(stream)

    monkeypatch.setattr(Chunk, "read", counted)
    start, end = 1_500_000_000, 1_600_000_000
    window = list(BagReader(bag).messages(start_ns=start, end_ns=end))
    assert [m.log_time_ns for m in window] == [
        m.log_time_ns for m in everything if start <= m.log_time_ns < end]
    assert len(window) == 10
    chunks_in_window = len(reads)
    reads.clear()
    assert len(list(BagReader(bag).messages())) == 200
    # A tenth of the log reads far fewer chunks than the whole.
    assert 0 < chunks_in_window < len(reads) / 3, (chunks_in_window, len(reads))
    # Open sides, and topics with a window.
    assert len(list(BagReader(bag).messages(end_ns=start))) == 50
    assert len(list(BagReader(bag).messages(start_ns=end))) == 140
    assert {m.topic for m in BagReader(bag).messages(topics=["/a"], start_ns=start,
                                                     end_ns=end)} == {"/a"}


def test_a_time_window_applies_to_a_file_cut_short(tmp_path: Path) -> None:
    bag = _cut_bag(tmp_path)
    every = [m.log_time_ns for m in BagReader(bag).messages()]
    middle = every[len(every) // 2]
    assert [m.log_time_ns for m in BagReader(bag).messages(start_ns=middle)] == [
        t for t in every if t >= middle]
