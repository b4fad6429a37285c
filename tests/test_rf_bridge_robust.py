"""rf_bridge when things go wrong: master restart, killed peers, hostile or stuck peers."""

from __future__ import annotations

import json
import os
import select
import signal
import socket
import struct
import subprocess
import threading
import time
from collections.abc import Iterator
from typing import Any
from xmlrpc.server import SimpleXMLRPCServer

import pytest
from sensor_msgs.msg import Image
from std_msgs.msg import String

from efficient_comm.testing import unique_topic
from rf_bridge.adapters.ros1.tcpros import encode_header, read_header
from rf_bridge.adapters.ros1.xmlrpc import call
from rf_bridge.testing import SYSTEM_PYTHON, Ros1System, wait_for
from rf_bridge.testing import CapturedLogs as Logs

from .test_rf_bridge_ros1 import (
    NODE,
    bridge,
    close_containers,
    connected_listener,
    out_and_in,
    read_line,
    spin_until,
)


@pytest.fixture
def ros1() -> Iterator[Ros1System]:
    with Ros1System() as system:
        yield system


@pytest.fixture
def logs(capfd: pytest.CaptureFixture[str]) -> Logs:
    return Logs(capfd)


@pytest.fixture(autouse=True)
def _close_containers() -> Iterator[None]:
    yield from close_containers()


def drops(b: Any, topic: str, direction: str) -> dict[str, int]:
    snap = next(s for s in b.stats() if s.topic == topic and s.direction == direction)
    return dict(snap.drops)


def test_master_restart_reregisters_without_restarting_the_bridge(
    ros1: Ros1System, logs: Logs
) -> None:
    out, inn, node, b = out_and_in(ros1)
    adapter: Any = b.adapters["ros1"]
    try:
        ros1.stop_master()
        ros1.start_master()
        assert wait_for(lambda: adapter.registrations >= 2, 20), "not registered again"
        assert logs.wait("registering")
        listener = connected_listener(ros1, adapter, out, "std_msgs/String")
        node.inject(out, String(data="after restart"))
        assert json.loads(read_line(listener))["data"] == "after restart"
        ros1.python(NODE, "talk", inn, "std_msgs/String", "m.String(data='t%d' % i)", "3", log="t")
        assert spin_until(node, lambda: len(node.published(inn)) >= 3)
        assert [m.data for m in node.published(inn)] == ["t0", "t1", "t2"]
    finally:
        b.close()


BAG = r"""
import sys
import genpy, rosbag
from std_msgs.msg import String
with rosbag.Bag(sys.argv[1], "w") as bag:
    for i in range(20):
        bag.write(sys.argv[2], String(data="roscpp %d" % i), genpy.Time(1, i * 50_000_000))
"""


def test_publishers_running_across_a_master_restart_keep_flowing(
    ros1: Ros1System, logs: Logs
) -> None:
    """rospy (``rostopic pub``) and roscpp (``rosbag play``) publishers never register with
    a restarted master; the bridge registers again and keeps its links to them, and lets a
    link go only when its publisher is gone."""
    from_rospy, from_roscpp = unique_topic("rospy"), unique_topic("roscpp")
    node, b = bridge(
        ros1,
        [
            {"ros2": t, "type": "std_msgs/msg/String", "direction": "from_peer"}
            for t in (from_rospy, from_roscpp)
        ],
    )
    adapter: Any = b.adapters["ros1"]
    bag = ros1.workdir / "loop.bag"
    subprocess.run([SYSTEM_PYTHON, "-c", BAG, str(bag), from_roscpp], env=ros1.env,
                   check=True, timeout=60)
    try:
        rospy_pub = ros1.spawn(
            ["rostopic", "pub", "-r", "50", from_rospy, "std_msgs/String", "data: rospy"],
            log="pub",
        )
        ros1.spawn(["rosbag", "play", "-l", "-q", str(bag)], log="play")

        def counts() -> tuple[int, int]:
            return len(node.published(from_rospy)), len(node.published(from_roscpp))

        assert spin_until(node, lambda: min(counts()) >= 5, 30), counts()
        ros1.stop_master()
        ros1.start_master()
        assert wait_for(lambda: adapter.registrations >= 2, 20), "not registered again"
        assert logs.wait("registering")
        before = counts()
        assert spin_until(
            node, lambda: all(n >= m + 20 for n, m in zip(counts(), before, strict=True)), 30
        ), (before, counts(), ros1.log_text("play"))
        assert node.published(from_roscpp)[-1].data.startswith("roscpp ")
        assert drops(b, from_rospy, "from_ros1") == {}
        Ros1System.kill(rospy_pub)  # gone, and the new master never knew it
        assert wait_for(lambda: not adapter._subs[from_rospy].links, 20)
        assert logs.wait("is gone; link closed")
        assert len(adapter._subs[from_roscpp].links) == 1
    finally:
        b.close()


