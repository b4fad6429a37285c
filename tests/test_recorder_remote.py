"""The recorder over DDS: controlled by services from another participant, recording topics
of its own process (by reference) and of other participants, reporting on its status topic.
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
from efficient_comm.testing import isolated_domain_id, unique_topic
from robot_recorder import Recorder
from robot_recorder.testing import read_rosbags
from robot_recorder.writer import IDLE, RECORDING
from robot_recorder_interfaces.msg import RecorderStatus, TopicSelection
from robot_recorder_interfaces.srv import SetTopics, Snapshot, Split, Start, Stop

from ._ros import Peer, child, executable, peer

RELIABLE = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)


class Talker:
    def __init__(self, node: NodeHandle, topic: str) -> None:
        self.pub = node.create_publisher(String, topic, qos=RELIABLE)

    def say(self, text: str) -> None:
        self.pub.publish(String(data=text))


def _call(p: Peer, container: Container, srv_type: Any, name: str, **fields: Any) -> Any:
    client = p.node.create_client(srv_type, name)
    assert p.wait_for(client.service_is_ready, also=container.spin_once), name
    future = client.call_async(srv_type.Request(**fields))
    assert p.wait_for(future.done, also=container.spin_once), name
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
