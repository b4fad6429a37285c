"""YAML values as the ros2 command turns them into messages, checked on the wire.

ros2cli converts each value with the field's type ('1.5' -> 1.5, 'yes' -> True, 3.7 -> 3)
and refuses, naming the field, what does not convert. A plain rclpy subscriber in another
process prints what arrives; a refused command must publish nothing, so each refusal is
followed by a good message that has to be the first one received.
"""

from __future__ import annotations

import re
import sys
from collections.abc import Iterator

import pytest

from efficient_comm.testing import isolated_domain_id, unique_topic

from ._cli import ROOT, Running, ros2, running

ENDPOINT = ROOT / "tests" / "_cli_endpoint.py"


class Listener:
    def __init__(self, process: Running, domain_id: int, pose: str, flag: str,
                 number: str) -> None:
        self.process, self.domain_id = process, domain_id
        self.pose, self.flag, self.number = pose, flag, number

    def received(self, topic: str, count: int) -> list[str]:
        """The first ``count`` messages received on ``topic`` (their reprs), waited for."""
        pattern = re.compile(rf"^received on {re.escape(topic)}: (.*)$", re.MULTILINE)
        text = self.process.wait_for(lambda t: len(pattern.findall(t)) >= count)
        return pattern.findall(text)[:count]


@pytest.fixture(scope="module")
def listener(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Listener]:
    domain_id = isolated_domain_id()
    pose, flag, number = (unique_topic(n) for n in ("pose", "flag", "number"))
    log = tmp_path_factory.mktemp("listener") / "listener.log"
    with running([sys.executable, str(ENDPOINT), "listener", "sub",
                  f"{pose}:geometry_msgs/msg/PoseStamped", f"{flag}:std_msgs/msg/Bool",
                  f"{number}:std_msgs/msg/Int32"], domain_id=domain_id, log=log) as process:
        process.wait_for(lambda text: "ready" in text)
        yield Listener(process, domain_id, pose, flag, number)


def pub(listener: Listener, topic: str, type_name: str, values: str, *args: str,
        stdin: str = "") -> tuple[int, str, str]:
    result = ros2("topic", "pub", "--once", *args, topic, type_name, values,
                  domain_id=listener.domain_id, stdin=stdin)
    assert "Traceback" not in result.stderr and "SystemError" not in result.stderr
    return result.returncode, result.stdout, result.stderr


def refused(listener: Listener, topic: str, type_name: str, values: str, field: str) -> None:
    status, out, err = pub(listener, topic, type_name, values)
    assert status == 1, (out, err)
    assert "publishing" not in out
    assert len(err.strip().splitlines()) == 1 and field in err, err


def test_values_are_converted_by_the_fields_type_or_refused(listener: Listener) -> None:
    pose = "geometry_msgs/msg/PoseStamped"
    refused(listener, listener.pose, pose, "{pose: {position: {x: abc}}}", "pose.position.x")
    refused(listener, listener.pose, pose, "{pose: {orientation: {w: [1]}}}",
            "pose.orientation.w")
    status, _, err = pub(listener, listener.pose, pose,
                         "{pose: {position: {x: '1.5', y: 2}}, header: {frame_id: 7}}")
    assert status == 0, err
    (first,) = listener.received(listener.pose, 1)
    assert "position=geometry_msgs.msg.Point(x=1.5, y=2.0, z=0.0)" in first, first
    assert "frame_id='7'" in first, first

    refused(listener, listener.flag, "std_msgs/msg/Bool", "{data: maybe}", "data")
    for text in ("{data: 'yes'}", "{data: 'off'}"):
        assert pub(listener, listener.flag, "std_msgs/msg/Bool", text)[0] == 0
    assert listener.received(listener.flag, 2) == ["std_msgs.msg.Bool(data=True)",
                                                   "std_msgs.msg.Bool(data=False)"]

    refused(listener, listener.number, "std_msgs/msg/Int32", "{data: 2147483648}", "data")
    refused(listener, listener.number, "std_msgs/msg/Int32", "{data: '1.5'}", "data")
    assert pub(listener, listener.number, "std_msgs/msg/Int32", "{data: 3.7}")[0] == 0
    assert pub(listener, listener.number, "std_msgs/msg/Int32", "{data: '-12'}")[0] == 0
    assert listener.received(listener.number, 2) == ["std_msgs.msg.Int32(data=3)",
                                                     "std_msgs.msg.Int32(data=-12)"]


def test_header_auto_and_stamp_now_put_the_time_of_publishing(listener: Listener) -> None:
    pose = "geometry_msgs/msg/PoseStamped"
    stamp = re.compile(r"stamp=builtin_interfaces\.msg\.Time\(sec=(\d+), nanosec=\d+\)")
    before = listener.process.text().count(f"received on {listener.pose}")
    for values in ("{header: auto}", "{header: {stamp: now, frame_id: map}}"):
        status, out, err = pub(listener, listener.pose, pose, values)
        assert status == 0, err
        match = stamp.search(out)
        assert match and int(match.group(1)) > 1_700_000_000, out
    received = listener.received(listener.pose, before + 2)[before:]
    stamps = [int(m.group(1)) for m in map(stamp.search, received) if m]
    assert len(stamps) == 2 and all(s > 1_700_000_000 for s in stamps), received
    assert "frame_id='map'" in received[1]


def test_pub_reads_values_from_stdin(listener: Listener) -> None:
    before = listener.process.text().count(f"received on {listener.number}")
    status, _, err = pub(listener, listener.number, "std_msgs/msg/Int32", "", "--stdin",
                         stdin="data: 41\n")
    assert status == 2 and "--stdin" in err  # values and --stdin exclude each other
    result = ros2("topic", "pub", "--once", "--stdin", listener.number, "std_msgs/msg/Int32",
                  domain_id=listener.domain_id, stdin="data: 42\n")
    assert result.returncode == 0, result.stderr
    numbers = listener.received(listener.number, before + 1)
    assert numbers[before] == "std_msgs.msg.Int32(data=42)"


def test_fixed_size_arrays_take_exactly_their_size() -> None:
    result = ros2("topic", "pub", "--once", "/unused", "sensor_msgs/msg/CameraInfo",
                  "{k: [1, 2, 3]}", domain_id=isolated_domain_id())
    assert result.returncode == 1 and "k (double[9])" in result.stderr, result.stderr
