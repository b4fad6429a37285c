"""rf_bridge against a real ROS 1 system: Debian's rosmaster, rospy, rostopic and rosbag.

The bridge runs in this process on a TestHandle in a container with DDS (an isolated
domain), so it logs through rclpy's real loggers, whose console output the tests read; ROS 1
programs run on the system Python in their own sessions, against a master on a free port.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import subprocess
import time
from collections.abc import Iterator
from typing import Any

import pytest
from geometry_msgs.msg import PoseStamped
from sensor_msgs.msg import Image
from std_msgs.msg import String

from efficient_comm.testing import TestHandle, unique_topic
from rf_bridge import BridgeNode, parse_config
from rf_bridge.testing import CapturedLogs as Logs
from rf_bridge.testing import LineReader, Ros1System, rclpy_test_handle, wait_for

# A rospy node for the tests: "listen" prints each message as a JSON line; "talk" publishes
# eval(expr) for i in range(count) once a subscriber is connected, then waits.
NODE = r"""
import hashlib, importlib, json, sys, time
import rospy
mode, topic, type_name = sys.argv[1:4]
definition = sys.argv[6] if len(sys.argv) > 6 else ""
pkg, name = type_name.split("/")
if definition:
    from genpy.dynamic import generate_dynamic
    cls = generate_dynamic(type_name, definition)[type_name]
    module = None
else:
    module = importlib.import_module(pkg + ".msg")
    cls = getattr(module, name)

def plain(v):
    if isinstance(v, bytes):
        return {"len": len(v), "sha1": hashlib.sha1(v).hexdigest()}
    if hasattr(v, "__slots__") and hasattr(v, "_slot_types"):
        return {k: plain(getattr(v, k)) for k in v.__slots__}
    if hasattr(v, "secs") and hasattr(v, "nsecs"):
        return [v.secs, v.nsecs]
    if isinstance(v, (list, tuple)):
        return [plain(x) for x in v]
    return v

rospy.init_node("rf_test_" + mode, anonymous=True, disable_signals=True)
if mode == "listen":
    rospy.Subscriber(topic, cls, lambda m: print(json.dumps(plain(m)), flush=True))
    print("ready", flush=True)
    while True:
        time.sleep(1)
else:
    expr, count = sys.argv[4], int(sys.argv[5])
    pub = rospy.Publisher(topic, cls, queue_size=1000)
    while pub.get_num_connections() == 0:  # the handshake is done: what follows is delivered
        time.sleep(0.01)
    print("ready", flush=True)
    for i in range(count):
        pub.publish(eval(expr, {"i": i, "cls": cls, "m": module,
                          "std": importlib.import_module("std_msgs.msg"),
                          "geo": importlib.import_module("geometry_msgs.msg"),
                          "rospy": rospy}))
        time.sleep(0.002)
    print("done", flush=True)
    while True:
        time.sleep(1)
