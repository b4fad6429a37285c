"""The recorder view's model against a real Recorder in another process, through the Hub.

The robot is ``tests/_gui_recorder_robot.py``: one efficient_comm container with a talker
(``chatter`` and ``counter``, 50 Hz each) and robot_recorder's Recorder, in its own DDS
domain. Bags are read back with robot_recorder's public reader.
"""

from __future__ import annotations

import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from itertools import pairwise
from pathlib import Path

import pytest
from rclpy.serialization import deserialize_message
from std_msgs.msg import String

from debug_gui import Hub, RobotId
from debug_gui.errors import AccessDenied, InvalidInput, RobotUnavailable
from debug_gui.models.recorder import RecorderModel, RecorderTeam, parse_entries
from debug_gui.security import AccessPolicy
from efficient_comm.testing import isolated_domain_id, ros_env
from robot_recorder import read_messages

from ._gui import RobotProcess, fake_robot, started, wait_for

RECORDER_ROBOT = Path(__file__).with_name("_gui_recorder_robot.py")
PLAIN_ROBOT = Path(__file__).with_name("_gui_plain_robot.py")


@contextmanager
def recorder_robot(tmp_path: Path, *, domain_id: int, namespace: str) -> Iterator[RobotProcess]:
    """The light robot with a recorder (bags under ``tmp_path/bags``) until the test ends."""
    log = tmp_path / f"recorder_robot_{domain_id}{namespace.replace('/', '_')}.log"
    cmd = [sys.executable, str(RECORDER_ROBOT), "--namespace", namespace,
           "--bag-dir", str(tmp_path / "bags")]
    with started(cmd, env=ros_env(domain_id), log=log) as proc:
        yield RobotProcess(proc=proc, log=log, domain_id=domain_id, namespace=namespace)


def _topics(bag: Path) -> dict[str, int]:
    counts: dict[str, int] = {}
    for message in read_messages(bag):
        counts[message.topic] = counts.get(message.topic, 0) + 1
    return counts