def test_killed_subscriber_undelivered_counted_then_new_one_served(ros1: Ros1System) -> None:
    topic = unique_topic("out")
    node, b = bridge(ros1, [{"ros2": topic, "type": "std_msgs/msg/String"}])
    adapter: Any = b.adapters["ros1"]
    try:
        first = connected_listener(ros1, adapter, topic, "std_msgs/String", log="l1")
        node.inject(topic, String(data="seen"))
        assert json.loads(read_line(first))["data"] == "seen"
        Ros1System.kill(first)
        for i in range(7):
            node.inject(topic, String(data=f"lost {i}"))
        assert sum(drops(b, topic, "to_ros1").values()) == 7
        second = connected_listener(ros1, adapter, topic, "std_msgs/String", log="l2")
        node.inject(topic, String(data="again"))
        assert json.loads(read_line(second))["data"] == "again"
    finally:
        b.close()


def test_killed_publisher_replaced_by_a_new_one(ros1: Ros1System) -> None:
    topic = unique_topic("in")
    node, b = bridge(
        ros1, [{"ros2": topic, "type": "std_msgs/msg/String", "direction": "from_peer"}]
    )
    try:
        first = ros1.python(
            NODE, "talk", topic, "std_msgs/String", "m.String(data='a%d' % i)", "2", log="t1"
        )
        assert spin_until(node, lambda: len(node.published(topic)) >= 2)
        Ros1System.kill(first)
        ros1.python(
            NODE, "talk", topic, "std_msgs/String", "m.String(data='b%d' % i)", "2", log="t2"
        )
        assert spin_until(node, lambda: len(node.published(topic)) >= 4)
        assert [m.data for m in node.published(topic)] == ["a0", "a1", "b0", "b1"]
    finally:
        b.close()


def tcpros_port(adapter: Any, topic: str) -> int:
    value = call(adapter.uri, "requestTopic", "/test", topic, [["TCPROS"]])
    return int(value[2])


def test_bad_tcpros_headers_dropped_the_rest_keeps_serving(ros1: Ros1System, logs: Logs) -> None:
    topic = unique_topic("out")
    node, b = bridge(ros1, [{"ros2": topic, "type": "std_msgs/msg/String"}])
    adapter: Any = b.adapters["ros1"]
    try:
        listener = ros1.python(NODE, "listen", topic, "std_msgs/String", log="l")
        assert read_line(listener) == "ready"
        port = tcpros_port(adapter, topic)
        bad = [
            struct.pack("<I", 0xFFFFFFF0),  # absurd header length
            struct.pack("<I", 12) + struct.pack("<I", 8) + b"no_equal",  # field without '='
            struct.pack("<I", 20) + struct.pack("<I", 100) + b"topic=x",  # field overruns
        ]
        for payload in bad:
            with socket.create_connection(("127.0.0.1", port), timeout=5) as s:
                s.sendall(payload)
                s.shutdown(socket.SHUT_WR)
                assert s.recv(100) == b""  # closed by the bridge without a reply
        for fields, expect in [
            ({"topic": "/nobody", "md5sum": "*", "callerid": "/x"}, "does not publish"),
            ({"topic": topic, "md5sum": "0" * 32, "callerid": "/x"}, "md5sum mismatch"),
        ]:
            with socket.create_connection(("127.0.0.1", port), timeout=5) as s:
                s.sendall(encode_header(fields))
                assert expect in read_header(s)["error"]
        assert logs.wait("malformed TCPROS header") and logs.wait("rejecting TCPROS subscriber")
        assert wait_for(lambda: bool(adapter._pubs[topic].connections), 20)
        node.inject(topic, String(data="still serving"))
        assert json.loads(read_line(listener))["data"] == "still serving"
    finally:
        b.close()


