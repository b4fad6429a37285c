"""Merging robots' logs in team time: the skewed-clock team, read back by rosbags and mcap.

Three robots run the clock-sync exchange over a simulated jittery, lossy network: the
reference ``ref``, ``a`` (clock +250 ms, +50 ppm) linked to it, and ``b`` (-400 ms, -50 ppm)
that only reaches the reference through ``a``. Each robot records its own log with its own
clock: its ``/team_clock/offset`` estimates and "flash" events that all robots see at the same
true instant. After merging, the events must line up within 1 ms.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import pytest
import yaml
from geometry_msgs.msg import PointStamped
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from rclpy.serialization import serialize_message
from rosbags.highlevel import AnyReader

from efficient_comm import to_msg
from rosbag2_layout import BagWriter
from team_clock.cli import main as cli_main
from team_clock.errors import LogFormatError, MergeError, NoEstimateError
from team_clock.merge import RobotLog, merge
from team_clock.model import Knot, OffsetModel, offset_metadata
from team_clock.testing import SimDelay, SimTeam
from team_clock_interfaces.msg import ClockOffset

MS = 1_000_000
SKEWS = {"ref": (1000 * MS, 0.0), "a": (250 * MS, 50.0), "b": (-400 * MS, -50.0)}
OFFSET_TYPE = "team_clock_interfaces/msg/ClockOffset"
EVENT_TYPE = "geometry_msgs/msg/PointStamped"


def _record_team(tmp_path: Path, *, seed: int = 5, loss: float = 0.2,
                 events: int = 60) -> tuple[dict[str, Path], dict[str, int]]:
    """Run the team, flash ``events`` times after a warm-up; the logs and the true times."""
    team = SimTeam(SKEWS, reference="ref", links=[("ref", "a"), ("a", "b")], loss=loss,
                   seed=seed, delay=SimDelay(min_s=0.001, jitter_s=0.002))
    return team.record_flashes(tmp_path, events=events, seed=seed)


def _events(path: Path) -> dict[str, dict[str, tuple[int, int]]]:
    """``{namespace: {event id: (log time, header stamp)}}`` read back with rosbags."""
    out: dict[str, dict[str, tuple[int, int]]] = {}
    with AnyReader([path]) as reader:
        conns = [c for c in reader.connections if c.topic.endswith("/event")]
        for conn, log_time, raw in reader.messages(connections=conns):
            msg: Any = reader.deserialize(raw, conn.msgtype)
            stamp = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
            out.setdefault(conn.topic.split("/")[1], {})[msg.header.frame_id] = (log_time, stamp)
    return out


@pytest.fixture(scope="module")
def team_logs(tmp_path_factory: pytest.TempPathFactory) -> tuple[dict[str, Path], dict[str, int]]:
    return _record_team(tmp_path_factory.mktemp("team"))


def test_unmerged_logs_disagree_by_the_skew(team_logs) -> None:
    paths, truth = team_logs
    with AnyReader([paths["a"]]) as reader:
        times = [t for c, t, _ in reader.messages() if c.topic == "/event"]
    with AnyReader([paths["ref"]]) as reader:
        ref_times = [t for c, t, _ in reader.messages() if c.topic == "/event"]
    assert len(times) == len(ref_times) == len(truth)
    # a's clock is 750 ms behind the reference's (and drifting): unusable side by side.
    assert all(abs((r - a) - 750 * MS) < 5 * MS for a, r in zip(times, ref_times, strict=True))


@pytest.mark.parametrize("stamps", [False, True])
def test_simultaneous_events_line_up_within_1ms_after_merging(team_logs, tmp_path, stamps):
    paths, truth = team_logs
    report = merge([RobotLog(p) for p in paths.values()], tmp_path / "merged", stamps=stamps)
    assert {r.namespace for r in report.robots} == {"ref", "a", "b"}  # named by the estimates
    events = _events(tmp_path / "merged")
    assert set(events) == {"ref", "a", "b"}
    worst_spread = worst_truth = 0
    for event, true_ns in truth.items():
        times = [events[robot][event][0] for robot in events]
        worst_spread = max(worst_spread, max(times) - min(times))
        worst_truth = max(worst_truth, *(abs(t - true_ns) for t in times))
        stamp_times = [events[robot][event][1] for robot in events]
        if stamps:
            assert max(stamp_times) - min(stamp_times) <= 1 * MS, (event, stamp_times)
        else:  # stamps untouched: still each robot's own clock
            assert max(stamp_times) - min(stamp_times) > 600 * MS
    assert worst_spread <= 1 * MS, worst_spread
    assert worst_truth <= 1 * MS, worst_truth
    for r in report.robots:
        assert r.messages > len(truth) and not r.skipped and not r.truncated_files
        if stamps:
            assert r.stamps_moved == len(truth)  # ClockOffset has no Header: not touched
    # The stated uncertainty of the applied offsets covers each event's error, and is
    # larger for b, which is synchronised through a relay.
    by_ns = {r.namespace: r for r in report.robots}
    for robot, path in paths.items():
        local = _events(path)["event"]
        model = by_ns[robot].model
        for event, true_ns in truth.items():
            error = abs(events[robot][event][0] - true_ns)
            assert error <= model.uncertainty_at(local[event][0]), (robot, event, error)
    assert by_ns["b"].max_uncertainty_ns > by_ns["a"].max_uncertainty_ns > 0
    _assert_metadata_matches_mcap(tmp_path / "merged")


def _assert_metadata_matches_mcap(bag: Path) -> None:
    """metadata.yaml says what the MCAP file holds: files, topics, types, counts, times."""
    info = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert (info["version"], info["storage_identifier"]) == (9, "mcap")
    (name,) = info["relative_file_paths"]
    with open(bag / name, "rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None and summary.statistics is not None
    stats = summary.statistics
    listed = {t["topic_metadata"]["name"]: (t["topic_metadata"]["type"], t["message_count"])
              for t in info["topics_with_message_count"]}
    held = {ch.topic: (summary.schemas[ch.schema_id].name, stats.channel_message_counts[cid])
            for cid, ch in summary.channels.items()}
    assert listed == held
    assert info["message_count"] == stats.message_count == sum(n for _, n in held.values())
    assert info["starting_time"]["nanoseconds_since_epoch"] == stats.message_start_time
    assert info["duration"]["nanoseconds"] == stats.message_end_time - stats.message_start_time
    assert info["files"] == [{"path": name, "starting_time": info["starting_time"],
                              "duration": info["duration"],
                              "message_count": info["message_count"]}]


def test_merged_bag_reads_back_with_mcap_and_equals_the_inputs(team_logs, tmp_path):
    paths, _ = team_logs
    out = tmp_path / "merged.mcap"
    report = merge([RobotLog(p) for p in paths.values()], out)
    decoders = DecoderFactory()
    merged: dict[str, list[bytes]] = {}
    with open(out, "rb") as f:
        reader = make_reader(f)
        assert reader.get_header().profile == "ros2"
        last = 0
        for schema, channel, message in reader.iter_messages(log_time_order=False):
            assert message.log_time >= last  # written in team-time order
            last = message.log_time
            assert channel.message_encoding == "cdr" and schema is not None
            assert schema.encoding == "ros2msg"
            decoder = decoders.decoder_for("cdr", schema)
            assert decoder is not None
            decoder(message.data)  # every message decodes by its recorded schema
            merged.setdefault(channel.topic, []).append(message.data)
    assert sum(len(v) for v in merged.values()) == report.messages
    for robot, path in paths.items():
        with AnyReader([path]) as bag:
            originals: dict[str, list[bytes]] = {}
            for conn, _, raw in bag.messages():
                originals.setdefault(conn.topic, []).append(bytes(raw))
        for topic, datas in originals.items():
            assert merged[f"/{robot}{topic}"] == datas  # same bytes, same order


def test_cli_merges_and_reports(team_logs, tmp_path, capsys):
    paths, _ = team_logs
    out = tmp_path / "cli_merged"
    args = ["merge", "-o", str(out), "--stamps",
            *(f"{name}={path}" for name, path in paths.items())]
    assert cli_main(args) == 0
    printed = capsys.readouterr().out
    assert "/b:" in printed and "stamps moved" in printed
    assert set(_events(out)) == {"ref", "a", "b"}
    assert cli_main(args) == 1  # the output exists now: refused, nothing overwritten
    assert "exists" in capsys.readouterr().err
    assert cli_main(["offsets", str(paths["b"])]) == 0
    assert "hops 2 via a" in capsys.readouterr().out


# -- offsets from recordings -----------------------------------------------------------------


def _offset(robot: str, stamp_ns: int, offset_ns: int, *, drift_ppm: float = 0.0,
            valid: bool = True) -> ClockOffset:
    msg = ClockOffset(robot=robot, reference="ref", source="ref", offset_ns=offset_ns,
                      drift_ppm=drift_ppm, uncertainty_ns=1000, hops=1, samples=5, valid=valid)
    msg.stamp = to_msg(stamp_ns)
    return msg


def _log(path: Path, offsets: list[ClockOffset], *, metadata: Sequence[dict[str, str]] = (),
         events: int = 3, chunk_size: int = 1 << 20) -> Path:
    with BagWriter(path, chunk_bytes=chunk_size, min_free_bytes=0) as w:
        for msg in offsets:
            w.write("/team_clock/offset", OFFSET_TYPE, serialize_message(msg),
                    msg.stamp.sec * 1_000_000_000 + msg.stamp.nanosec)
        for k in range(events):
            p = PointStamped()
            p.header.frame_id = f"e{k}"
            w.write("/event", EVENT_TYPE, serialize_message(p), 1_000_000_000 * (k + 1))
        for values in metadata:
            w.add_metadata("team_clock", values)
    return path


def test_model_interpolates_between_estimates_and_extrapolates_with_drift(tmp_path):
    s = 1_000_000_000
    path = _log(tmp_path / "log", [_offset("a", 10 * s, 100_000, drift_ppm=10.0),
                                   _offset("a", 20 * s, 300_000, drift_ppm=10.0)])
    for source in (path, path / "log_0.mcap"):  # bag directory or the file itself
        model = OffsetModel.from_mcap(source)
        assert model.robot == "a" and model.reference == "ref" and len(model.knots) == 2
        assert model.to_reference(10 * s) == 10 * s + 100_000  # exact at the estimates
        assert model.to_reference(20 * s) == 20 * s + 300_000
        # before the first: its drift (10 ppm of 5 s = 50 µs); after the last: the last one's
        assert model.to_reference(5 * s) == 5 * s + 100_000 - 50_000
        assert model.to_reference(30 * s) == 30 * s + 300_000 + 100_000
        mid = model.to_reference(15 * s) - 15 * s  # blended: between the two
        assert 150_000 < mid < 250_000
        steps = [model.to_reference(t) for t in range(10 * s, 20 * s, s // 10)]
        assert all(b > a for a, b in itertools.pairwise(steps))  # monotonic


def test_model_falls_back_to_metadata_in_both_layouts(tmp_path):
    flat = {"robot": "a", "reference": "ref", "stamp.sec": "5", "stamp.nanosec": "0",
            "offset_ns": "-2000", "drift_ppm": "0.0", "uncertainty_ns": "10", "hops": "1",
            "valid": "True"}
    path = _log(tmp_path / "flat", [], metadata=[flat])
    assert OffsetModel.from_mcap(path).to_reference(5_000_000_000) == 5_000_000_000 - 2000
    ours = offset_metadata(_offset("a", 5_000_000_000, 7000))
    path = _log(tmp_path / "ours.mcap", [], metadata=[ours])
    assert OffsetModel.from_mcap(path).to_reference(5_000_000_000) == 5_000_007_000


def test_logs_without_a_usable_estimate_are_refused(tmp_path, capsys):
    none = _log(tmp_path / "none", [])
    invalid = _log(tmp_path / "invalid", [_offset("lone", 10, 0, valid=False)] * 3)
    several = _log(tmp_path / "several", [_offset("a", 10, 5), _offset("b", 10, 7)])
    with pytest.raises(NoEstimateError, match="no /team_clock/offset"):
        OffsetModel.from_mcap(none)
    with pytest.raises(NoEstimateError, match="never had a clock estimate"):
        OffsetModel.from_mcap(invalid)
    with pytest.raises(NoEstimateError, match="say which robot"):
        OffsetModel.from_mcap(several)
    assert OffsetModel.from_mcap(several, robot="b").to_reference(10) == 17
    # Merging, the namespace names the robot when the log recorded a shared domain.
    report = merge([RobotLog(several, namespace="b")], tmp_path / "shared")
    assert report.robots[0].model.robot == "b"
    with pytest.raises(NoEstimateError):
        merge([RobotLog(invalid)], tmp_path / "out")
    assert not (tmp_path / "out").exists()
    # Told explicitly that a log's clock is the reference, the merge goes ahead.
    assert cli_main(["merge", "-o", str(tmp_path / "out2"), "--assume-synced", "r",
                     f"r={none}"]) == 0
    # Also beside robots aligned to a named reference (the claim is not held against it).
    assert cli_main(["merge", "-o", str(tmp_path / "out3"), "--assume-synced", "laptop",
                     f"laptop={none}", f"b={several}"]) == 0
    capsys.readouterr()
    # A name that matches no NAMESPACE=LOG is an error, not silently ignored.
    assert cli_main(["merge", "-o", str(tmp_path / "out4"), "--assume-synced", "typo",
                     f"r={none}"]) == 1
    assert "--assume-synced typo" in capsys.readouterr().err
    assert not (tmp_path / "out4").exists()


def test_damaged_and_foreign_inputs(tmp_path):
    s = 1_000_000_000
    good = _log(tmp_path / "good.mcap", [_offset("a", s, 1000)], events=1000, chunk_size=2048)
    data = good.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: len(data) // 2])  # a recorder killed mid-file
    report = merge([RobotLog(cut)], tmp_path / "m1", compression="none")
    assert report.robots[0].truncated_files == [cut]
    assert 100 < report.messages < 1001  # everything up to the last complete chunk
    with open(good, "rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None
    chunk = sorted(summary.chunk_indexes, key=lambda c: c.chunk_start_offset)[1]
    flipped = bytearray(data)
    # a bit error inside a chunk's records: its CRC (or its compression) no longer matches
    flipped[chunk.chunk_start_offset + chunk.chunk_length // 2] ^= 0xFF
    corrupt = tmp_path / "corrupt.mcap"
    corrupt.write_bytes(bytes(flipped))
    with pytest.raises(LogFormatError):
        merge([RobotLog(corrupt, model=OffsetModel.identity(robot="a"))], tmp_path / "m5")
    assert not (tmp_path / "m5").exists()  # no half-merged output left behind
    foreign = tmp_path / "notes.mcap"
    foreign.write_text("not a log")
    with pytest.raises(LogFormatError):
        merge([RobotLog(foreign, model=OffsetModel.identity())], tmp_path / "m2")
    with pytest.raises(MergeError, match="two logs"):
        merge([RobotLog(good, namespace="x"), RobotLog(good, namespace="x")], tmp_path / "m3")
    with pytest.raises(MergeError, match="not a ROS name"):
        merge([RobotLog(good, namespace="a/b")], tmp_path / "m4")


def test_model_knots_are_sorted_and_uncertainty_grows_away_from_them():
    model = OffsetModel([Knot(2_000, 10, 0.0, 100), Knot(1_000, 10, 0.0, 50)],
                        holdover_ppm=1000.0)
    assert [k.stamp_ns for k in model.knots] == [1_000, 2_000]
    assert model.uncertainty_at(1_000) == 50
    assert model.uncertainty_at(1_000_000) > 100


def test_model_bound_covers_a_blend_of_a_loose_and_a_tight_estimate():
    """The first estimate is 100 µs off (and says so), the second exact: between them the
    blend carries part of the first one's error, and the stated bound must too."""
    s = 1_000_000_000
    model = OffsetModel([Knot(0, 100_000, 0.0, 100_000), Knot(10 * s, 0, 0.0, 1_000)])
    for t in range(0, 10 * s + 1, s // 4):
        assert abs(model.to_reference(t) - t) <= model.uncertainty_at(t), t
    # The largest bound over a span is found without sampling it.
    span = range(-2 * s, 12 * s + 1, s // 1000)
    worst = max(model.uncertainty_at(t) for t in span)
    assert worst <= model.max_uncertainty(span.start, span.stop - 1) <= worst + 1
    # Alike estimates far apart: the bound peaks between them (holdover from both sides).
    apart = OffsetModel([Knot(0, 0, 0.0, 1_000), Knot(100 * s, 0, 0.0, 3_000)])
    inner = range(40 * s, 60 * s + 1, s // 100)
    peak = max(apart.uncertainty_at(t) for t in inner)
    assert peak > apart.uncertainty_at(inner.start) and peak > apart.uncertainty_at(60 * s)
    assert peak <= apart.max_uncertainty(inner.start, inner.stop - 1) <= peak + 1


def test_split_bag_with_renumbered_channels_merges_each_topic_whole(tmp_path):
    """Each file of a split bag numbers its channels afresh: topics are matched by name.

    Also: log and publish times both move by the model (publish time 5 ms earlier here).
    """
    from std_msgs.msg import Int32, String

    bag = tmp_path / "split"
    bag.mkdir()
    s = 1_000_000_000
    order = (("/text", "std_msgs/msg/String"), ("/count", "std_msgs/msg/Int32"))
    for part, topics in enumerate((order, order[::-1])):  # ids swap in the second file
        with BagWriter(bag / f"split_{part}.mcap", min_free_bytes=0) as w:
            for topic, type_name in topics:
                w.add_topic(topic, type_name)
            t = (part + 1) * s
            w.write("/text", "std_msgs/msg/String", serialize_message(String(data=f"t{part}")),
                    t, publish_time_ns=t - 5 * MS)
            w.write("/count", "std_msgs/msg/Int32", serialize_message(Int32(data=part)),
                    t + 1, publish_time_ns=t + 1 - 5 * MS)
    model = OffsetModel.constant(-300 * MS, drift_ppm=50.0, robot="r")
    out = tmp_path / "merged.mcap"
    report = merge([RobotLog(bag, namespace="r", model=model)], out)
    assert report.messages == 4
    got: dict[str, list[tuple[Any, int, int]]] = {}
    with open(out, "rb") as f:
        for schema, channel, message in make_reader(f).iter_messages():
            assert schema is not None
            decoded = DecoderFactory().decoder_for("cdr", schema)(message.data)  # type: ignore[misc]
            got.setdefault(channel.topic, []).append(
                (decoded.data, message.log_time, message.publish_time))
    assert [d for d, _, _ in got["/r/text"]] == ["t0", "t1"]
    assert [d for d, _, _ in got["/r/count"]] == [0, 1]
    for part, (_, log_time, publish_time) in enumerate(got["/r/text"]):
        t = (part + 1) * s
        assert log_time == model.to_reference(t)
        assert publish_time == model.to_reference(t - 5 * MS)
    # One topic with another type in a later file: refused, no output left behind.
    clash = tmp_path / "clash"
    clash.mkdir()
    for part, (msg_type, msg) in enumerate((("String", String(data="a")),
                                            ("Int32", Int32(data=1)))):
        with BagWriter(clash / f"clash_{part}.mcap", min_free_bytes=0) as w:
            w.write("/x", f"std_msgs/msg/{msg_type}", serialize_message(msg), s)
    with pytest.raises(MergeError, match="two types"):
        merge([RobotLog(clash, namespace="r", model=model)], tmp_path / "clash_merged")
    assert not (tmp_path / "clash_merged").exists()



def test_a_reference_log_without_estimates_is_held_against_the_others_reference(tmp_path):
    """The reference itself measures nothing (a simulated world whose time the robots
    synchronise to need not run a ClockSync): named as the reference, its log merges
    beside logs aligned to it, and refuses logs aligned to another robot."""
    world = _log(tmp_path / "world", [])
    aligned = _log(tmp_path / "b", [_offset("b", 10, 5)])  # reference "ref"
    report = merge([RobotLog(world, namespace="ref",
                             model=OffsetModel.identity(robot="ref", reference="ref")),
                    RobotLog(aligned, namespace="b")], tmp_path / "ok")
    assert [r.model.reference for r in report.robots] == ["ref", "ref"]
    with pytest.raises(MergeError, match=r"different reference robots \['ref', 'world'\]"):
        merge([RobotLog(world, namespace="world",
                        model=OffsetModel.identity(robot="world", reference="world")),
               RobotLog(aligned, namespace="b")], tmp_path / "refused")
    assert not (tmp_path / "refused").exists()