"""


@pytest.fixture
def ros1() -> Iterator[Ros1System]:
    with Ros1System() as system:
        yield system


@pytest.fixture
def logs(capfd: pytest.CaptureFixture[str]) -> Logs:
    return Logs(capfd)


_handles = contextlib.ExitStack()


def close_containers() -> Iterator[None]:
    """Close the DDS containers :func:`bridge` made (an autouse fixture in each module)."""
    yield
    _handles.close()


@pytest.fixture(autouse=True)
def _close_containers() -> Iterator[None]:
    yield from close_containers()


def read_line(proc: subprocess.Popen[bytes], timeout_s: float = 20.0) -> str:
    reader = _readers.get(proc.pid)
    if reader is None:
        reader = _readers[proc.pid] = LineReader(proc)
    return reader.next(timeout_s)


_readers: dict[int, LineReader] = {}


def bridge(
    system: Ros1System,
    topics: list[dict[str, Any]],
    *,
    ros1: dict[str, Any] | None = None,
    **extra: Any,
) -> tuple[TestHandle, BridgeNode]:
    config = parse_config(
        {
            "ros1": {
                "master_uri": system.master_uri,
                "node_name": unique_topic("rf_bridge"),
                "master_check_s": 0.2,
                **(ros1 or {}),
            },
            "topics": topics,
            **extra,
        }
    )
    assert not config.errors
    node = _handles.enter_context(rclpy_test_handle())
    b = BridgeNode(node, config=config)
    adapter = b.adapters["ros1"]
    assert adapter.wait_registered(10.0)  # type: ignore[attr-defined]
    return node, b


def connected_listener(
    ros1: Ros1System, adapter: Any, topic: str, type_name: str, *, log: str = "l"
) -> subprocess.Popen[bytes]:
    """A rospy listener of a topic the bridge publishes, once the bridge serves it."""
    listener = ros1.python(NODE, "listen", topic, type_name, log=log)
    assert read_line(listener) == "ready"
    assert wait_for(lambda: bool(adapter._pubs[topic].connections), 20)
    return listener


def out_and_in(ros1: Ros1System) -> tuple[str, str, TestHandle, BridgeNode]:
    """A bridge with one String topic each way: ``out`` to ROS 1, ``inn`` from it."""
    out, inn = unique_topic("out"), unique_topic("in")
    node, b = bridge(
        ros1,
        [
            {"ros2": out, "type": "std_msgs/msg/String"},
            {"ros2": inn, "type": "std_msgs/msg/String", "direction": "from_peer"},
        ],
    )
    return out, inn, node, b


def spin_until(node: TestHandle, predicate: Any, timeout_s: float = 20.0) -> bool:
    return node.container.executor.spin_until(predicate, timeout_s=timeout_s)


def stat(b: BridgeNode, direction: str) -> Any:
    return next(s for s in b.stats() if s.direction == direction)


def test_ros2_to_ros1_string_and_pose(ros1: Ros1System) -> None:
    chatter, pose = unique_topic("chatter"), unique_topic("pose")
    node, b = bridge(
        ros1,
        [
            {"ros2": chatter, "type": "std_msgs/msg/String"},
            {"ros2": pose, "type": "geometry_msgs/msg/PoseStamped"},
        ],
    )
    try:
        l1 = ros1.python(NODE, "listen", chatter, "std_msgs/String", log="l1")
        l2 = ros1.python(NODE, "listen", pose, "geometry_msgs/PoseStamped", log="l2")
        assert read_line(l1) == "ready" and read_line(l2) == "ready"
        pub = b.adapters["ros1"]._pubs  # type: ignore[attr-defined]
        assert wait_for(lambda: pub[chatter].connections and pub[pose].connections, 20)
        for i in range(3):
            node.inject(chatter, String(data=f"hello {i}"))
        p = PoseStamped()
        p.header.frame_id = "map"
        p.header.stamp.sec, p.header.stamp.nanosec = 12, 345
        p.pose.position.x, p.pose.orientation.w = 1.5, 1.0
        node.inject(pose, p)
        assert [json.loads(read_line(l1))["data"] for _ in range(3)] == [
            "hello 0",
            "hello 1",
            "hello 2",
        ]
        got = json.loads(read_line(l2))
        assert got["header"]["frame_id"] == "map" and got["header"]["stamp"] == {
            "secs": 12,
            "nsecs": 345,
        }
        assert got["pose"]["position"]["x"] == 1.5 and got["pose"]["orientation"]["w"] == 1.0
        assert stat(b, "to_ros1").messages >= 3
    finally:
        b.close()


def test_ros1_to_ros2_string_pose_image(ros1: Ros1System) -> None:
    chatter, pose, image = unique_topic("chatter"), unique_topic("pose"), unique_topic("image")
    node, b = bridge(
        ros1,
        [
            {"ros2": chatter, "type": "std_msgs/msg/String", "direction": "from_peer"},
            {"ros2": pose, "type": "geometry_msgs/msg/PoseStamped", "direction": "from_peer"},
            {"ros2": image, "type": "sensor_msgs/msg/Image", "direction": "from_peer"},
        ],
    )
    try:
        ros1.python(
            NODE, "talk", chatter, "std_msgs/String", "m.String(data='n%d' % i)", "5", log="t1"
        )
        ros1.python(
            NODE,
            "talk",
            pose,
            "geometry_msgs/PoseStamped",
            "m.PoseStamped(header=std.Header(frame_id='odom'),"
            " pose=m.Pose(position=m.Point(x=i, y=2.0)))",
            "2",
            log="t2",
        )
        ros1.python(
            NODE,
            "talk",
            image,
            "sensor_msgs/Image",
            "m.Image(height=512, width=512, encoding='rgb8', step=1536,"
            " data=bytes([i % 256]) * (512 * 1536))",
            "2",
            log="t3",
        )

        def counts() -> list[int]:
            return [len(node.published(t)) for t in (chatter, pose, image)]

        assert spin_until(node, lambda: counts() >= [5, 2, 2]), (counts(), ros1.log_text("t2"))
        assert [m.data for m in node.published(chatter)] == [f"n{i}" for i in range(5)]
        poses = node.published(pose)
        assert [(m.header.frame_id, m.pose.position.x, m.pose.position.y) for m in poses] == [
            ("odom", 0.0, 2.0),
            ("odom", 1.0, 2.0),
        ]
        images = node.published(image)
        assert images[1].width == 512 and images[1].encoding == "rgb8"
        assert bytes(images[1].data) == bytes([1]) * (512 * 1536)
        s = next(s for s in b.stats() if s.topic == image)
        assert s.messages == 2 and s.bytes > 2 * 512 * 1536
    finally:
        b.close()


def test_image_ros2_to_ros1(ros1: Ros1System) -> None:
    topic = unique_topic("image")
    node, b = bridge(ros1, [{"ros2": topic, "type": "sensor_msgs/msg/Image"}])
    try:
        listener = connected_listener(ros1, b.adapters["ros1"], topic, "sensor_msgs/Image")
        img = Image(height=1024, width=1024, encoding="mono8", step=1024)
        img.data = bytes(range(256)) * 4096
        node.inject(topic, img)
        got = json.loads(read_line(listener))
        assert got["height"] == 1024 and got["encoding"] == "mono8"
        assert got["data"] == {"len": 1 << 20, "sha1": hashlib.sha1(bytes(img.data)).hexdigest()}
    finally:
        b.close()


SIGHTING = "string label\nfloat64 distance\nfloat64 bearing\n"


def test_type_learned_from_connection_with_yaml_rule(ros1: Ros1System) -> None:
    """A ROS 1 type nobody built for the bridge: learned from the publisher's header."""
    topic = unique_topic("sightings")
    node, b = bridge(
        ros1,
        [{"ros2": topic, "peer_type": "lab_msgs/Sighting", "direction": "from_peer"}],
        types=[
            {
                "ros1": "lab_msgs/Sighting",
                "ros2": "geometry_msgs/msg/Vector3",
                "fields": {"x": "distance", "y": "bearing"},
            }
        ],
    )
    try:
        assert "lab_msgs/Sighting" not in b.translators.registry
        ros1.python(
            NODE,
            "talk",
            topic,
            "lab_msgs/Sighting",
            "cls(label='ball', distance=2.5 + i, bearing=-0.25)",
            "3",
            SIGHTING,
            log="t",
        )
        assert spin_until(node, lambda: len(node.published(topic)) >= 3)
        assert [(m.x, m.y, m.z) for m in node.published(topic)] == [
            (2.5, -0.25, 0.0),
            (3.5, -0.25, 0.0),
            (4.5, -0.25, 0.0),
        ]
        assert "lab_msgs/Sighting" in b.translators.registry
    finally:
        b.close()