def test_subscriber_that_stops_reading_gets_data_again_when_it_reads(
    ros1: Ros1System, logs: Logs
) -> None:
    """A rospy listener stopped (SIGSTOP) while the bridge publishes: its queue keeps the
    newest messages and the older ones are dropped and counted, as a rospy publisher does;
    when it reads again (SIGCONT) it gets data on the same connection. Another listener
    misses nothing meanwhile."""
    topic = unique_topic("image")
    node, b = bridge(ros1, [{"ros2": topic, "type": "sensor_msgs/msg/Image"}],
                     ros1={"queue_size": 5})
    adapter: Any = b.adapters["ros1"]
    try:
        healthy = connected_listener(ros1, adapter, topic, "sensor_msgs/Image", log="ok")
        slow = ros1.python(NODE, "listen", topic, "sensor_msgs/Image", log="slow")
        assert read_line(slow) == "ready"
        assert wait_for(lambda: len(adapter._pubs[topic].connections) == 2, 20)
        connections = list(adapter._pubs[topic].connections)
        os.killpg(slow.pid, signal.SIGSTOP)
        img = Image(height=512, width=1024, encoding="mono8", step=1024)
        img.data = bytes(512 * 1024)
        for _ in range(40):  # at the pace of the healthy listener, which gets everything
            node.inject(topic, img)
            assert json.loads(read_line(healthy))["height"] == 512
        assert wait_for(lambda: drops(b, topic, "to_ros1").get("queue_full", 0) > 0, 20)
        assert logs.wait("is not keeping up")
        os.killpg(slow.pid, signal.SIGCONT)
        node.inject(topic, Image(height=1, width=1, encoding="mono8", step=1, data=b"\x07"))
        seen: list[int] = []
        while not seen or seen[-1] != 1:
            seen.append(json.loads(read_line(slow, 30))["height"])
        assert set(seen[:-1]) <= {512} and len(seen) < 41  # what it missed was dropped
        assert json.loads(read_line(healthy))["height"] == 1
        assert list(adapter._pubs[topic].connections) == connections  # never cut off
        assert set(drops(b, topic, "to_ros1")) == {"queue_full"}
        assert logs.wait("caught up")
    finally:
        b.close()


class FakePublisher:
    """A ROS 1 publisher that sends whatever the test wants after a header of its choice."""

    def __init__(self, ros1: Ros1System, topic: str, header: dict[str, str], data: bytes) -> None:
        self.tcp = socket.create_server(("127.0.0.1", 0))
        port = self.tcp.getsockname()[1]
        self.rpc = SimpleXMLRPCServer(("127.0.0.1", 0), logRequests=False)
        self.rpc.register_function(
            lambda caller, t, protocols: [1, "", ["TCPROS", "127.0.0.1", port]], "requestTopic"
        )
        self.uri = f"http://127.0.0.1:{self.rpc.server_address[1]}/"
        self.conns: list[socket.socket] = []
        threading.Thread(target=self.rpc.serve_forever, daemon=True).start()

        def serve() -> None:
            while True:
                try:
                    conn, _ = self.tcp.accept()
                except OSError:
                    return
                self.conns.append(conn)
                try:
                    read_header(conn)
                    conn.sendall(encode_header(header) + data)
                except OSError:
                    pass

        threading.Thread(target=serve, daemon=True).start()
        call(
            ros1.master_uri,
            "registerPublisher",
            "/fake" + topic.replace("/", "_"),
            topic,
            header.get("type", "*"),
            self.uri,
        )

    def close(self) -> None:
        self.rpc.shutdown()
        self.rpc.server_close()
        self.tcp.close()
        for c in self.conns:
            c.close()


