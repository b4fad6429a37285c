"""The ros2 command against plain rclpy nodes in other processes, as a user types it.

Each check compares with the format ros2cli prints (topic echo's YAML and ``---``, topic hz's
lines, param get's ``Integer value is: 5``, service call's requester/response lines).
"""

from __future__ import annotations

import re
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest
import yaml

from efficient_comm.testing import isolated_domain_id, unique_topic

from ._cli import ROOT, Running, ros2, ros2_path, running

PEER = ROOT / "tests" / "_cli_peer.py"


class Peer:
    def __init__(self, process: Running, topic: str, domain_id: int) -> None:
        self.process, self.topic, self.domain_id = process, topic, domain_id


@pytest.fixture(scope="module")
def peer(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Peer]:
    domain_id = isolated_domain_id()
    topic = unique_topic("cli")
    log = tmp_path_factory.mktemp("peer") / "peer.log"
    with running([sys.executable, str(PEER), topic], domain_id=domain_id, log=log) as process:
        process.wait_for(lambda text: "ready" in text)
        yield Peer(process, topic, domain_id)


def run(peer: Peer, *args: str, ok: bool = True) -> str:
    result = ros2(*args, domain_id=peer.domain_id)
    if ok:
        assert result.returncode == 0, result.stderr
        assert "Traceback" not in result.stderr
    return result.stdout


def test_topic_list_type_info(peer: Peer) -> None:
    assert peer.topic in run(peer, "topic", "list").splitlines()
    assert f"{peer.topic} [std_msgs/msg/String]" in run(peer, "topic", "list", "-t").splitlines()
    assert run(peer, "topic", "type", peer.topic) == "std_msgs/msg/String\n"
    info = run(peer, "topic", "info", peer.topic)
    assert info == "Type: std_msgs/msg/String\nPublisher count: 1\nSubscription count: 0\n"
    verbose = run(peer, "topic", "info", "-v", peer.topic)
    assert "Node name: cli_peer" in verbose and "Reliability: RELIABLE" in verbose


def test_echo_prints_yaml_documents(peer: Peer, tmp_path: Path) -> None:
    once = run(peer, "topic", "echo", "--once", peer.topic)
    assert re.fullmatch(r"data: hello \d+\n---\n", once), once
    field = run(peer, "topic", "echo", "--once", peer.topic, "--field", "data")
    assert re.fullmatch(r"hello \d+\n---\n", field), field
    qos = run(peer, "topic", "echo", "--once", "--qos-reliability", "best_effort",
              "--qos-durability", "volatile", "--qos-depth", "1", peer.topic,
              "std_msgs/msg/String")
    assert re.fullmatch(r"data: hello \d+\n---\n", qos), qos
    flow = run(peer, "topic", "echo", "--once", "--flow-style", peer.topic)
    assert re.fullmatch(r"\{data: hello \d+\}\n---\n", flow), flow
    with running([ros2_path(), "topic", "echo", peer.topic], domain_id=peer.domain_id,
                 log=tmp_path / "echo.log") as echo:
        text = echo.wait_for(lambda t: t.count("---\n") >= 5)
    documents = [yaml.safe_load(d) for d in text.split("---\n")[:5]]
    numbers = [int(d["data"].split()[1]) for d in documents]
    assert numbers == list(range(numbers[0], numbers[0] + 5)), numbers


def test_hz_and_bw_lines(peer: Peer, tmp_path: Path) -> None:
    with running([ros2_path(), "topic", "hz", peer.topic], domain_id=peer.domain_id,
                 log=tmp_path / "hz.log") as hz:
        text = hz.wait_for(lambda t: t.count("window:") >= 2)
    match = re.search(r"average rate: (\d+\.\d{3})\n\tmin: \d+\.\d{3}s max: \d+\.\d{3}s "
                      r"std dev: \d+\.\d{5}s window: \d+\n", text)
    assert match, text
    assert 10 < float(match.group(1)) < 30  # the peer publishes at 20 Hz
    with running([ros2_path(), "topic", "bw", peer.topic], domain_id=peer.domain_id,
                 log=tmp_path / "bw.log") as bw:
        text = bw.wait_for(lambda t: "Message size mean" in t)
    assert text.startswith(f"Subscribed to [{peer.topic}]\n")
    assert re.search(r"\d+ B/s from \d+ messages\n\tMessage size mean: \d+ B min: \d+ B "
                     r"max: \d+ B\n", text), text