def test_rostopic_echo_hz_and_rosbag_record_and_play(ros1: Ros1System) -> None:
    """ROS 1's own tools on bridged topics: rostopic (rospy) and rosbag (roscpp) record a
    bridged topic, and rosbag play (a roscpp publisher) feeds the recording back to ROS 2."""
    topic, replay = unique_topic("chatter"), unique_topic("replay")
    node, b = bridge(
        ros1,
        [
            {"ros2": topic, "type": "std_msgs/msg/String"},
            {"ros2": replay, "type": "std_msgs/msg/String", "direction": "from_peer"},
        ],
    )
    try:
        echo = ros1.spawn(["rostopic", "echo", "-n", "3", topic], log="echo", stdout_pipe=True)
        hz = LineReader(ros1.spawn(["rostopic", "hz", topic], log="hz", stdout_pipe=True))
        bag = ros1.workdir / "out.bag"
        rec = ros1.spawn(["rosbag", "record", "-O", str(bag), topic], log="rec")
        pubs = b.adapters["ros1"]._pubs  # type: ignore[attr-defined]
        assert wait_for(lambda: len(pubs[topic].connections) >= 3, 30), "echo, hz, record"
        sent = 0
        deadline = time.monotonic() + 30
        rates: list[float] = []
        while time.monotonic() < deadline and not rates:
            node.inject(topic, String(data=f"m{sent}"))
            sent += 1
            time.sleep(0.02)
            rates += [float(line.split(":")[1]) for line in hz.drain() if "average rate" in line]
        assert rates, "rostopic hz saw no rate"
        assert 10 < rates[0] < 100  # sent every 20 ms plus the loop's own time
        assert echo.wait(timeout=20) == 0
        assert echo.stdout is not None
        echoed = [
            int(line.split('"m')[1].rstrip('"'))
            for line in echo.stdout.read().decode().splitlines()
            if line.startswith("data:")
        ]
        assert len(echoed) == 3 and echoed == list(range(echoed[0], echoed[0] + 3))
        Ros1System.kill(rec, sig=2)  # SIGINT: rosbag closes the bag
        script = (
            "import json,rosbag,sys\nb=rosbag.Bag(sys.argv[1])\n"
            "print(json.dumps([m.data for _,m,_ in b.read_messages()]))"
        )
        result = subprocess.run(
            ["/usr/bin/python3", "-c", script, str(bag)],
            env=ros1.env,
            capture_output=True,
            timeout=60,
            check=True,
        )
        recorded = json.loads(result.stdout)
        first = int(recorded[0][1:])
        assert len(recorded) > 10 and recorded == [
            f"m{i}" for i in range(first, first + len(recorded))
        ]
        ros1.spawn(
            ["rosbag", "play", "--wait-for-subscribers", str(bag), f"{topic}:={replay}"], log="play"
        )
        assert spin_until(node, lambda: len(node.published(replay)) >= len(recorded), 60)
        assert [m.data for m in node.published(replay)] == recorded
    finally:
        b.close()