def test_status_start_split_snapshot_selection_and_stop(tmp_path: Path) -> None:
    domain = isolated_domain_id()
    policy = AccessPolicy.for_server()
    with Hub(domains=[domain]) as hub, \
            recorder_robot(tmp_path, domain_id=domain, namespace="/rec") as proc:
        alive = [proc]
        robot = RobotId(domain, "/rec")
        wait_for(lambda: robot in hub.robots(), what="the robot", alive=alive)
        model = RecorderModel(hub, robot, policy=policy, token=policy.token)
        wait_for(lambda: model.discover() == ["/rec/recorder"], what="its recorder",
                 alive=alive)
        model.activate()
        # Status observed: idle, with free disk, listing the selected topic.
        idle = wait_for(lambda: (s := model.states()) and s[0].statuses >= 1
                        and s[0].topics and s[0], what="a status", alive=alive)
        assert idle.state == "idle" and idle.free_bytes > 0, idle
        assert [t.name for t in idle.topics] == ["/rec/chatter"]
        assert model.selection() and model.selection()[0].name == "/rec/chatter"

        bag = tmp_path / "bags" / "first"
        started_ = model.start(bag=str(bag))
        assert started_.success and started_.bag == str(bag), started_
        assert "recording into" in started_.text
        assert bag.is_dir()
        growing = wait_for(lambda: (s := model.states()[0]).state == "recording"
                           and s.bytes > 0 and s, what="bytes recorded", alive=alive)
        wait_for(lambda: model.states()[0].bytes > growing.bytes, what="bytes growing",
                 alive=alive)

        # Topic selection: a second topic, one with a throttle; applied by the recorder.
        applied = model.set_topics(["chatter", "counter every_nth=5"])
        assert applied.success, applied
        assert [e.name for e in model.selection()] == ["chatter", "counter"]
        wait_for(lambda: {t.name: t.messages for t in model.states()[0].topics}
                 .get("/rec/counter", 0) > 0, what="counter recorded", alive=alive)
        # Malformed entries never leave the GUI; robot_recorder's parser says why.
        with pytest.raises(InvalidInput, match="max_rate_hz"):
            model.set_topics(["counter max_rate_hz=-1"])
        with pytest.raises(InvalidInput, match="unknown option 'rate'"):
            model.set_topics(["counter rate=5"])
        with pytest.raises(InvalidInput, match="invalid value"):
            model.set_topics(["counter every_nth=2.5"])
        # A selection the recorder itself refuses comes back with its reason.
        refused = model.set_topics(["chatter", "/rec/chatter"])
        assert not refused.success and "selected twice" in refused.message, refused
        assert "set_topics refused: " in refused.text

        split = model.split()
        assert split.success and split.file.endswith(".mcap"), split
        wait_for(lambda: len(list(bag.glob("*.mcap"))) == 2, what="a second file", alive=alive)
        snapshot = model.snapshot(bag=str(tmp_path / "bags" / "event"))
        assert snapshot.success and snapshot.messages > 0, snapshot
        assert sum(_topics(tmp_path / "bags" / "event").values()) == snapshot.messages

        stopped = model.stop()
        assert stopped.success and stopped.bag == str(bag), stopped
        wait_for(lambda: model.states()[0].state == "idle", what="idle again", alive=alive)
        final = model.states()[0]
        counts = _topics(bag)
        assert counts.get("/rec/chatter", 0) > 0 and counts.get("/rec/counter", 0) > 0, counts
        assert sum(counts.values()) == final.messages, (counts, final)
        # The throttle was applied: the recorder got every 5th counter sample.
        ticks = [int(deserialize_message(m.data, String).data.split()[1])
                 for m in read_messages(bag, topics=["/rec/counter"])]
        assert len(ticks) >= 2 and {b - a for a, b in pairwise(ticks)} == {5}, ticks
        assert final.drops == 0

        # A refusal reaches the caller with the recorder's message.
        again = model.start(bag=str(bag))
        assert not again.success and "exists" in again.message, again
        # Stopping an idle recorder is no error, and says so.
        assert model.stop().text.endswith("was not recording")

        model.deactivate()
        heard = model.states()[0].statuses
        # Inactive, it hears nothing more while another view's model goes on hearing the
        # recorder's status (published every 0.2 s).
        watcher = RecorderModel(hub, robot, policy=policy, token=None)
        watcher.activate()
        wait_for(lambda: watcher.states() and watcher.states()[0].statuses >= 3,
                 what="statuses meanwhile", alive=alive)
        watcher.deactivate()
        assert model.states()[0].statuses == heard


def test_a_throttled_topic_of_a_plain_publisher_is_recorded_at_the_asked_rate(
        tmp_path: Path) -> None:
    """Issue 18, 4c: a plain rclpy publisher in another process ignores throttle requests;
    the recorder drops the surplus itself (it used to record nothing, "applied")."""
    domain = isolated_domain_id()
    policy = AccessPolicy.for_server()
    plain_log = tmp_path / "plain.log"
    with Hub(domains=[domain]) as hub, \
            recorder_robot(tmp_path, domain_id=domain, namespace="/sub") as proc, \
            started([sys.executable, PLAIN_ROBOT, "--namespace", "/plainpub"],
                    env=ros_env(domain), log=plain_log) as plain_proc:
        plain = RobotProcess(proc=plain_proc, log=plain_log, domain_id=domain,
                             namespace="/plainpub")
        alive = [proc, plain]
        robot = RobotId(domain, "/sub")
        model = RecorderModel(hub, robot, policy=policy, token=policy.token)
        wait_for(lambda: model.discover() == ["/sub/recorder"], what="its recorder",
                 alive=alive)
        model.activate()
        wait_for(lambda: "ready" in plain.output(), what="the plain publisher", alive=alive)
        applied = model.set_topics(["/plainpub/chatter max_rate_hz=4"])  # of 10 Hz
        assert applied.success, applied
        bag = tmp_path / "bags" / "plain"
        assert model.start(bag=str(bag)).success
        wait_for(lambda: {t.name: t.messages for t in model.states()[0].topics}
                 .get("/plainpub/chatter", 0) >= 6, what="the plain topic recorded",
                 alive=alive)
        assert model.stop().success
        model.deactivate()
    stamps = [m.log_time_ns for m in read_messages(bag, topics=["/plainpub/chatter"])]
    assert len(stamps) >= 6, stamps
    # At most the asked rate: n samples span at least n - 1 periods of 0.25 s, less the
    # rate limiter's tolerance (never more than one period). All of the plain 10 Hz
    # would span about half of that.
    span_s = (stamps[-1] - stamps[0]) / 1e9
    assert span_s >= (len(stamps) - 2) * 0.25, (len(stamps), span_s)