def test_pub_once_reaches_the_subscriber(peer: Peer) -> None:
    out = run(peer, "topic", "pub", "--once", peer.topic + "_in", "std_msgs/msg/String",
              "{data: hi from pub}")
    assert "publisher: beginning loop\n" in out
    assert "publishing #1: std_msgs.msg.String(data='hi from pub')\n" in out
    peer.process.wait_for(lambda t: "received: hi from pub" in t)


def test_node_list_and_info(peer: Peer) -> None:
    assert "/cli_peer" in run(peer, "node", "list").splitlines()
    info = run(peer, "node", "info", "/cli_peer")
    assert info.startswith("/cli_peer\n  Subscribers:\n")
    assert "  Publishers:\n" in info and f"    {peer.topic}: std_msgs/msg/String\n" in info
    assert f"    {peer.topic}_in: std_msgs/msg/String\n" in info
    assert ("    /cli_peer/check: efficient_comm_interfaces/srv/UnloadComponent\n" in info)
    assert info.endswith("  Action Servers:\n  Action Clients:\n")


def test_param_verbs(peer: Peer, tmp_path: Path) -> None:
    expected = {"count": "Integer value is: 5", "gain": "Double value is: 1.5",
                "label": "String value is: hello", "enabled": "Boolean value is: True",
                "ids": "Integer values are: [1, 2, 3]"}
    for name, line in expected.items():
        assert run(peer, "param", "get", "/cli_peer", name) == line + "\n"
    listed = run(peer, "param", "list", "/cli_peer").splitlines()
    assert {"  count", "  gain", "  nested.depth", "  use_sim_time"} <= set(listed)
    assert run(peer, "param", "set", "/cli_peer", "count", "9") == "Set parameter successful\n"
    assert run(peer, "param", "get", "/cli_peer", "count") == "Integer value is: 9\n"
    refused = ros2("param", "set", "/cli_peer", "count", "many", domain_id=peer.domain_id)
    assert refused.returncode == 1 and refused.stderr.startswith("Setting parameter failed")
    dumped = yaml.safe_load(run(peer, "param", "dump", "/cli_peer"))
    params = dumped["/cli_peer"]["ros__parameters"]
    assert params["count"] == 9 and params["ids"] == [1, 2, 3] and params["nested"]["depth"] == 2
    file = tmp_path / "params.yaml"
    file.write_text("/cli_peer:\n  ros__parameters:\n    count: 11\n    label: loaded\n")
    loaded = run(peer, "param", "load", "/cli_peer", str(file))
    assert "Set parameter count successful\n" in loaded
    assert run(peer, "param", "get", "/cli_peer", "label") == "String value is: loaded\n"
    described = run(peer, "param", "describe", "/cli_peer", "count")
    assert described.startswith("Parameter name: count\n  Type: integer\n")


def test_param_load_takes_the_wildcard_and_unslashed_node_names(peer: Peer,
                                                                 tmp_path: Path) -> None:
    def load(text: str) -> str:
        file = tmp_path / "params.yaml"
        file.write_text(text)
        return run(peer, "param", "load", "/cli_peer", str(file))

    def get(name: str) -> str:
        return run(peer, "param", "get", "/cli_peer", name)

    assert "Set parameter label successful\n" in load(
        "/**:\n  ros__parameters:\n    label: from_wildcard\n")
    assert get("label") == "String value is: from_wildcard\n"
    load("cli_peer:\n  ros__parameters:\n    gain: 2.5\n")
    assert get("gain") == "Double value is: 2.5\n"
    # Both: the wildcard first, the node's own section wins; other nodes' sections are not
    # the node's business when it has its own.
    load("/**:\n  ros__parameters:\n    label: wild\n    count: 21\n"
         "/cli_peer:\n  ros__parameters:\n    label: own\n"
         "/other:\n  ros__parameters:\n    gain: 9.0\n")
    assert (get("label"), get("count"), get("gain")) == (
        "String value is: own\n", "Integer value is: 21\n", "Double value is: 2.5\n")
    file = tmp_path / "wild.yaml"
    file.write_text("/**:\n  ros__parameters:\n    label: x\n")
    refused = ros2("param", "load", "/cli_peer", str(file), "--no-use-wildcard",
                   domain_id=peer.domain_id)
    assert refused.returncode == 1 and len(refused.stderr.strip().splitlines()) == 1