def test_standalone_process_between_dds_and_ros1(ros1: Ros1System, tmp_path: Any) -> None:
    """The README's example as a user runs it (``ros2 run rf_bridge rf_bridge``): a String
    to ROS 1 and nav_msgs/Odometry from a rospy publisher, a ROS 2 peer over DDS."""
    import yaml
    from nav_msgs.msg import Odometry

    from efficient_comm.testing import isolated_domain_id

    from ._ros import child, executable, peer

    out, back = unique_topic("chatter"), unique_topic("odom")
    config = tmp_path / "bridge.yaml"
    config.write_text(
        yaml.safe_dump(
            {
                "ros1": {"master_uri": ros1.master_uri, "node_name": unique_topic("rf_bridge")},
                "topics": [
                    {"ros2": out, "type": "std_msgs/msg/String"},
                    {"ros2": back, "type": "nav_msgs/msg/Odometry", "direction": "from_peer"},
                ],
            }
        )
    )
    domain = isolated_domain_id()
    program = executable("rf_bridge", "rf_bridge")
    with (
        child(
            [program, "--ros-args", "-p", f"config:={config}"],
            domain_id=domain,
            log=tmp_path / "bridge.log",
        ),
        peer(domain) as p,
    ):
        pub = p.node.create_publisher(String, out, 10)
        got: list[Any] = []
        p.node.create_subscription(Odometry, back, got.append, 10)
        listener = ros1.python(NODE, "listen", out, "std_msgs/String", log="l")
        assert read_line(listener) == "ready"
        assert p.wait_for(lambda: pub.get_subscription_count() > 0, 30)
        seen: list[str] = []
        reader = _readers[listener.pid]

        def arrived() -> bool:
            pub.publish(String(data="over dds"))
            seen.extend(reader.drain())
            return bool(seen)

        assert p.wait_for(arrived, 30), (tmp_path / "bridge.log").read_text()
        assert json.loads(seen[0])["data"] == "over dds"
        ros1.python(
            NODE,
            "talk",
            back,
            "nav_msgs/Odometry",
            "m.Odometry(header=std.Header(frame_id='odom'), child_frame_id='base_link',"
            " pose=geo.PoseWithCovariance(covariance=[float(i)] * 36))",
            "3",
            log="t",
        )
        assert p.wait_for(lambda: len(got) >= 3, 30)
        assert [(m.header.frame_id, m.child_frame_id) for m in got[:3]] == [
            ("odom", "base_link")
        ] * 3
        assert [list(m.pose.covariance) for m in got[:3]] == [[float(i)] * 36 for i in range(3)]


