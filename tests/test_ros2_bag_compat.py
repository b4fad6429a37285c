"""``ros2 bag`` as ros2cli's rosbag2 verbs behave: sqlite3 bags (rosbag2's default before
Iron), one-line errors, ``play --clock/--start-paused/-d`` and ``record -e/--exclude``."""

from __future__ import annotations

import re
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import rclpy
import yaml
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore
from rosgraph_msgs.msg import Clock
from std_msgs.msg import String

from efficient_comm.testing import isolated_domain_id, unique_topic
from robot_recorder import read_messages

from ._cli import cli_env, ros2, ros2_path, running
from ._ros import Peer, peer

PEER = Path(__file__).with_name("_cli_peer.py")
STRING = "std_msgs/msg/String"
T0 = 1_700_000_000_000_000_000


def _sqlite_bag(path: Path, topic: str, texts: list[str], *, start_ns: int = T0) -> None:
    """A bag written by rosbags' writer with its sqlite3 storage, as rosbag2 writes them."""
    store = get_typestore(Stores.ROS2_JAZZY)
    string = store.types[STRING]
    with Writer(path, version=9, storage_plugin=StoragePlugin.SQLITE3) as writer:
        connection = writer.add_connection(topic, STRING, typestore=store)
        for i, text in enumerate(texts):
            writer.write(connection, start_ns + i * 10_000_000,
                         store.serialize_cdr(string(data=text), STRING))


def _two_file_sqlite_bag(tmp_path: Path, topic: str) -> Path:
    """One bag of two .db3 files (rosbag2 splits so), metadata.yaml listing both."""
    first, second, bag = tmp_path / "a", tmp_path / "b", tmp_path / "split"
    _sqlite_bag(first, topic, ["m0", "m1", "m2"])
    _sqlite_bag(second, topic, ["m3", "m4"], start_ns=T0 + 30_000_000)
    bag.mkdir()
    shutil.copy(first / "a.db3", bag / "split_0.db3")
    shutil.copy(second / "b.db3", bag / "split_1.db3")
    meta = yaml.safe_load((first / "metadata.yaml").read_text())
    info = meta["rosbag2_bagfile_information"]
    info["relative_file_paths"] = ["split_0.db3", "split_1.db3"]
    info["message_count"] = 5
    info["topics_with_message_count"][0]["message_count"] = 5
    info["duration"] = {"nanoseconds": 70_000_000}
    info["files"] = []
    (bag / "metadata.yaml").write_text(yaml.safe_dump(meta))
    return bag


RESUME = ("service", "call", "/rosbag2_player/control",
          "robot_recorder_interfaces/srv/PlayerControl", "{command: 1}")


@contextmanager
def _listener(topic: str, domain_id: int, msg_type: Any = String) -> Iterator[
        tuple[Peer, Any, list[Any]]]:
    """A plain rclpy subscriber (reliable, deep enough for a whole bag) and what it got."""
    got: list[Any] = []
    with peer(domain_id, "listener") as listener:
        sub = listener.node.create_subscription(msg_type, topic, got.append, 100)
        yield listener, sub, got


def _matched(listener: Peer, sub: Any) -> None:
    """Until the listener's subscription has matched the player's publisher (as rosbag2's
    own play tests do before resuming: a reader that has only been *seen* in the graph may
    not have matched yet, and a short bag is over before it has)."""
    assert listener.wait_for(lambda: sub.get_publisher_count() > 0, timeout_s=60), \
        "the player's publisher never matched"


def test_sqlite3_bags_info_and_play(tmp_path: Path) -> None:
    domain_id = isolated_domain_id()
    topic = unique_topic("sq")
    bag = _two_file_sqlite_bag(tmp_path, topic)
    info = ros2("bag", "info", str(bag), domain_id=domain_id)
    assert info.returncode == 0, info.stderr
    assert "Files:             split_0.db3\n                   split_1.db3\n" in info.stdout
    assert "Storage id:        sqlite3\n" in info.stdout, info.stdout
    assert (f"Messages:          5\nTopic information: Topic: {topic} | Type: {STRING} | "
            "Count: 5 |") in info.stdout, info.stdout
    one = ros2("bag", "info", str(tmp_path / "a" / "a.db3"), domain_id=domain_id)
    assert one.returncode == 0 and "Messages:          3\n" in one.stdout, one.stdout + one.stderr
    replay = unique_topic("replay")
    with _listener(replay, domain_id) as (listener, sub, got), \
         running([ros2_path(), "bag", "play", str(bag), "--start-paused", "--remap",
                  f"{topic}:={replay}"], domain_id=domain_id, log=tmp_path / "play.log") as play:
        _matched(listener, sub)
        resumed = ros2(*RESUME, domain_id=domain_id)
        assert resumed.returncode == 0, resumed.stderr
        assert listener.wait_for(lambda: len(got) == 5, timeout_s=30), got
        play.proc.wait(30)
        assert play.proc.returncode == 0, play.text()
    assert [m.data for m in got] == ["m0", "m1", "m2", "m3", "m4"]