STRING_DEF = {
    "type": "std_msgs/String",
    "md5sum": "992ce8a1687cec8c8bd883ec73ca41d1",
    "message_definition": "string data\n",
    "callerid": "/fake",
}


@pytest.mark.parametrize(
    ("header", "data", "reason", "log"),
    [
        (STRING_DEF, struct.pack("<II", 8, 1000) + b"abcd", "malformed", "truncated message"),
        (STRING_DEF, struct.pack("<I", 5_000_000), "oversize", "exceeds the limit"),
        (
            {"type": "nope/Nope", "md5sum": "1" * 32, "callerid": "/fake"},
            b"",
            "unknown_type",
            "cannot bridge 'nope/Nope'",
        ),
    ],
    ids=["malformed_frame", "oversize", "unknown_type"],
)
def test_bad_publisher_dropped_the_rest_keeps_serving(
    ros1: Ros1System, logs: Logs, header: dict[str, str], data: bytes, reason: str, log: str
) -> None:
    bad, good = unique_topic("bad"), unique_topic("good")
    node, b = bridge(
        ros1,
        [
            {"ros2": bad, "type": "std_msgs/msg/String", "direction": "from_peer"},
            {"ros2": good, "type": "std_msgs/msg/String", "direction": "from_peer"},
        ],
        ros1={"max_message_bytes": 1 << 20},
    )
    fake = FakePublisher(ros1, bad, header, data)
    try:
        assert wait_for(lambda: drops(b, bad, "from_ros1").get(reason, 0) >= 1, 20), drops(
            b, bad, "from_ros1"
        )
        assert logs.wait(log), logs.text()
        ros1.python(
            NODE, "talk", good, "std_msgs/String", "m.String(data='ok%d' % i)", "3", log="t"
        )
        assert spin_until(node, lambda: len(node.published(good)) >= 3)
        assert node.published(bad) == []
    finally:
        fake.close()
        b.close()


def test_listeners_bind_loopback_by_default(ros1: Ros1System) -> None:
    topic = unique_topic("out")
    _, b = bridge(ros1, [{"ros2": topic, "type": "std_msgs/msg/String"}])
    adapter: Any = b.adapters["ros1"]
    try:
        assert adapter._listener.getsockname()[0] == "127.0.0.1"
        assert adapter._slave._server.server_address[0] == "127.0.0.1"
    finally:
        b.close()


def test_oversize_outgoing_message_counted_and_not_sent(ros1: Ros1System, logs: Logs) -> None:
    topic = unique_topic("image")
    node, b = bridge(ros1, [{"ros2": topic, "type": "sensor_msgs/msg/Image"}],
                     ros1={"max_message_bytes": 4096})
    adapter: Any = b.adapters["ros1"]
    try:
        listener = connected_listener(ros1, adapter, topic, "sensor_msgs/Image")
        node.inject(topic, Image(height=100, width=100, encoding="mono8", step=100,
                                 data=bytes(10_000)))
        node.inject(topic, Image(height=1, width=2, encoding="mono8", step=2, data=b"\x01\x02"))
        assert json.loads(read_line(listener))["width"] == 2  # the big one never went out
        assert drops(b, topic, "to_ros1") == {"oversize": 1}
        assert logs.wait("max_message_bytes")
    finally:
        b.close()


