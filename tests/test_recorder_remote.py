"""The recorder over DDS: controlled by services from another participant, recording topics
of its own process (by reference) and of other participants, reporting on its status topic.
The recorder and player commands as a user types them, with a plain rclpy peer.
"""

from __future__ import annotations

import os
import signal
import subprocess
from pathlib import Path
from typing import Any

import yaml
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import String

from efficient_comm import Container
from efficient_comm.handle import NodeHandle
from efficient_comm.testing import (
    TestHandle,
    isolated_domain_id,
    ros_env,
    test_container,
    unique_topic,
)
from robot_recorder import Recorder
from robot_recorder.testing import read_rosbags
from robot_recorder.writer import IDLE, RECORDING
from robot_recorder_interfaces.msg import RecorderStatus, TopicSelection
from robot_recorder_interfaces.srv import (
    PlayerControl,
    SetTopics,
    Snapshot,
    Split,
    Start,
    Stop,
)

from ._ros import Peer, child, executable, peer

RELIABLE = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)


class Talker:
    def __init__(self, node: NodeHandle, topic: str) -> None:
        self.pub = node.create_publisher(String, topic, qos=RELIABLE)

    def say(self, text: str) -> None:
        self.pub.publish(String(data=text))


def _call(p: Peer, container: Container | None, srv_type: Any, name: str,
          **fields: Any) -> Any:
    """Call service ``name`` from peer ``p`` (spinning ``container`` too, if in-process)."""
    also = container.spin_once if container is not None else None
    client = p.node.create_client(srv_type, name)
    assert p.wait_for(client.service_is_ready, timeout_s=30, also=also), name
    future = client.call_async(srv_type.Request(**fields))
    assert p.wait_for(future.done, timeout_s=30, also=also), name
    p.node.destroy_client(client)
    return future.result()


def test_remote_control_local_and_remote_topics_and_status(tmp_path: Path) -> None:
    local, remote = unique_topic("local"), unique_topic("remote")
    domain = isolated_domain_id()
    with Container("robot", domain_id=domain, serve=False) as container, \
            peer(domain, "laptop") as laptop:
        talker = container.add(lambda n: Talker(n, local), name="talker")
        recorder = container.add(
            lambda n: Recorder(n, output_dir=tmp_path, topics=[]), name="recorder",
            parameters={"status_period_s": 0.2, "snapshot_bytes": 1 << 20,
                        "min_free_bytes": 0})
        statuses: list[Any] = []
        laptop.node.create_subscription(RecorderStatus, "/recorder/status", statuses.append, 10)
        remote_pub = laptop.node.create_publisher(String, remote, RELIABLE)

        reply = _call(laptop, container, SetTopics, "/recorder/set_topics", topics=[
            TopicSelection(name=local), TopicSelection(name=remote)])
        assert reply.success, reply.message
        # The remote topic's type is learnt from the graph once its publisher is seen.
        assert laptop.wait_for(lambda: set(recorder.topic_states()) == {local, remote},
                               also=container.spin_once)
        assert laptop.wait_for(lambda: remote_pub.get_subscription_count() == 1,
                               also=container.spin_once)
        reply = _call(laptop, container, Start, "/recorder/start", bag=str(tmp_path / "bag"))
        assert reply.success and reply.bag == str(tmp_path / "bag"), reply.message
        for i in range(10):
            talker.say(f"local {i}")
            remote_pub.publish(String(data=f"remote {i}"))
        states = recorder.topic_states()
        assert laptop.wait_for(lambda: states[remote].messages == 10
                               and states[local].messages == 10, also=container.spin_once)
        assert _call(laptop, container, Split, "/recorder/split").success
        talker.say("local after split")
        assert laptop.wait_for(
            lambda: any(s.state == RECORDING and s.messages == 21 for s in statuses),
            also=container.spin_once)
        reply = _call(laptop, container, Snapshot, "/recorder/snapshot",
                      bag=str(tmp_path / "event"))
        assert reply.success and reply.messages == 21, reply.message
        reply = _call(laptop, container, Stop, "/recorder/stop")
        assert reply.success and reply.bag == str(tmp_path / "bag")
        assert laptop.wait_for(lambda: statuses[-1].state == IDLE, also=container.spin_once)
        # Bad requests are refused with a reason, and the recorder keeps going.
        reply = _call(laptop, container, Start, "/recorder/start", bag=str(tmp_path / "bag"))
        assert not reply.success and "exists" in reply.message
        reply = _call(laptop, container, SetTopics, "/recorder/set_topics", topics=[
            TopicSelection(name=local, every_nth=1, max_rate_hz=-1.0)])
        assert not reply.success and "max_rate_hz" in reply.message

    final = statuses[-1]
    assert final.free_bytes > 0 and final.drops == 0
    assert {t.name: t.messages for t in final.topics} == {local: 11, remote: 10}
    got = read_rosbags(tmp_path / "bag")
    assert sorted(m.data for t, m in got if t == local) == sorted(
        [f"local {i}" for i in range(10)] + ["local after split"])
    assert [m.data for t, m in got if t == remote] == [f"remote {i}" for i in range(10)]
    assert len(list((tmp_path / "bag").glob("*.mcap"))) == 2
    assert len(read_rosbags(tmp_path / "event")) == 21


