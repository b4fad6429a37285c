"""debug_gui's Foxglove endpoint at the protocol level, against a robot in another process.

A WebSocket client speaks the Foxglove WebSocket protocol (under its old name
``foxglove.websocket.v1``, and the SDK's ``foxglove.sdk.v1``) to the endpoint serving a
plain rclpy robot (tests/_foxglove_peer.py) on an isolated DDS domain. The robot reports
from its own side what it sees: how many subscriptions its topic has and which parameter
values it accepted, so the assertions hold on the robot, not only on the wire.
"""

from __future__ import annotations

import contextlib
import json
import queue
import re
import socket
import struct
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest
from mcap_ros2._dynamic import generate_dynamic
from rclpy.serialization import deserialize_message, serialize_message
from std_msgs.msg import String
from websockets.exceptions import InvalidStatus
from websockets.sync.client import ClientConnection, connect

from debug_gui import Hub
from debug_gui.foxglove import FoxgloveEndpoint, serve_foxglove
from debug_gui.security import AccessPolicy
from efficient_comm.testing import isolated_domain_id, ros_env, stop_process_group, unique_topic
from efficient_comm_interfaces.srv import UnloadComponent

from ._ros import executable

PEER = Path(__file__).with_name("_foxglove_peer.py")
TIMEOUT_S = 30.0
MESSAGE_DATA = 0x01
SERVICE_CALL_RESPONSE = 0x03