def test_idle_connections_hold_handshakes_for_a_bounded_time(ros1: Ros1System, logs: Logs) -> None:
    """Connections that never send a header take a handshake slot each until it times
    out; beyond the limit they are refused at once, and subscribers are served again
    as soon as slots free up."""
    from rf_bridge.adapters.ros1.adapter import MAX_HANDSHAKES

    topic = unique_topic("out")
    node, b = bridge(ros1, [{"ros2": topic, "type": "std_msgs/msg/String"}])
    adapter: Any = b.adapters["ros1"]
    port = tcpros_port(adapter, topic)
    idle = [socket.create_connection(("127.0.0.1", port), timeout=5) for _ in range(MAX_HANDSHAKES)]
    try:
        with socket.create_connection(("127.0.0.1", port), timeout=5) as extra:
            assert extra.recv(100) == b""  # refused while the idle ones hold every slot
        assert logs.wait("handshakes already in progress")
        for s in idle:
            s.close()
        listener = connected_listener(ros1, adapter, topic, "std_msgs/String")
        node.inject(topic, String(data="served"))
        assert json.loads(read_line(listener))["data"] == "served"
    finally:
        for s in idle:
            s.close()
        b.close()


def test_a_header_trickled_a_byte_at_a_time_is_cut_off(
    ros1: Ros1System, logs: Logs, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A byte every 200 ms resets every per-read timeout; the handshake's total deadline
    closes the connection anyway."""
    from rf_bridge.adapters.ros1 import adapter as ros1_adapter

    monkeypatch.setattr(ros1_adapter, "HANDSHAKE_TIMEOUT_S", 1.0)
    topic = unique_topic("out")
    _, b = bridge(ros1, [{"ros2": topic, "type": "std_msgs/msg/String"}])
    header = encode_header({"topic": topic, "md5sum": "*", "callerid": "/slow"})
    try:
        start = time.monotonic()
        with socket.create_connection(("127.0.0.1", tcpros_port(b.adapters["ros1"], topic)),
                                      timeout=5) as slow:
            closed = False
            for byte in header:
                try:
                    slow.sendall(bytes((byte,)))
                except OSError:
                    closed = True
                    break
                readable, _, _ = select.select([slow], [], [], 0.2)
                if readable:
                    closed = slow.recv(100) == b""
                    break
        assert closed and 0.9 < time.monotonic() - start < 3.0
        assert logs.wait("no header within 1 s")
    finally:
        b.close()


def test_close_ends_every_thread_and_stops_listening(ros1: Ros1System) -> None:
    out, inn, node, b = out_and_in(ros1)
    adapter: Any = b.adapters["ros1"]
    listener = ros1.python(NODE, "listen", out, "std_msgs/String", log="l")
    assert read_line(listener) == "ready"
    ros1.python(NODE, "talk", inn, "std_msgs/String", "m.String(data='t%d' % i)", "1", log="t")
    assert wait_for(lambda: bool(adapter._pubs[out].connections), 20)
    assert spin_until(node, lambda: len(node.published(inn)) >= 1)
    port = tcpros_port(adapter, out)
    threads = [
        *adapter._threads,
        *(c.thread for c in adapter._pubs[out].connections),
        *(link.thread for link in adapter._subs[inn].links.values()),
    ]
    assert len(threads) >= 4 and all(t.is_alive() for t in threads)
    b.close()
    assert [t.name for t in threads if t.is_alive()] == []
    with pytest.raises(ConnectionRefusedError):
        socket.create_connection(("127.0.0.1", port), timeout=5).close()


def test_publisher_update_naming_too_many_publishers_is_cut(ros1: Ros1System, logs: Logs) -> None:
    from rf_bridge.adapters.ros1.adapter import MAX_PUBLISHERS_PER_TOPIC

    topic = unique_topic("in")
    _, b = bridge(
        ros1, [{"ros2": topic, "type": "std_msgs/msg/String", "direction": "from_peer"}]
    )
    adapter: Any = b.adapters["ros1"]
    try:
        uris = [f"http://127.0.0.1:1/{i}" for i in range(MAX_PUBLISHERS_PER_TOPIC + 40)]
        call(adapter.uri, "publisherUpdate", "/master", topic, uris)
        assert len(adapter._subs[topic].links) == MAX_PUBLISHERS_PER_TOPIC
        assert logs.wait("publishers named")
        call(adapter.uri, "publisherUpdate", "/master", topic, [])
        assert adapter._subs[topic].links == {}
    finally:
        b.close()