def test_standalone_recorder_process_records_another_process_and_closes_on_sigint(
        tmp_path: Path) -> None:
    topic = unique_topic("chatter")
    domain = isolated_domain_id()
    args: list[str | Path] = [executable("robot_recorder", "recorder"), "--ros-args",
            "-p", f"topics:=['{topic}']", "-p", f"output_dir:={tmp_path}",
            "-p", "status_period_s:=0.2", "-p", "min_free_bytes:=0"]
    with peer(domain, "talker") as talker, \
            child(args, domain_id=domain, log=tmp_path / "recorder.log") as proc:
        statuses: list[Any] = []
        talker.node.create_subscription(RecorderStatus, "/recorder/status", statuses.append, 10)
        pub = talker.node.create_publisher(String, topic, RELIABLE)
        assert talker.wait_for(lambda: pub.get_subscription_count() == 1, timeout_s=30), (
            tmp_path / "recorder.log").read_text()
        for i in range(20):
            pub.publish(String(data=f"m{i}"))
        assert talker.wait_for(lambda: bool(statuses) and statuses[-1].messages == 20,
                               timeout_s=30), statuses[-1:]
        bag = Path(statuses[-1].bag)
        os.killpg(proc.pid, signal.SIGINT)
        assert proc.wait(20) == 0
    assert (bag / "metadata.yaml").exists()  # closed properly on Ctrl-C
    assert [m.data for _, m in read_rosbags(bag)] == [f"m{i}" for i in range(20)]
    # The user is told where: the directory to play back.
    assert f"recording to {bag}" in (tmp_path / "recorder.log").read_text()


def _recorder_command(tmp_path: Path, *params: str) -> list[str | Path]:
    """The recorder as a user types it, with ``-p`` parameters."""
    args: list[str | Path] = [executable("robot_recorder", "recorder"), "--ros-args",
                              "-p", f"output_dir:={tmp_path / 'out'}",
                              "-p", "status_period_s:=0.2", "-p", "min_free_bytes:=0"]
    for param in params:
        args += ["-p", param]
    return args


def test_set_topics_with_an_unknown_type_is_refused_and_changes_nothing(tmp_path: Path) -> None:
    topic, other = unique_topic("kept"), unique_topic("other")
    domain = isolated_domain_id()
    with peer(domain, "laptop") as laptop, \
            child(_recorder_command(tmp_path, f"topics:=['{topic}']"), domain_id=domain,
                  log=tmp_path / "recorder.log"):
        statuses: list[Any] = []
        laptop.node.create_subscription(RecorderStatus, "/recorder/status", statuses.append, 10)
        pub = laptop.node.create_publisher(String, topic, RELIABLE)
        assert laptop.wait_for(lambda: pub.get_subscription_count() == 1, timeout_s=30), (
            tmp_path / "recorder.log").read_text()
        pub.publish(String(data="before"))
        for selection in ([TopicSelection(name=other, type="nosuch_msgs/msg/Thing")],
                          [TopicSelection(name=topic),
                           TopicSelection(name=other, type="std_msgs/msg/NoSuchType")]):
            reply = _call(laptop, None, SetTopics, "/recorder/set_topics", topics=selection)
            assert not reply.success, selection
            assert selection[-1].type.split("/")[0] in reply.message, reply.message
        pub.publish(String(data="after"))
        assert laptop.wait_for(lambda: bool(statuses) and statuses[-1].messages == 2,
                               timeout_s=30), statuses[-1:]
        assert [t.name for t in statuses[-1].topics] == [topic]
        assert statuses[-1].error == ""
        bag = Path(statuses[-1].bag)
    assert [m.data for _, m in read_rosbags(bag)] == ["before", "after"]