def test_type_learned_from_a_subscriber_when_definitions_differ(
    ros1: Ros1System, logs: Logs
) -> None:
    """A rule's ROS 1 definition that is out of date (the ROS 1 type gained a field): the
    bridge adopts the definition the rospy subscriber sends, as ROS 1 defines ROS 1 types."""
    from geometry_msgs.msg import Vector3

    topic = unique_topic("sightings")
    node, b = bridge(
        ros1,
        [{"ros2": topic, "type": "geometry_msgs/msg/Vector3", "peer_type": "lab_msgs/Sighting"}],
        types=[
            {
                "ros1": "lab_msgs/Sighting",
                "ros2": "geometry_msgs/msg/Vector3",
                "fields": {"x": "distance", "y": "bearing"},
                "ros1_definition": "float64 distance\nfloat64 bearing\n",
            }
        ],
    )
    adapter: Any = b.adapters["ros1"]
    try:
        derived = adapter._pubs[topic].md5sum
        listener = ros1.python(NODE, "listen", topic, "lab_msgs/Sighting", "", "0", SIGHTING,
                               log="l")
        assert read_line(listener) == "ready"
        assert wait_for(lambda: bool(adapter._pubs[topic].connections), 20)
        assert adapter._pubs[topic].md5sum != derived
        node.inject(topic, Vector3(x=2.5, y=-0.25))
        assert json.loads(read_line(listener)) == {
            "label": "", "distance": 2.5, "bearing": -0.25
        }
        assert logs.wait("learned lab_msgs/Sighting")
    finally:
        b.close()


def test_composed_from_a_container_file(ros1: Ros1System, tmp_path: Any) -> None:
    """The bridge as a component in a container file (entry point ``BridgeNode``), next to
    the component whose topic it carries: the camera's image reaches the bridge by reference
    and rospy as a ROS 1 message."""
    import yaml

    from efficient_comm import Container
    from efficient_comm.testing import isolated_domain_id

    topic = unique_topic("camera")
    bridge_file = tmp_path / "bridge.yaml"
    bridge_file.write_text(
        yaml.safe_dump(
            {
                "ros1": {"master_uri": ros1.master_uri, "node_name": unique_topic("rf_bridge")},
                "topics": [{"ros2": topic, "type": "sensor_msgs/msg/Image"}],
            }
        )
    )
    container_file = tmp_path / "robot.yaml"
    container_file.write_text(
        yaml.safe_dump(
            {
                "components": [
                    {
                        "class": "BridgeNode",
                        "name": "rf_bridge",
                        "parameters": {
                            "/rf_bridge": {"ros__parameters": {"config": str(bridge_file)}}
                        },
                    },
                ]
            }
        )
    )
    with Container("robot", domain_id=isolated_domain_id()) as container:
        report = container.load_file(container_file)
        assert not report.errors, report.errors
        bridge_node: BridgeNode = report.loaded[0].instance
        adapter: Any = bridge_node.adapters["ros1"]
        sent: list[Any] = []
        adapter_send = adapter.send

        def spy(route: Any, msg: Any, received_ns: int) -> None:
            sent.append(msg)
            adapter_send(route, msg, received_ns)

        adapter.send = spy
        camera = container.add(
            lambda node: node.create_publisher(Image, topic, qos=10), name="camera"
        )
        listener = connected_listener(ros1, adapter, topic, "sensor_msgs/Image")
        img = Image(height=2, width=2, encoding="mono8", step=2, data=b"\x01\x02\x03\x04")
        camera.publish(img)
        assert sent and sent[0] is img  # by reference up to the adapter
        got = json.loads(read_line(listener))
        assert got["width"] == 2 and got["data"]["len"] == 4
        bridge_node.close()