def test_param_delete(peer: Peer) -> None:
    assert run(peer, "param", "delete", "cli_peer", "scratch") == \
        "Deleted parameter successfully\n"
    assert "  scratch" not in run(peer, "param", "list", "/cli_peer").splitlines()
    static = ros2("param", "delete", "/cli_peer", "count", domain_id=peer.domain_id)
    assert static.returncode == 1 and static.stderr.startswith("Deleting parameter failed")
    missing = ros2("param", "delete", "/nobody", "x", "--timeout", "1",
                   domain_id=peer.domain_id)
    assert missing.returncode == 1 and missing.stderr == "error: Node not found\n"


def test_relative_names_resolve_against_the_root_namespace(peer: Peer, tmp_path: Path) -> None:
    relative = peer.topic.lstrip("/")
    assert run(peer, "topic", "type", relative) == "std_msgs/msg/String\n"
    assert re.fullmatch(r"data: hello \d+\n---\n", run(peer, "topic", "echo", "--once",
                                                        relative))
    out = run(peer, "service", "call", "cli_peer/check",
              "efficient_comm_interfaces/srv/UnloadComponent", "{unique_id: 7}")
    assert "success=True" in out
    with running([ros2_path(), "topic", "hz", relative], domain_id=peer.domain_id,
                 log=tmp_path / "hz.log") as hz:
        hz.wait_for(lambda t: "window:" in t)
    bad = ros2("topic", "echo", "a b", domain_id=peer.domain_id)
    assert bad.returncode == 1 and bad.stderr.startswith("error: Invalid topic name 'a b'")
    assert len(bad.stderr.strip().splitlines()) == 1


def test_topic_find(peer: Peer) -> None:
    found = run(peer, "topic", "find", "std_msgs/msg/String").splitlines()
    assert found == sorted([peer.topic, peer.topic + "_in"])
    assert run(peer, "topic", "find", "-c", "--spin-time", "1", "std_msgs/msg/Bool") == "0\n"


def test_echo_csv_and_filter(peer: Peer) -> None:
    csv = run(peer, "topic", "echo", "--once", "--csv", peer.topic)
    assert re.fullmatch(r"hello \d+\n", csv), csv
    kept = run(peer, "topic", "echo", "--once", "--filter", "m.data.endswith('7')", peer.topic)
    assert re.fullmatch(r"data: hello \d*7\n---\n", kept), kept
    field = run(peer, "topic", "echo", "--once", "--field", "data", "--filter",
                "m.endswith('3')", peer.topic)
    assert re.fullmatch(r"hello \d*3\n---\n", field), field
    bad = ros2("topic", "echo", "--once", "--filter", "m.data ==", peer.topic,
               domain_id=peer.domain_id)
    assert bad.returncode == 1 and "--filter" in bad.stderr
    assert len(bad.stderr.strip().splitlines()) == 1


def test_service_verbs(peer: Peer) -> None:
    listed = run(peer, "service", "list", "-t").splitlines()
    assert "/cli_peer/check [efficient_comm_interfaces/srv/UnloadComponent]" in listed
    assert run(peer, "service", "type", "/cli_peer/check") == \
        "efficient_comm_interfaces/srv/UnloadComponent\n"
    out = run(peer, "service", "call", "/cli_peer/check",
              "efficient_comm_interfaces/srv/UnloadComponent", "{unique_id: 7}")
    assert ("requester: making request: "
            "efficient_comm_interfaces.srv.UnloadComponent_Request(unique_id=7)\n\n") in out
    assert ("response:\nefficient_comm_interfaces.srv.UnloadComponent_Response("
            "success=True, error_message='got 7')\n\n") in out
    bad = ros2("service", "call", "/cli_peer/check",
               "efficient_comm_interfaces/srv/UnloadComponent", "{unique: 7}",
               domain_id=peer.domain_id)
    assert bad.returncode == 1 and "unique" in bad.stderr
    assert len(bad.stderr.strip().splitlines()) == 1 and "Traceback" not in bad.stderr