def test_recorder_command_help_autostart_and_unknown_options(tmp_path: Path) -> None:
    recorder = executable("robot_recorder", "recorder")
    # --help: help, and nothing recorded (not even a directory made).
    result = subprocess.run([str(recorder), "--help", "--ros-args", "-p",
                             f"output_dir:={tmp_path / 'help'}"], capture_output=True,
                            text=True, timeout=60, cwd=tmp_path, env=ros_env(isolated_domain_id()))
    assert result.returncode == 0, result.stderr
    assert "autostart" in result.stdout and "usage: recorder" in result.stdout
    assert list(tmp_path.iterdir()) == []
    # A misspelt option in a topic entry: named, in one line.
    result = subprocess.run([str(recorder), "--ros-args", "-p",
                             "topics:=['/chatter max_rte_hz=5']", "-p",
                             f"output_dir:={tmp_path / 'typo'}"], capture_output=True,
                            text=True, timeout=60, env=ros_env(isolated_domain_id()))
    assert result.returncode == 1
    assert "unknown option 'max_rte_hz'" in result.stderr, result.stderr
    assert result.stderr.count("\n") == 1 and "Traceback" not in result.stderr
    # autostart:=false: idle until told to start.
    topic = unique_topic("chatter")
    domain = isolated_domain_id()
    with peer(domain, "laptop") as laptop, \
            child(_recorder_command(tmp_path, f"topics:=['{topic}']", "autostart:=false"),
                  domain_id=domain, log=tmp_path / "recorder.log"):
        statuses: list[Any] = []
        laptop.node.create_subscription(RecorderStatus, "/recorder/status", statuses.append, 10)
        assert laptop.wait_for(lambda: len(statuses) >= 3, timeout_s=30), (
            tmp_path / "recorder.log").read_text()
        assert all(s.state == IDLE and not s.bag for s in statuses)
        assert not (tmp_path / "out").exists()
        reply = _call(laptop, None, Start, "/recorder/start")
        assert reply.success and reply.bag.startswith(str(tmp_path / "out")), reply.message
        assert laptop.wait_for(lambda: statuses[-1].state == RECORDING, timeout_s=30)


def _small_bag(tmp_path: Path, topic: str, n: int) -> Path:
    """A bag of ``n`` Strings on ``topic``, 10 ms apart, recorded in-process."""
    container = test_container()
    pub = TestHandle("talker", container=container).create_publisher(String, topic)
    recorder = Recorder(TestHandle("recorder", container=container), topics=[topic],
                        output_dir=tmp_path)
    bag = recorder.start(tmp_path / "bag").result(10)
    for i in range(n):
        pub.publish(String(data=f"m{i}"))
        container.advance(0.01)
    recorder.close()
    return bag


def _append(texts: list[str], msg: String) -> None:
    texts.append(msg.data)


def test_player_command_waits_for_subscribers_and_exits_at_the_end(tmp_path: Path) -> None:
    topic = unique_topic("replay")
    bag = _small_bag(tmp_path, topic, 20)
    player = executable("robot_recorder", "player")
    sent = [f"m{i}" for i in range(20)]
    domain = isolated_domain_id()
    with peer(domain, "viewer") as viewer, \
            child([player, bag], domain_id=domain, log=tmp_path / "player.log") as proc:
        # The player is up and answers (that takes longer than the bag lasts), but has not
        # published yet: nobody subscribes. A subscriber joining now gets everything.
        reply = _call(viewer, None, PlayerControl, "/player/control",
                      command=PlayerControl.Request.SET_RATE, rate=1.0)
        assert reply.success and reply.position_ns >= 0, reply  # -1: played to nobody
        got: list[str] = []
        viewer.node.create_subscription(String, topic, lambda m: _append(got, m), RELIABLE)
        assert viewer.wait_for(lambda: len(got) == 20, timeout_s=30), str(got)
        assert got == sent
        # At the end of the bag the command exits by itself.
        assert viewer.wait_for(lambda: proc.poll() is not None, timeout_s=30)
        assert proc.returncode == 0, (tmp_path / "player.log").read_text()
    # --loop: plays on until stopped.
    with peer(domain, "viewer") as viewer, \
            child([player, bag, "--loop"], domain_id=domain,
                  log=tmp_path / "loop.log") as proc:
        got = []
        viewer.node.create_subscription(String, topic, lambda m: _append(got, m), RELIABLE)
        assert viewer.wait_for(lambda: len(got) > 45, timeout_s=30), got
        assert proc.poll() is None
        os.killpg(proc.pid, signal.SIGINT)
        assert proc.wait(20) == 0
    assert got[:40] == sent + sent
    # Nobody listening and a wait limit: it says so, plays and ends.
    result = subprocess.run([str(player), str(bag), "--wait-timeout", "0.2"],
                            capture_output=True, text=True, timeout=60,
                            env=ros_env(isolated_domain_id()))
    assert result.returncode == 0, result.stderr
    assert "nobody subscribes" in result.stderr + result.stdout