def test_writes_without_the_token_are_refused_and_change_nothing(tmp_path: Path) -> None:
    """Security (issue 12, point 7): the model checks the token itself, on the server."""
    domain = isolated_domain_id()
    policy = AccessPolicy.for_server()
    with Hub(domains=[domain]) as hub, \
            recorder_robot(tmp_path, domain_id=domain, namespace="/sec") as proc:
        robot = RobotId(domain, "/sec")
        wait_for(lambda: robot in hub.robots(), what="the robot", alive=[proc])
        for token in (None, "wrong-token-123"):
            _refused_without_the_token(
                RecorderModel(hub, robot, policy=policy, token=token), tmp_path, proc)
        assert not (tmp_path / "nope").exists()
        assert not (tmp_path / "bags").exists() or not any((tmp_path / "bags").iterdir())


def _refused_without_the_token(model: RecorderModel, tmp_path: Path,
                               proc: RobotProcess) -> None:
    wait_for(model.discover, what="its recorder", alive=[proc])
    model.activate()
    writes: list[Callable[[], object]] = [
        lambda: model.start(bag=str(tmp_path / "nope")), model.stop, model.split,
        model.snapshot, lambda: model.set_topics([])]
    for write in writes:
        with pytest.raises(AccessDenied, match="needs the server's token"):
            write()
    # "start all robots" reports the refusal per robot instead of raising.
    (result,) = RecorderTeam([model]).for_all("start")
    assert not result.success and "needs the server's token" in result.message
    # Reading still works, and the recorder never started.
    state = wait_for(lambda: (s := model.states()) and s[0].statuses and s[0],
                     what="a status", alive=[proc])
    assert state.state == "idle" and state.bag == ""
    model.deactivate()


def test_a_robot_without_a_recorder_is_said_so(tmp_path: Path) -> None:
    domain = isolated_domain_id()
    policy = AccessPolicy.for_server()
    with Hub(domains=[domain]) as hub, \
            fake_robot(tmp_path, domain_id=domain, namespace="/plain") as proc:
        robot = RobotId(domain, "/plain")
        wait_for(lambda: robot in hub.robots(), what="the robot", alive=[proc])
        # Its graph is known (its service is seen), and no recorder is among it.
        wait_for(lambda: "/plain/fake_robot/slow" in hub.services(robot),
                 what="its services", alive=[proc])
        model = RecorderModel(hub, robot, policy=policy, token=policy.token)
        assert model.discover() == []
        with pytest.raises(RobotUnavailable, match=rf"plain @ domain {domain} has no recorder"):
            model.start()
        (result,) = RecorderTeam([model]).for_all("start")
        assert not result.success and "has no recorder" in result.text


def test_selection_entries_are_parsed_by_robot_recorder() -> None:
    parsed = parse_entries(["/a", "", "b std_msgs/msg/String max_rate_hz=5 every_nth=2"])
    assert [(s.name, s.type, s.max_rate_hz, s.every_nth) for s in parsed] == [
        ("/a", "", 0.0, 1), ("b", "std_msgs/msg/String", 5.0, 2)]
    with pytest.raises(InvalidInput, match="two types given"):
        parse_entries(["a std_msgs/msg/String std_msgs/msg/Int32"])
    with pytest.raises(InvalidInput, match="entry is text"):
        parse_entries([3])  # type: ignore[list-item]
