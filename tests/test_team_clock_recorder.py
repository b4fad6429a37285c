"""The recorder (robot_recorder) stores ClockSync's estimates; OffsetModel reads them back.

Robot ``a``'s container clock is a's local clock: its recorder stamps log times with it and
its ClockSync reads it. The reference robot's clock runs 250 ms behind and 50 ppm slow.
Events recorded by a's recorder, mapped through the model read from that very bag, must
land on the reference clock's readings at the same instants.
"""

from __future__ import annotations

from functools import partial
from pathlib import Path

import pytest
from geometry_msgs.msg import PointStamped
from rosbags.highlevel import AnyReader

from efficient_comm.testing import TestHandle, test_container
from robot_recorder import Recorder
from team_clock.bag import LogReader
from team_clock.clocks import SkewedClock
from team_clock.errors import NoEstimateError
from team_clock.merge import RobotLog, merge
from team_clock.model import METADATA_NAME, OffsetModel
from team_clock.sync import OFFSET_TOPIC, PING_TOPIC, PONG_TOPIC, ClockSync
from team_clock.testing import SimDelay, SimNetwork, sim_remappings

MS = 1_000_000


def test_recorded_estimates_align_the_recorders_own_log_times(tmp_path: Path) -> None:
    container = test_container()
    clock = container.executor.clock
    clock.set_ns(1_700_000_000_000_000_000)  # type: ignore[attr-defined]
    ref_clock = SkewedClock(clock, offset_ns=-250 * MS, drift_ppm=-50.0,
                            epoch_ns=clock.now_ns())
    container.add(partial(SimNetwork, links=[("ref", "a")], loss=0.1, seed=2,
                          delay=SimDelay(min_s=0.001, jitter_s=0.002)), name="sim_net")
    container.add(partial(ClockSync, local_clock=ref_clock), name="clock_sync",
                  namespace="/ref", remappings=sim_remappings("ref"),
                  parameters={"reference": "ref", "period_s": 0.5})
    a_remaps = {k: v for k, v in sim_remappings("a").items() if k in (PING_TOPIC, PONG_TOPIC)}
    container.add(ClockSync, name="clock_sync", namespace="/a", remappings=a_remaps,
                  parameters={"reference": "ref", "period_s": 0.5})
    source = TestHandle("camera", container=container)
    pub = source.create_publisher(PointStamped, "/event")
    recorder = container.add(partial(Recorder, topics=["/event"], output_dir=tmp_path,
                                     autostart=True), name="recorder", namespace="/a")
    truth: dict[str, int] = {}
    container.advance(10.0)
    for k in range(40):
        container.advance(0.5)
        msg = PointStamped()
        msg.header.frame_id = f"e{k}"
        pub.publish(msg)
        truth[f"e{k}"] = ref_clock.now_ns()
    container.advance(1.0)
    recorder.close()
    (bag,) = [p for p in tmp_path.iterdir() if p.is_dir()]

    model = OffsetModel.from_mcap(bag)
    assert model.robot == "a" and model.reference == "ref" and len(model.knots) > 10
    with AnyReader([bag]) as reader:
        conns = [c for c in reader.connections if c.topic == "/event"]
        worst = 0
        seen = 0
        for conn, log_time, raw in reader.messages(connections=conns):
            event = reader.deserialize(raw, conn.msgtype).header.frame_id  # type: ignore[attr-defined]
            worst = max(worst, abs(model.to_reference(log_time) - truth[event]))
            seen += 1
    assert seen == len(truth)
    assert worst <= 1 * MS, worst
    # The recorder also keeps the estimate it held in the file's metadata: enough alone.
    meta = [values for name, values in LogReader(bag).metadata() if name == METADATA_NAME]
    assert meta, "the recorder stored no team_clock metadata"
    alone = OffsetModel.from_metadata(meta)
    t = next(iter(truth.values()))
    assert abs(alone.to_reference(t) - model.to_reference(t)) < 5 * MS
    assert OFFSET_TOPIC in LogReader(bag).topics()
    # And the recorder's bag merges: its events land on the reference clock.
    report = merge([RobotLog(bag)], tmp_path / "merged", stamps=True)
    assert report.robots[0].namespace == "a" and not report.robots[0].skipped
    with AnyReader([tmp_path / "merged"]) as reader:
        conns = [c for c in reader.connections if c.topic == "/a/event"]
        merged = {reader.deserialize(raw, c.msgtype).header.frame_id: t  # type: ignore[attr-defined]
                  for c, t, raw in reader.messages(connections=conns)}
    assert merged.keys() == truth.keys()
    assert all(abs(merged[e] - truth[e]) <= 1 * MS for e in truth)


def test_the_clock_robot_parameter_names_whose_estimates_are_recorded(tmp_path: Path) -> None:
    """Two robots' estimates reach the recorder; the parameter says which is this log's."""
    from team_clock_interfaces.msg import ClockOffset

    container = test_container()
    talker = TestHandle("team", container=container)
    pub = talker.create_publisher(ClockOffset, OFFSET_TOPIC)
    recorder = Recorder(TestHandle("recorder", container=container,
                                   parameters={"clock_robot": "b"}),
                        topics=[], output_dir=tmp_path)
    bag = recorder.start(tmp_path / "bag").result(10)
    for robot, offset in (("a", 1), ("b", 2), ("c", 3), ("b", 4)):
        pub.publish(ClockOffset(robot=robot, reference="a", offset_ns=offset, valid=True))
    recorder.close()
    model = OffsetModel.from_mcap(bag)
    assert model.robot == "b" and [k.offset_ns for k in model.knots] == [2, 4]
    for other in ("a", "c"):  # not recorded at all
        with pytest.raises(NoEstimateError, match="the log has those of"):
            OffsetModel.from_mcap(bag, robot=other)
    meta = [values for name, values in LogReader(bag).metadata() if name == METADATA_NAME]
    assert [m["robot"] for m in meta] == ["b"]