def test_values_the_other_side_cannot_hold(ros1: Ros1System, logs: Logs) -> None:
    """One rule: an 8-bit ``byte`` crosses as the same octet (what the wire carries: ROS 2's
    byte 200 is ROS 1's int8 -56 and back); any other value the receiving type cannot hold
    (a ROS 1 time beyond 2^31 s, a negative ROS 2 time) drops that message, counted as
    ``out_of_range`` and logged, and the connection carries on."""
    from std_msgs.msg import Byte, Char, Header

    byte_out, char_out, header_out = (unique_topic(n) for n in ("byte", "char", "header"))
    byte_in, header_in = unique_topic("byte_in"), unique_topic("header_in")
    node, b = bridge(
        ros1,
        [
            {"ros2": byte_out, "type": "std_msgs/msg/Byte"},
            {"ros2": char_out, "type": "std_msgs/msg/Char"},
            {"ros2": header_out, "type": "std_msgs/msg/Header"},
            {"ros2": byte_in, "type": "std_msgs/msg/Byte", "direction": "from_peer"},
            {"ros2": header_in, "type": "std_msgs/msg/Header", "direction": "from_peer"},
        ],
    )
    adapter: Any = b.adapters["ros1"]
    try:
        lb = connected_listener(ros1, adapter, byte_out, "std_msgs/Byte", log="lb")
        lc = connected_listener(ros1, adapter, char_out, "std_msgs/Char", log="lc")
        lh = connected_listener(ros1, adapter, header_out, "std_msgs/Header", log="lh")
        node.inject(byte_out, Byte(data=b"\xc8"), Byte(data=b"\x05"))
        node.inject(char_out, Char(data=200))
        assert [json.loads(read_line(lb))["data"] for _ in range(2)] == [-56, 5]
        assert json.loads(read_line(lc))["data"] == 200
        late = Header(frame_id="before 1970")
        late.stamp.sec = -5
        node.inject(header_out, late, Header(frame_id="fine"))
        assert json.loads(read_line(lh))["frame_id"] == "fine"
        assert drops(b, header_out, "to_ros1") == {"out_of_range": 1}
        assert logs.wait(f"not sent to ROS 1 {header_out}")

        ros1.python(NODE, "talk", byte_in, "std_msgs/Byte", "m.Byte(data=-56 + i)", "2",
                    log="tb")
        ros1.python(
            NODE,
            "talk",
            header_in,
            "std_msgs/Header",
            "m.Header(frame_id=str(i), stamp=rospy.Time(2**31 + 5 if i == 1 else 7, 0))",
            "3",
            log="th",
        )
        assert spin_until(
            node, lambda: len(node.published(byte_in)) >= 2 and len(node.published(header_in)) >= 2
        )
        assert [m.data for m in node.published(byte_in)] == [b"\xc8", b"\xc9"]
        assert [m.frame_id for m in node.published(header_in)] == [
            "0", "2"
        ]
        assert drops(b, header_in, "from_ros1") == {"out_of_range": 1}
        assert logs.wait(f"not delivered from ROS 1 {header_in}")
    finally:
        b.close()


def drops(b: BridgeNode, topic: str, direction: str) -> dict[str, int]:
    snap = next(s for s in b.stats() if s.topic == topic and s.direction == direction)
    return dict(snap.drops)


def test_help_prints_usage_and_exits_0() -> None:
    """``ros2 run rf_bridge rf_bridge --help`` as a user types it (the program it runs)."""
    from ._ros import executable

    program = executable("rf_bridge", "rf_bridge")
    done = subprocess.run([program, "--help"], capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    assert "config:=bridge.yaml" in done.stdout and done.stderr == ""
    wrong = subprocess.run([program, "--bogus"], capture_output=True, text=True, timeout=60)
    assert wrong.returncode == 2
    assert wrong.stderr.strip().splitlines()[-1] == (
        "rf_bridge: error: unrecognized arguments: --bogus"
    )