def test_a_latched_message_published_before_the_recorder_started_is_recorded(
        tmp_path: Path) -> None:
    topic = unique_topic("latched")
    domain = isolated_domain_id()
    latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL)
    args: list[str | Path] = [executable("robot_recorder", "recorder"), "--ros-args",
            "-p", f"topics:=['{topic}']", "-p", f"output_dir:={tmp_path}",
            "-p", "status_period_s:=0.2", "-p", "min_free_bytes:=0", "-p", "autostart:=true"]
    with peer(domain, "map_server") as talker:
        pub = talker.node.create_publisher(String, topic, latched)
        pub.publish(String(data="the map"))  # before any recorder exists
        with child(args, domain_id=domain, log=tmp_path / "recorder.log") as proc:
            statuses: list[Any] = []
            talker.node.create_subscription(RecorderStatus, "/recorder/status",
                                            statuses.append, 10)
            assert talker.wait_for(lambda: bool(statuses) and statuses[-1].messages == 1,
                                   timeout_s=60), (tmp_path / "recorder.log").read_text()
            bag = Path(statuses[-1].bag)
            os.killpg(proc.pid, signal.SIGINT)
            assert proc.wait(20) == 0
    assert [m.data for _, m in read_rosbags(bag)] == ["the map"]
    info = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    (entry,) = [t["topic_metadata"] for t in info["topics_with_message_count"]
                if t["topic_metadata"]["name"] == topic]
    assert [q["durability"] for q in entry["offered_qos_profiles"]] == ["transient_local"]


def test_player_program_runs(tmp_path: Path) -> None:
    result = subprocess.run([str(executable("robot_recorder", "player")), "--help"],
                            capture_output=True, text=True, timeout=60)
    assert result.returncode == 0 and "--stamps" in result.stdout


def test_a_late_joiner_gets_the_latched_message_from_a_player_process(tmp_path: Path) -> None:
    from rclpy.serialization import serialize_message

    from robot_recorder_interfaces.srv import PlayerControl
    from rosbag2_layout import BagWriter, qos_dict

    topic = unique_topic("map")
    domain = isolated_domain_id()
    latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL)
    bag = tmp_path / "bag"
    with BagWriter(bag, min_free_bytes=0) as writer:
        writer.add_topic(topic, "std_msgs/msg/String", qos_profiles=[qos_dict(latched)])
        writer.write(topic, "std_msgs/msg/String",
                     bytes(serialize_message(String(data="the map"))), 1_000)
    config = tmp_path / "player.yaml"
    config.write_text(yaml.safe_dump({"components": [{
        "class": "robot_recorder.player:Player", "name": "player",
        "parameters": {"/player": {"ros__parameters": {"bag": str(bag)}}}}]}))
    args: list[str | Path] = [executable("efficient_comm", "container"), "--config", config,
                              "--name", "replay"]
    with peer(domain, "late") as late, \
            child(args, domain_id=domain, log=tmp_path / "container.log"):
        client = late.node.create_client(PlayerControl, "/player/control")
        assert late.wait_for(client.service_is_ready, timeout_s=60), (
            tmp_path / "container.log").read_text()

        def position() -> int:
            future = client.call_async(PlayerControl.Request(
                command=PlayerControl.Request.SET_RATE, rate=1.0))
            assert late.wait_for(future.done, timeout_s=30)
            return int(future.result().position_ns)

        assert late.wait_for(lambda: position() == -1, timeout_s=30)  # played: at the end
        got: list[str] = []

        def on_map(msg: Any) -> None:
            got.append(msg.data)

        late.node.create_subscription(String, topic, on_map, latched)
        assert late.wait_for(lambda: got == ["the map"], timeout_s=30), got