def test_service_call_converts_the_request_by_the_fields_type(peer: Peer) -> None:
    srv = "efficient_comm_interfaces/srv/UnloadComponent"
    out = run(peer, "service", "call", "/cli_peer/check", srv, "{unique_id: '7'}")
    assert "success=True, error_message='got 7'" in out
    piped = ros2("service", "call", "--stdin", "/cli_peer/check", srv,
                 domain_id=peer.domain_id, stdin="unique_id: 7\n")
    assert "success=True, error_message='got 7'" in piped.stdout, piped.stderr
    for bad in ("{unique_id: seven}", "{unique_id: -1}"):
        result = ros2("service", "call", "/cli_peer/check", srv, bad, domain_id=peer.domain_id)
        assert result.returncode == 1 and "unique_id" in result.stderr, result.stderr
        assert len(result.stderr.strip().splitlines()) == 1 and "making request" not in \
            result.stdout


def test_run_and_pkg() -> None:
    domain_id = isolated_domain_id()
    prefix = ros2("pkg", "prefix", "efficient_comm", domain_id=domain_id).stdout.strip()
    assert prefix == str(ROOT / "ros2_ws" / "install" / "efficient_comm")
    assert "efficient_comm" in ros2("pkg", "list", domain_id=domain_id).stdout.splitlines()
    assert "efficient_comm standalone" in \
        ros2("pkg", "executables", "efficient_comm", domain_id=domain_id).stdout.splitlines()
    result = ros2("run", "--prefix", "echo PREFIX", "efficient_comm", "standalone", "--x", "y",
                  domain_id=domain_id)
    assert result.stdout == f"PREFIX {prefix}/lib/efficient_comm/standalone --x y\n"
    missing = ros2("run", "efficient_comm", "nope", domain_id=domain_id)
    assert missing.returncode == 1 and "standalone" in missing.stderr


def test_interface_verbs() -> None:
    domain_id = isolated_domain_id()
    listed = ros2("interface", "list", domain_id=domain_id).stdout.splitlines()
    assert listed[0] == "Messages:" and "    std_msgs/msg/String" in listed
    assert "Services:" in listed and "    rcl_interfaces/srv/GetParameters" in listed
    package = ros2("interface", "package", "std_msgs", domain_id=domain_id).stdout
    assert "std_msgs/msg/Header\n" in package
    shown = ros2("interface", "show", "std_msgs/msg/Header", domain_id=domain_id).stdout
    assert "builtin_interfaces/Time stamp\n\tint32 sec\n\tuint32 nanosec\n" in shown
    assert "string frame_id\n" in shown


@pytest.mark.parametrize("args, offered", [
    (["launch", "x"], "bag, component"),
    (["topic", "delay", "x"], "list, info, find, type, echo, hz, bw, pub"),
    (["topic", "echo", "/x", "--no-lost-messages"], "--once"),
])
def test_what_is_not_offered_says_what_is(args: list[str], offered: str) -> None:
    result = ros2(*args, domain_id=isolated_domain_id())
    assert result.returncode == 2
    assert offered in result.stderr and "regular ROS 2 install" in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1 and "Traceback" not in result.stderr


def test_the_workspace_installs_no_ros2_command() -> None:
    """Only the venv's launcher is called ros2: a sourced regular install keeps ros2cli's."""
    install = ROOT / "ros2_ws" / "install"
    assert not [p for p in install.glob("**/ros2") if p.is_file()]
    assert (ROOT / ".venv" / "bin" / "ros2").is_file()
    assert "entry_points" not in (ROOT / "ros2_ws/src/ros2_pip_cli/setup.py").read_text()


def test_the_command_imports_rclpy_only_for_verbs_that_read_the_graph() -> None:
    """``ros2 run`` and ``ros2 pkg`` answered after importing rclpy and the graph node (about
    0.3 s of the 0.5 s a ``ros2 pkg prefix`` took); the suite runs them by the hundred."""
    probe = ("import sys\nimport ros2_pip_cli, ros2_pip_cli._pkg\n"
             "print('rclpy' in sys.modules)")
    loaded = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True,
                            timeout=60, check=True).stdout.strip()
    assert loaded == "False"