def test_a_bag_that_cannot_be_played_is_one_line_naming_it(tmp_path: Path) -> None:
    domain_id = isolated_domain_id()
    garbage = tmp_path / "garbage.db3"
    garbage.write_bytes(b"not a database")
    for bag, reason in [(garbage, "is not an SQLite database"),
                        (tmp_path / "missing", "no such bag")]:
        result = ros2("bag", "play", str(bag), domain_id=domain_id)
        assert result.returncode == 1
        (line,) = result.stderr.splitlines()
        assert line.startswith(f"error: Cannot play '{bag}': ") and reason in line, line
        assert "<locals>" not in line and "PlaybackError" not in line, line


def test_play_waits_for_acknowledgements_as_asked(tmp_path: Path) -> None:
    domain_id = isolated_domain_id()
    _sqlite_bag(tmp_path / "bag", unique_topic("ack"), ["m0"])
    bad = ros2("bag", "play", str(tmp_path / "bag"), "--wait-for-all-acked", "-2",
               domain_id=domain_id)
    assert bad.returncode == 1 and "--wait-for-all-acked must be >= -1" in bad.stderr, bad
    # Nobody subscribes: there is nothing to wait for, even without a limit.
    played = ros2("bag", "play", str(tmp_path / "bag"), "--wait-for-all-acked", "0",
                  domain_id=domain_id)
    assert played.returncode == 0 and not played.stderr, played


def test_play_clock_start_paused_and_delay_are_honoured(tmp_path: Path) -> None:
    domain_id = isolated_domain_id()
    topic = unique_topic("clk")
    _sqlite_bag(tmp_path / "bag", topic, [f"m{i}" for i in range(5)])
    # --clock: /clock carries the bag's time, from the start, paused or not.
    with _listener("/clock", domain_id, Clock) as (listener, _, clocks), \
         running([ros2_path(), "bag", "play", str(tmp_path / "bag"), "--clock", "50",
                  "--start-paused"], domain_id=domain_id, log=tmp_path / "clock.log") as play:
        assert listener.wait_for(lambda: bool(clocks), timeout_s=60), play.text()
        assert clocks[0].clock.sec == T0 // 1_000_000_000
        assert ros2(*RESUME, domain_id=domain_id).returncode == 0
        play.proc.wait(30)
        assert play.proc.returncode == 0, play.text()
    # --start-paused: nothing is played until resumed; the player waits.
    replay = unique_topic("paused")
    with _listener(replay, domain_id) as (listener, sub, got), \
         running([ros2_path(), "bag", "play", str(tmp_path / "bag"), "--start-paused",
                  "--remap", f"{topic}:={replay}"], domain_id=domain_id,
                 log=tmp_path / "play.log") as play:
        # The call waits for the player's service; STEP answers whether it is paused.
        stepped = ros2("service", "call", "/rosbag2_player/control",
                       "robot_recorder_interfaces/srv/PlayerControl", "{command: 3}",
                       domain_id=domain_id)
        assert "success=True" in stepped.stdout and "paused=True" in stepped.stdout, \
            stepped.stdout + stepped.stderr
        _matched(listener, sub)
        assert play.proc.poll() is None
        resumed = ros2(*RESUME, domain_id=domain_id)
        assert resumed.returncode == 0, resumed.stderr
        assert listener.wait_for(lambda: bool(got) and got[-1].data == "m4", timeout_s=30), got
        play.proc.wait(30)
        assert play.proc.returncode == 0, play.text()
    # -d: plays after the delay (each loop, as rosbag2), until stopped.
    with _listener(replay, domain_id) as (listener, _, got), \
         running([ros2_path(), "bag", "play", str(tmp_path / "bag"), "-d", "0.5", "--loop",
                  "--remap", f"{topic}:={replay}"], domain_id=domain_id,
                 log=tmp_path / "delay.log") as play:
        assert listener.wait_for(lambda: [m.data for m in got[-5:]] == [
            f"m{i}" for i in range(5)], timeout_s=60), got
        assert play.stop(signal.SIGINT) == 0, play.text()


def test_record_regex_and_exclude(tmp_path: Path) -> None:
    domain_id = isolated_domain_id()
    keep, drop = unique_topic("keep"), unique_topic("drop")
    with running([sys.executable, str(PEER), keep], domain_id=domain_id,
                 log=tmp_path / "peer1.log") as peer1, \
         running([sys.executable, str(PEER), drop], domain_id=domain_id,
                 log=tmp_path / "peer2.log") as peer2:
        peer1.wait_for(lambda t: "ready" in t)
        peer2.wait_for(lambda t: "ready" in t)
        pattern = f"{re.escape(keep)}|{re.escape(drop)}"  # both, and not the others
        with running([ros2_path(), "bag", "record", "-o", "out", "-e", pattern,
                      "--exclude", re.escape(drop)], domain_id=domain_id,
                     log=tmp_path / "record.log", cwd=tmp_path) as rec:
            rec.wait_for(lambda t: "Recording to" in t)
            bag = tmp_path / "out"
            rec.wait_for(lambda t: any(p.stat().st_size > 3000 for p in bag.glob("*.mcap")),
                         timeout=60)
            assert rec.stop(signal.SIGINT) == 0, rec.text()
    info = ros2("bag", "info", str(bag), domain_id=domain_id).stdout
    assert f"Topic: {keep} |" in info, info
    assert f"Topic: {drop} |" not in info, info