class Robot:
    """The peer process and the lines it prints, waited for with a deadline."""

    def __init__(self, domain: int, namespace: str, topic: str, *extra: str) -> None:
        self.domain, self.namespace, self.topic = domain, namespace, topic
        self.proc = subprocess.Popen(
            [sys.executable, str(PEER), namespace, topic, *extra], env=ros_env(domain),
            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
            start_new_session=True)
        self.lines: queue.Queue[str] = queue.Queue()
        self.seen: list[str] = []
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()
        self.expect("ready")

    def _read(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            self.lines.put(line.rstrip("\n"))

    def expect(self, wanted: str, *, after: int = 0) -> None:
        """Wait for the robot to print ``wanted`` (as its ``after``-th line or later)."""
        end = time.monotonic() + TIMEOUT_S
        while wanted not in self.seen[after:]:
            try:
                self.seen.append(self.lines.get(timeout=max(0.0, end - time.monotonic())))
            except queue.Empty:
                pytest.fail(f"the robot never printed {wanted!r}; it printed {self.seen}")

    def last(self, prefix: str) -> str | None:
        while not self.lines.empty():
            self.seen.append(self.lines.get_nowait())
        matching = [line for line in self.seen if line.startswith(prefix)]
        return matching[-1] if matching else None

    def close(self) -> None:
        stop_process_group(self.proc)
        self._reader.join(timeout=TIMEOUT_S)
        if self.proc.stdout is not None:
            self.proc.stdout.close()


class Viewer:
    """A minimal Foxglove WebSocket client: what Foxglove, Lichtblick and PlotJuggler send."""

    def __init__(self, url: str, *, subprotocol: str = "foxglove.websocket.v1") -> None:
        self._stack = contextlib.ExitStack()
        self.ws: ClientConnection = self._stack.enter_context(connect(
            url, subprotocols=[subprotocol], max_size=None,  # type: ignore[list-item]
            open_timeout=TIMEOUT_S))
        self.channels: dict[str, dict[str, Any]] = {}
        self.services: dict[str, dict[str, Any]] = {}
        self.binary: list[bytes] = []
        self.pending: list[dict[str, Any]] = []
        self.info = self.next_json(lambda m: m.get("op") == "serverInfo")

    def send(self, op: str, **fields: Any) -> None:
        self.ws.send(json.dumps({"op": op, **fields}))

    def _take(self, message: str | bytes) -> dict[str, Any] | None:
        if isinstance(message, bytes):
            self.binary.append(message)
            return None
        parsed: dict[str, Any] = json.loads(message)
        if parsed.get("op") == "advertise":
            self.channels.update({c["topic"]: c for c in parsed["channels"]})
        elif parsed.get("op") == "unadvertise":
            gone = set(parsed["channelIds"])
            self.channels = {t: c for t, c in self.channels.items() if c["id"] not in gone}
        elif parsed.get("op") == "advertiseServices":
            self.services.update({s["name"]: s for s in parsed["services"]})
        return parsed

    def next_json(self, accept: Callable[[dict[str, Any]], bool], *,
                  timeout_s: float = TIMEOUT_S, required: bool = True) -> Any:
        """The first JSON message ``accept`` takes, in arrival order, waited for.

        Messages it does not take stay for later calls: the endpoint may send a status and
        an answer in either order.
        """
        for i, waiting in enumerate(self.pending):
            if accept(waiting):
                return self.pending.pop(i)
        end = time.monotonic() + timeout_s
        while time.monotonic() < end:
            try:
                parsed = self._take(self.ws.recv(timeout=max(0.01, end - time.monotonic())))
            except TimeoutError:
                break
            if parsed is None:
                continue
            if accept(parsed):
                return parsed
            self.pending.append(parsed)
        if required:
            pytest.fail("no such message from the endpoint in time")
        return None

    def next_binary(self, opcode: int) -> bytes:
        end = time.monotonic() + TIMEOUT_S
        while time.monotonic() < end:
            for i, frame in enumerate(self.binary):
                if frame[0] == opcode:
                    return self.binary.pop(i)
            try:
                self._take(self.ws.recv(timeout=max(0.01, end - time.monotonic())))
            except TimeoutError:
                break
        pytest.fail(f"no binary message with opcode {opcode} in time")

    def wait_for_channel(self, topic: str) -> dict[str, Any]:
        if topic not in self.channels:
            self.next_json(lambda _m: topic in self.channels)
        return self.channels[topic]

    def wait_for_service(self, name: str) -> dict[str, Any]:
        if name not in self.services:
            self.next_json(lambda _m: name in self.services)
        return self.services[name]

    def close(self) -> None:
        self._stack.close()


@pytest.fixture
def robot() -> Iterator[Robot]:
    peer = Robot(isolated_domain_id(), f"/robot_{unique_topic('r')[3:11]}",
                 unique_topic("chatter")[1:])
    try:
        yield peer
    finally:
        peer.close()


def wait_for_node(hub: Hub, node: str) -> None:
    end = time.monotonic() + TIMEOUT_S
    while not any(node in hub.nodes(robot) for robot in hub.robots()):
        assert time.monotonic() < end, f"the Hub never saw the node {node}"
        time.sleep(0.05)  # the Hub has no event for a node's arrival; polled with a deadline


@pytest.fixture
def policy() -> AccessPolicy:
    return AccessPolicy.for_server()


@pytest.fixture
def endpoint(robot: Robot, policy: AccessPolicy) -> Iterator[FoxgloveEndpoint]:
    with Hub(domains=[robot.domain]) as hub:
        assert hub.wait_for_robots(1, timeout_s=TIMEOUT_S), "the Hub never saw the robot"
        # The robot is seen by its statistics topic; its node's name reaches the Hub by
        # another discovery message, sometimes later: parameters are addressed by node.
        wait_for_node(hub, f"{robot.namespace}/detector")
        with serve_foxglove(hub, policy=policy, port=0, refresh_s=0.2) as served:
            yield served


def test_topics_are_cdr_with_ros2msg_schemas_and_subscribed_only_while_watched(
        robot: Robot, endpoint: FoxgloveEndpoint) -> None:
    viewer = Viewer(endpoint.url)
    try:
        topic = f"{robot.namespace}/{robot.topic}"
        channel = viewer.wait_for_channel(topic)
        assert channel["encoding"] == "cdr"
        assert channel["schemaEncoding"] == "ros2msg"
        assert channel["schemaName"] == "std_msgs/msg/String"
        assert channel["schema"].splitlines()[-1] == "string data"
        stats = viewer.wait_for_channel(f"{robot.namespace}/efficient_comm/stats")
        assert "MSG: efficient_comm_interfaces/msg/CallbackStats" in stats["schema"]

        robot.expect("subscribers 0")  # nobody watches: the robot sends to nobody
        mark = len(robot.seen)
        viewer.send("subscribe", subscriptions=[{"id": 42, "channelId": channel["id"]}])
        robot.expect("subscribers 1", after=mark)
        frame = viewer.next_binary(MESSAGE_DATA)
        subscription_id, _log_time = struct.unpack_from("<IQ", frame, 1)
        assert subscription_id == 42
        msg = deserialize_message(frame[13:], String)
        assert msg.data.startswith("hello ")
        # A viewer without ROS decodes it from the advertised schema alone.
        decode = generate_dynamic(channel["schemaName"], channel["schema"])
        assert decode[channel["schemaName"]](frame[13:]).data == msg.data

        mark = len(robot.seen)
        viewer.send("unsubscribe", subscriptionIds=[42])
        robot.expect("subscribers 0", after=mark)  # the robot-side subscription ended
        assert endpoint.subscribed_topics() == []
    finally:
        viewer.close()


def test_a_parameter_round_trips_and_a_veto_is_reported(
        robot: Robot, endpoint: FoxgloveEndpoint) -> None:
    viewer = Viewer(endpoint.write_url)
    name = f"{robot.namespace}/detector.threshold"
    try:
        viewer.send("getParameters", parameterNames=[name], id="get")
        got = viewer.next_json(lambda m: m.get("op") == "parameterValues" and m.get("id") == "get")
        assert got["parameters"] == [{"name": name, "type": "float64", "value": 0.5}], \
            viewer.pending

        # JSON has no 1 vs 1.0: the endpoint keeps the parameter a double.
        viewer.send("setParameters", parameters=[{"name": name, "value": 1}], id="set")
        done = viewer.next_json(lambda m: m.get("op") == "parameterValues" and m.get("id") == "set")
        assert done["parameters"] == [{"name": name, "type": "float64", "value": 1.0}], \
            viewer.pending
        robot.expect("threshold 1.0")

        viewer.send("setParameters", parameters=[{"name": name, "value": -2.0,
                                                   "type": "float64"}], id="veto")
        status = viewer.next_json(lambda m: m.get("op") == "status")
        assert "threshold must not be negative" in status["message"]
        after = viewer.next_json(lambda m: m.get("op") == "parameterValues"
                                 and m.get("id") == "veto")
        assert after["parameters"], viewer.pending  # the statuses say why
        assert after["parameters"][0]["value"] == 1.0
    finally:
        viewer.close()


def test_a_parameter_changed_elsewhere_reaches_a_subscribed_viewer(
        robot: Robot, endpoint: FoxgloveEndpoint) -> None:
    watcher = Viewer(endpoint.url)
    writer = Viewer(endpoint.write_url, subprotocol="foxglove.sdk.v1")
    name = f"{robot.namespace}/detector.threshold"
    try:
        watcher.send("subscribeParameterUpdates", parameterNames=[name])
        deadline = time.monotonic() + TIMEOUT_S
        value = 0.25
        update = None
        while update is None:  # until the endpoint's /parameter_events feed has matched
            assert time.monotonic() < deadline, "no parameter update reached the watcher"
            value += 0.25
            writer.send("setParameters", parameters=[{"name": name, "value": value,
                                                      "type": "float64"}])
            update = watcher.next_json(lambda m: m.get("op") == "parameterValues",
                                       timeout_s=2.0, required=False)
        assert update["parameters"][0]["name"] == name
        assert update["parameters"][0]["value"] == value
    finally:
        watcher.close()
        writer.close()


def test_a_service_call_answers(robot: Robot, endpoint: FoxgloveEndpoint) -> None:
    viewer = Viewer(endpoint.write_url)
    try:
        service = viewer.wait_for_service(f"{robot.namespace}/detector/check")
        assert service["type"] == "efficient_comm_interfaces/srv/UnloadComponent"
        assert service["request"]["schemaEncoding"] == "ros2msg"
        assert "uint64 unique_id" in service["request"]["schema"]
        payload = bytes(serialize_message(UnloadComponent.Request(unique_id=7)))
        viewer.ws.send(struct.pack("<BIII", 0x02, service["id"], 5, 3) + b"cdr" + payload)
        frame = viewer.next_binary(SERVICE_CALL_RESPONSE)
        service_id, call_id, length = struct.unpack_from("<III", frame, 1)
        assert (service_id, call_id) == (service["id"], 5)
        response = deserialize_message(frame[13 + length:], UnloadComponent.Response)
        assert response.success and response.error_message == "got 7"
        # A malformed request is answered with a failure, and the endpoint goes on.
        viewer.ws.send(struct.pack("<BIII", 0x02, service["id"], 6, 3) + b"cdr" + b"\x00")
        failure = viewer.next_json(lambda m: m.get("op") == "serviceCallFailure")
        assert failure["callId"] == 6 and "not a CDR" in failure["message"]
    finally:
        viewer.close()


def test_without_the_token_a_viewer_looks_but_cannot_write(
        robot: Robot, endpoint: FoxgloveEndpoint) -> None:
    viewer = Viewer(endpoint.url)
    name = f"{robot.namespace}/detector.threshold"
    try:
        viewer.send("setParameters", parameters=[{"name": name, "value": 3.0,
                                                   "type": "float64"}], id="w")
        status = viewer.next_json(lambda m: m.get("op") == "status")
        assert "token" in status["message"]
        service = viewer.wait_for_service(f"{robot.namespace}/detector/check")
        payload = bytes(serialize_message(UnloadComponent.Request(unique_id=7)))
        viewer.ws.send(struct.pack("<BIII", 0x02, service["id"], 9, 3) + b"cdr" + payload)
        failure = viewer.next_json(lambda m: m.get("op") == "serviceCallFailure")
        assert failure["callId"] == 9 and "token" in failure["message"]
        viewer.send("getParameters", parameterNames=[name], id="r")
        got = viewer.next_json(lambda m: m.get("op") == "parameterValues" and m.get("id") == "r")
        assert got["parameters"], viewer.pending
        assert got["parameters"][0]["value"] == 0.5  # the write never reached the robot
        assert robot.last("threshold") is None
    finally:
        viewer.close()


def test_beyond_loopback_even_looking_needs_the_token(robot: Robot) -> None:
    policy = AccessPolicy.for_server(host="0.0.0.0", token="secret-token-1")
    with Hub(domains=[robot.domain]) as hub, \
            serve_foxglove(hub, policy=policy, port=0, refresh_s=0.2) as served:
        with pytest.raises(InvalidStatus) as refused:
            Viewer(f"ws://127.0.0.1:{served.port}/")
        assert refused.value.response.status_code == 401
        viewer = Viewer(f"ws://127.0.0.1:{served.port}/?token=secret-token-1")
        assert "parameters" in viewer.info["capabilities"]
        viewer.close()


def _debug_gui(*args: str, domain: int) -> subprocess.Popen[str]:
    return subprocess.Popen(
        [str(executable("debug_gui", "debug_gui")), *args], env=ros_env(domain),
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, start_new_session=True)


def test_the_command_serves_foxglove_as_a_user_starts_it(robot: Robot) -> None:
    proc = _debug_gui("--port", "0", "--foxglove-port", "0", "--domains", str(robot.domain),
                      domain=robot.domain)
    try:
        assert proc.stdout is not None
        end = time.monotonic() + TIMEOUT_S
        line = ""
        while "Foxglove viewers connect to" not in line:
            assert time.monotonic() < end and proc.poll() is None, \
                f"debug_gui never printed the Foxglove URL (last line {line!r})"
            line = proc.stdout.readline()
        found = re.search(r"\(to set parameters and call services: (ws://\S+)\)", line)
        assert found, line
        viewer = Viewer(found.group(1))
        try:
            channel = viewer.wait_for_channel(f"{robot.namespace}/{robot.topic}")
            assert channel["schemaName"] == "std_msgs/msg/String"
        finally:
            viewer.close()
    finally:
        stop_process_group(proc)
        if proc.stdout is not None:
            proc.stdout.close()


def test_a_taken_foxglove_port_is_one_line_of_error(robot: Robot) -> None:
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        proc = _debug_gui("--port", "0", "--foxglove-port", str(taken.getsockname()[1]),
                          "--domains", str(robot.domain), domain=robot.domain)
        output, _ = proc.communicate(timeout=TIMEOUT_S)
    lines = output.strip().splitlines()
    assert proc.returncode == 2
    assert len(lines) == 1 and lines[0].startswith("debug_gui: error: cannot serve Foxglove on"), \
        output


def test_robots_of_several_domains_sharing_a_namespace_are_told_apart() -> None:
    namespace, topic = f"/robot_{unique_topic('r')[3:11]}", unique_topic("chatter")[1:]
    first = Robot(isolated_domain_id(), namespace, topic)
    second = Robot(isolated_domain_id(), namespace, topic)
    try:
        with Hub(domains=[first.domain, second.domain]) as hub, \
                serve_foxglove(hub, policy=AccessPolicy.for_server(), port=0,
                               refresh_s=0.2) as served:
            viewer = Viewer(served.url)
            try:
                one = viewer.wait_for_channel(f"/domain{first.domain}{namespace}/{topic}")
                two = viewer.wait_for_channel(f"/domain{second.domain}{namespace}/{topic}")
                assert one["id"] != two["id"]
                first.expect("subscribers 0")
                second.expect("subscribers 0")
                mark = len(second.seen)
                viewer.send("subscribe", subscriptions=[{"id": 1, "channelId": two["id"]}])
                second.expect("subscribers 1", after=mark)
                viewer.next_binary(MESSAGE_DATA)
                assert first.last("subscribers") == "subscribers 0"  # only the one watched
            finally:
                viewer.close()
    finally:
        first.close()
        second.close()


def test_a_throttle_aware_publisher_computes_only_while_a_viewer_subscribes() -> None:
    robot = Robot(isolated_domain_id(), f"/robot_{unique_topic('r')[3:11]}",
                  unique_topic("camera")[1:], "throttled")
    try:
        with Hub(domains=[robot.domain]) as hub, \
                serve_foxglove(hub, policy=AccessPolicy.for_server(), port=0,
                               refresh_s=0.2) as served:
            viewer = Viewer(served.url)
            try:
                channel = viewer.wait_for_channel(f"{robot.namespace}/{robot.topic}")
                robot.expect("wants False")  # advertised, yet nothing computed or sent
                mark = len(robot.seen)
                viewer.send("subscribe", subscriptions=[{"id": 3, "channelId": channel["id"]}])
                robot.expect("wants True", after=mark)
                frame = viewer.next_binary(MESSAGE_DATA)
                assert deserialize_message(frame[13:], String).data.startswith("hello ")
                mark = len(robot.seen)
                viewer.send("unsubscribe", subscriptionIds=[3])
                robot.expect("wants False", after=mark)
            finally:
                viewer.close()
    finally:
        robot.close()


def test_a_latched_message_reaches_a_viewer_that_subscribes_later(
        robot: Robot, endpoint: FoxgloveEndpoint) -> None:
    viewer = Viewer(endpoint.url)
    try:
        channel = viewer.wait_for_channel(f"{robot.namespace}/{robot.topic}_latched")
        viewer.send("subscribe", subscriptions=[{"id": 8, "channelId": channel["id"]}])
        frame = viewer.next_binary(MESSAGE_DATA)
        assert deserialize_message(frame[13:], String).data == \
            "published once, before anyone looked"
    finally:
        viewer.close()


def test_writes_that_bypass_the_gate_are_refused(
        robot: Robot, endpoint: FoxgloveEndpoint) -> None:
    # A local process that finds the SDK server's own loopback port and talks to it
    # directly: it may look (loopback), but it was never introduced with the token.
    sneak = Viewer(f"ws://127.0.0.1:{endpoint.sdk_port}/", subprotocol="foxglove.sdk.v1")
    name = f"{robot.namespace}/detector.threshold"
    try:
        sneak.send("setParameters", parameters=[{"name": name, "value": 4.0,
                                                  "type": "float64"}], id="s")
        status = sneak.next_json(lambda m: m.get("op") == "status")
        assert "token" in status["message"]
        service = sneak.wait_for_service(f"{robot.namespace}/detector/check")
        payload = bytes(serialize_message(UnloadComponent.Request(unique_id=7)))
        sneak.ws.send(struct.pack("<BIII", 0x02, service["id"], 4, 3) + b"cdr" + payload)
        failure = sneak.next_json(lambda m: m.get("op") == "serviceCallFailure")
        assert failure["callId"] == 4 and "token" in failure["message"]
        sneak.send("getParameters", parameterNames=[name], id="r")
        got = sneak.next_json(lambda m: m.get("op") == "parameterValues" and m.get("id") == "r")
        assert got["parameters"], sneak.pending
        assert got["parameters"][0]["value"] == 0.5
        assert robot.last("threshold") is None
    finally:
        sneak.close()


VIEWER_JS = Path(__file__).with_name("foxglove_viewer")


def test_foxglove_and_lichtblicks_own_client_library_views_the_robot(
        robot: Robot, endpoint: FoxgloveEndpoint) -> None:
    """The client library the Foxglove and Lichtblick apps are built on, with their ROS 2
    decoder: it decodes a topic from the advertised schema alone, reads and sets a
    parameter, and calls a service, against the endpoint a user starts."""
    if not (VIEWER_JS / "node_modules").is_dir():
        pytest.fail(f"{VIEWER_JS}/node_modules missing: scripts/setup_browser.sh installs it")
    name = f"{robot.namespace}/detector.threshold"
    result = subprocess.run(
        ["node", str(VIEWER_JS / "viewer.mjs"), endpoint.write_url,
         f"{robot.namespace}/{robot.topic}", name, "2.5", f"{robot.namespace}/detector/check"],
        capture_output=True, text=True, timeout=90, check=False)
    steps: dict[str, dict[str, Any]] = {}
    for line in result.stdout.splitlines():
        record = json.loads(line)
        steps.setdefault(record["step"], record)
    assert result.returncode == 0, (result.stdout, result.stderr)
    assert "parameters" in steps["serverInfo"]["capabilities"]
    assert steps["message"]["decoded"]["data"].startswith("hello ")
    assert steps["get"]["parameters"] == [{"name": name, "type": "float64", "value": 0.5}]
    assert steps["set"]["parameters"][0]["value"] == 2.5
    robot.expect("threshold 2.5")  # the robot itself took the viewer's value
    assert steps["service"]["type"] == "efficient_comm_interfaces/srv/UnloadComponent"
    assert steps["service"]["response"] == {"success": True, "error_message": "got 7"}