def _offered_type_hash(topic: str, domain_id: int) -> str:
    """The type hash the topic's publisher announces in the graph (rclpy's own)."""
    context = Context()
    rclpy.init(context=context, domain_id=domain_id)
    try:
        node = Node("hash_probe", context=context)
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(node)
        deadline = time.monotonic() + 30
        while not (infos := node.get_publishers_info_by_topic(topic)):
            assert time.monotonic() < deadline, f"no publisher of {topic} discovered"
            executor.spin_once(timeout_sec=0.1)  # discovery is handled while it waits
        return str(infos[0].topic_type_hash)
    finally:
        context.try_shutdown()


def test_record_says_recording_when_it_records_with_type_hashes_and_no_root_stats(
        tmp_path: Path) -> None:
    domain_id = isolated_domain_id()
    topic = unique_topic("rec")
    with running([sys.executable, str(PEER), topic], domain_id=domain_id,
                 log=tmp_path / "peer.log") as peer:
        peer.wait_for(lambda t: "ready" in t)
        expected_hash = _offered_type_hash(topic, domain_id)
        with running([ros2_path(), "bag", "record", "-o", "out", topic], domain_id=domain_id,
                     log=tmp_path / "record.log", cwd=tmp_path) as rec:
            text = rec.wait_for(lambda t: "Recording to 'out'" in t)
            said_ns = time.time_ns()  # the line was printed at most a poll (50 ms) before
            assert f"Subscribed to topic '{topic}'" in text, text
            listed = ros2("topic", "list", domain_id=domain_id)
            assert listed.returncode == 0, listed.stderr
            assert "/efficient_comm/stats" not in listed.stdout, listed.stdout
            bag = tmp_path / "out"
            rec.wait_for(lambda t: any(p.stat().st_size > 3000 for p in bag.glob("*.mcap")),
                         timeout=60)
            assert rec.stop(signal.SIGINT) == 0, rec.text()
    first_ns = next(iter(read_messages(bag))).log_time_ns
    # The peer publishes every 50 ms: recording from the line on means a message within a
    # few periods (rosbag2 says so once subscribed; ours said it seconds before).
    assert first_ns - said_ns < 1_000_000_000, (first_ns - said_ns) / 1e9
    meta = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    (entry,) = meta["topics_with_message_count"]
    assert expected_hash.startswith("RIHS01_")
    assert entry["topic_metadata"]["type_description_hash"] == expected_hash


BURST_PEER = Path(__file__).with_name("_burst_peer.py")


def test_messages_dds_loses_are_counted_and_said_at_the_end(tmp_path: Path) -> None:
    """A reliable publisher of depth 1 sending a burst: DDS drops what the recorder has not
    acknowledged yet. Every message is either in the bag or counted as lost."""
    domain_id = isolated_domain_id()
    topic, count = unique_topic("burst"), 2000
    peer = subprocess.Popen([sys.executable, str(BURST_PEER), topic, str(count)],
                            env=cli_env(domain_id), stdin=subprocess.PIPE,
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                            start_new_session=True)
    assert peer.stdin is not None and peer.stdout is not None
    try:
        with running([ros2_path(), "bag", "record", "-o", "out", topic], domain_id=domain_id,
                     log=tmp_path / "record.log", cwd=tmp_path) as rec, \
             running([ros2_path(), "topic", "echo", "/rosbag2_recorder/status",
                      "robot_recorder_interfaces/msg/RecorderStatus"], domain_id=domain_id,
                     log=tmp_path / "status.log") as status:
            rec.wait_for(lambda t: "Recording to 'out'" in t)
            assert peer.stdout.readline().strip() == "ready"
            peer.stdin.write("go\n")
            peer.stdin.flush()
            assert peer.stdout.readline().strip() == f"published {count}"

            def accounted(text: str) -> bool:  # recorded + reported lost, in one status
                for block in text.split("---"):
                    written = re.search(r"^messages: (\d+)$", block, re.MULTILINE)
                    dropped = re.search(r"^drops: (\d+)$", block, re.MULTILINE)
                    if written and dropped and int(written[1]) + int(dropped[1]) == count:
                        return True
                return False

            status.wait_for(accounted, timeout=60)
            assert rec.stop(signal.SIGINT) == 0, rec.text()
            said = rec.text()
    finally:
        peer.stdin.close()
        peer.wait(30)
        peer.stdout.close()
    recorded = sum(1 for _ in read_messages(tmp_path / "out"))
    match = re.search(rf"^Messages of {re.escape(topic)} missing from the bag: (\d+) lost by "
                      r"DDS before they reached the recorder$", said, re.MULTILINE)
    assert match, said
    assert int(match[1]) > 0 and recorded + int(match[1]) == count, (recorded, match[1])
