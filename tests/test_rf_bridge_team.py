"""rf_bridge's robot-to-robot link between two network namespaces.

Robot A and robot B each run a bridge in their own network namespace, joined by a veth pair
with a token-bucket bandwidth limit (tc tbf). The kernel here has no netem, so packet loss
comes from a small UDP forwarder in B's namespace that drops a share of the datagrams both
ways; Zenoh runs over UDP through it. What arrives must be correct, what is lost must be
counted, and the link must come back after the veth goes down and up.
"""

from __future__ import annotations

import contextlib
import itertools
import json
import os
import subprocess
import sys
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest

from efficient_comm.testing import isolated_domain_id, ros_env
from rf_bridge.testing import LineReader, free_port, wait_for

ROBOT = r"""
import contextlib, json, sys, threading, time
from std_msgs.msg import String
from efficient_comm.dds import prepare_process
from rf_bridge import BridgeNode, parse_config
from rf_bridge.testing import rclpy_test_handle

prepare_process()
args = json.loads(sys.argv[1])
resources = contextlib.ExitStack()  # kept: the node lives as long as the program
node = resources.enter_context(rclpy_test_handle("robot"))
bridge = BridgeNode(node, config=parse_config(args["config"]))
commands = []
def read_commands():
    for line in sys.stdin:
        commands.append(line.split())
threading.Thread(target=read_commands, daemon=True).start()

def stats():
    return {f"{s.topic} {s.direction}": [s.messages, s.drops] for s in bridge.stats()}

print("ready", flush=True)
seen = {t["ros2"]: 0 for t in args["config"]["topics"] if t["direction"] == "from_peer"}
while True:
    node.container.executor.spin_once(0.02)
    for topic in seen:
        got = node.published(topic)
        for m in got[seen[topic]:]:
            print(json.dumps({"topic": topic, "data": m.data}), flush=True)
        seen[topic] = len(got)
    while commands:
        cmd = commands.pop(0)
        if cmd[0] == "send":  # send TOPIC FIRST COUNT RATE
            topic, first, count, rate = cmd[1], int(cmd[2]), int(cmd[3]), float(cmd[4])
            for i in range(first, first + count):
                node.inject(topic, String(data=f"{i} " + "x" * 200))
                time.sleep(1.0 / rate)
            print(json.dumps({"sent": topic, "last": first + count - 1}), flush=True)
        elif cmd[0] == "stats":
            print(json.dumps({"stats": stats()}), flush=True)
"""

FORWARDER = r"""
import random, select, socket, sys
listen_host, listen_port = sys.argv[1], int(sys.argv[2])
target_port, loss = int(sys.argv[3]), float(sys.argv[4])
rng = random.Random(7)
outer = socket.socket(socket.AF_INET, socket.SOCK_DGRAM); outer.bind((listen_host, listen_port))
inner = {}  # client address -> its own socket towards the target (as a NAT would)
client_of = {}
print("ready", flush=True)
while True:
    for s in select.select([outer, *inner.values()], [], [])[0]:
        data, addr = s.recvfrom(65535)
        if rng.random() < loss:
            continue
        if s is outer:
            if addr not in inner:
                sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
                sock.bind(("127.0.0.1", 0))
                inner[addr] = sock
                client_of[sock] = addr
            inner[addr].sendto(data, ("127.0.0.1", target_port))
        else:
            outer.sendto(data, client_of[s])
"""

_ids = itertools.count()


@dataclass
class Link:
    ns_a: str
    ns_b: str
    dev_a: str
    addr_a: str
    addr_b: str

    def ip(self, *args: str) -> None:
        subprocess.run(["ip", *args], check=True, capture_output=True, timeout=20)


NETNS_PREFIX = "rf_bridge_test_"


def _netns_of_dead_runs() -> list[str]:
    """Namespaces left by test runs that were killed before their cleanup ran (a hard
    timeout kills the process): their names carry the pid of the run that made them."""
    listed = subprocess.run(
        ["ip", "netns", "list"], capture_output=True, text=True, timeout=20
    ).stdout.split()
    stale = []
    for name in listed:
        if not name.startswith(NETNS_PREFIX):
            continue
        pid = name[len(NETNS_PREFIX) :].split("_")[0]
        if pid.isdigit() and not os.path.exists(f"/proc/{pid}"):
            stale.append(name)
    return stale


def _remove_netns(ns: str) -> None:
    """Kill what still runs in ``ns`` and delete it (its veth end goes with it)."""
    pids = subprocess.run(
        ["ip", "netns", "pids", ns], capture_output=True, text=True, timeout=20
    ).stdout.split()
    for pid in pids:
        with contextlib.suppress(ProcessLookupError):
            os.kill(int(pid), 9)
    subprocess.run(["ip", "netns", "del", ns], capture_output=True, timeout=20)


def _build(lk: Link, dev_b: str) -> None:
    lk.ip("netns", "add", lk.ns_a)
    lk.ip("netns", "add", lk.ns_b)
    lk.ip("link", "add", lk.dev_a, "type", "veth", "peer", "name", dev_b)
    lk.ip("link", "set", lk.dev_a, "netns", lk.ns_a)
    lk.ip("link", "set", dev_b, "netns", lk.ns_b)
    for ns, dev, addr in ((lk.ns_a, lk.dev_a, lk.addr_a), (lk.ns_b, dev_b, lk.addr_b)):
        lk.ip("-n", ns, "addr", "add", f"{addr}/24", "dev", dev)
        lk.ip("-n", ns, "link", "set", dev, "up")
        lk.ip("-n", ns, "link", "set", "lo", "up")
        tbf = ["tbf", "rate", "2mbit", "burst", "16kb", "latency", "100ms"]
        subprocess.run(
            ["tc", "-n", ns, "qdisc", "add", "dev", dev, "root", *tbf],
            check=True,
            capture_output=True,
            timeout=20,
        )


@pytest.fixture
def link() -> Iterator[Link]:
    if os.geteuid() != 0:
        pytest.skip("the team-link test needs root for network namespaces (CI runs as root)")
    for ns in _netns_of_dead_runs():
        _remove_netns(ns)
    k = next(_ids)
    n = f"{os.getpid() % 10000}{k}"  # interface names: at most 15 characters
    subnet = f"10.{200 + os.getpid() % 50}.{k % 250}"
    base = f"{NETNS_PREFIX}{os.getpid()}_{k}"
    lk = Link(f"{base}_a", f"{base}_b", f"rfa{n}", f"{subnet}.1", f"{subnet}.2")
    dev_b = f"rfb{n}"
    try:
        try:
            _build(lk, dev_b)
        except (subprocess.CalledProcessError, FileNotFoundError) as exc:
            pytest.fail(f"cannot build the namespace link (ip netns, veth, tc tbf needed): {exc}")
        yield lk
    finally:
        for ns in (lk.ns_a, lk.ns_b):
            _remove_netns(ns)
        # a veth that never reached its namespace is still in ours
        subprocess.run(["ip", "link", "del", lk.dev_a], capture_output=True, timeout=20)


def start(
    ns: str | None, args: list[str], env: dict[str, str], *, log: Path | None = None
) -> tuple[subprocess.Popen[bytes], LineReader]:
    """Start a program (in network namespace ``ns`` unless None), its stderr to ``log`` if
    given; wait for its "ready"."""
    with contextlib.ExitStack() as files:
        err = files.enter_context(open(log, "wb")) if log is not None else None
        proc = subprocess.Popen(
            ["ip", "netns", "exec", ns, *args] if ns is not None else args,
            env=env,
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=err,
            start_new_session=True,
        )
    reader = LineReader(proc)
    try:
        assert reader.next(60) == "ready"
    except AssertionError:
        os.killpg(proc.pid, 9)
        proc.wait(timeout=10)
        raise
    return proc, reader


def command(proc: subprocess.Popen[bytes], text: str) -> None:
    assert proc.stdin is not None
    proc.stdin.write(text.encode() + b"\n")
    proc.stdin.flush()


def until(reader: LineReader, key: str, timeout_s: float = 60) -> dict[str, object]:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        msg = json.loads(reader.next(max(0.1, deadline - time.monotonic())))
        if key in msg:
            return msg  # type: ignore[no-any-return]
    raise AssertionError(f"no {key!r} line in time")


def test_team_link_over_lossy_limited_link_recovers_after_outage(link: Link) -> None:
    env = ros_env(isolated_domain_id())
    port_b, port_fwd = free_port(), 7447
    topic, slow = "/team/ball", "/team/map"
    robot = {"prefix": "rf_team"}
    topics: list[dict[str, Any]] = [
        {"ros2": topic, "type": "std_msgs/msg/String", "peer": "team"},
        {
            "ros2": slow,
            "type": "std_msgs/msg/String",
            "peer": "team",
            "throttle": {"max_rate_hz": 10.0},
        },
    ]
    cfg_a = {
        "team": {**robot, "robot_id": "a", "connect": [f"udp/{link.addr_b}:{port_fwd}"]},
        "topics": [{**t, "direction": "to_peer"} for t in topics],
    }
    cfg_b = {
        "team": {**robot, "robot_id": "b", "listen": [f"udp/127.0.0.1:{port_b}"]},
        "topics": [
            {k: v for k, v in t.items() if k != "throttle"} | {"direction": "from_peer"}
            for t in topics
        ],
    }
    procs = []
    try:
        fwd, _ = start(
            link.ns_b,
            ["/usr/bin/python3", "-c", FORWARDER, link.addr_b, str(port_fwd), str(port_b), "0.05"],
            env,
        )
        procs.append(fwd)
        b, out_b = start(
            link.ns_b, [sys.executable, "-c", ROBOT, json.dumps({"config": cfg_b})], env
        )
        procs.append(b)
        a, out_a = start(
            link.ns_a, [sys.executable, "-c", ROBOT, json.dumps({"config": cfg_a})], env
        )
        procs.append(a)

        received: list[int] = []

        def collect(last: int, timeout_s: float) -> None:
            """Read B's lines until message ``last`` (or a later one) arrived or time passes."""
            deadline = time.monotonic() + timeout_s
            while time.monotonic() < deadline:
                for line in out_b.drain():
                    msg = json.loads(line)
                    if msg.get("topic") == topic:
                        i, pad = msg["data"].split(" ")
                        assert pad == "x" * 200  # what arrives is correct
                        received.append(int(i))
                if received and received[-1] >= last:
                    return
                time.sleep(0.05)

        # Wait until the link carries anything (Zenoh discovery through the lossy link).
        first = 0
        up_deadline = time.monotonic() + 40
        while not received:
            if time.monotonic() > up_deadline:
                command(a, "stats")
                pytest.fail(f"the team link never came up; a's counts: {until(out_a, 'stats')}")
            command(a, f"send {topic} {first} 10 50")
            until(out_a, "sent")
            first += 10
            collect(first - 1, 2.0)
        start_i = first

        def unheard() -> int:
            """What a counted as sent while b did not subscribe (the link was down long
            enough for Zenoh to notice, or not up yet): lost, but counted at a."""
            command(a, "stats")
            _, drops = until(out_a, "stats")["stats"][f"{topic} to_team"]  # type: ignore[index]
            return int(drops.get("no_subscriber", 0))

        unheard_before = unheard()  # the probes sent before the link was up
        command(a, f"send {topic} {start_i} 300 100")
        command(a, f"send {slow} 0 100 100")  # throttled to 10 Hz before the link
        until(out_a, "sent")
        until(out_a, "sent")
        collect(start_i + 299, 10.0)
        after = [i for i in received if i >= start_i]
        assert after == sorted(after) and len(set(after)) == len(after)
        command(b, "stats")
        stats_b = until(out_b, "stats")["stats"]
        command(a, "stats")
        stats_a = until(out_a, "stats")["stats"]
        msgs_b, drops_b = stats_b[f"{topic} from_team"]  # type: ignore[index]
        lost = drops_b.get("lost", 0)
        unheard_1 = unheard() - unheard_before
        # everything up to the last message received either arrived or is counted as lost,
        # by b (a gap in the sequence) or by a (sent while b was not subscribed)
        assert msgs_b + lost + unheard_1 == received[-1] - received[0] + 1, (
            msgs_b, lost, unheard_1, received[-1]
        )
        assert 0 < lost + unheard_1 < 0.35 * (received[-1] - received[0] + 1)
        sent_slow, drops_slow = stats_a[f"{slow} to_team"]  # type: ignore[index]
        assert drops_slow.get("throttled", 0) >= 60 and 5 <= sent_slow <= 40

        # Outage: the veth goes down, messages sent meanwhile are lost, then it comes back.
        link.ip("-n", link.ns_a, "link", "set", link.dev_a, "down")
        command(a, f"send {topic} {start_i + 300} 50 25")  # 2 s
        until(out_a, "sent")
        link.ip("-n", link.ns_a, "link", "set", link.dev_a, "up")
        nxt = start_i + 350
        recovered = False
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline and not recovered:
            command(a, f"send {topic} {nxt} 20 50")
            until(out_a, "sent")
            nxt += 20
            collect(nxt - 1, 2.0)
            recovered = any(i >= start_i + 350 for i in received)
        assert recovered, "the link did not recover after the outage"
        command(b, "stats")
        msgs_b, drops_b = until(out_b, "stats")["stats"][f"{topic} from_team"]  # type: ignore[index]
        unheard_2 = unheard() - unheard_before
        lost_2 = drops_b.get("lost", 0)
        assert msgs_b + lost_2 + unheard_2 == received[-1] - received[0] + 1
        # most of the 50 sent during the outage, counted on one side or the other
        assert (lost_2 - lost) + (unheard_2 - unheard_1) >= 30
    finally:
        for p in procs:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(p.pid, 9)
            p.wait(timeout=10)
            for pipe in (p.stdin, p.stdout):
                if pipe is not None:
                    pipe.close()


def test_team_link_both_ways_without_loops_and_across_a_restart() -> None:
    """Two robots in one process on loopback: a ``both`` topic crosses once each way and
    never comes back; a robot that restarts (sequence from 1 again) is heard at once."""
    from std_msgs.msg import String

    from efficient_comm.testing import TestHandle, unique_topic
    from rf_bridge import BridgeNode, parse_config
    from rf_bridge.testing import rclpy_test_handle

    port = free_port()
    topic = unique_topic("team")
    route = {"ros2": topic, "type": "std_msgs/msg/String", "peer": "team", "direction": "both"}
    handles = contextlib.ExitStack()

    def robot(rid: str, **link: list[str]) -> tuple[TestHandle, BridgeNode]:
        node = handles.enter_context(rclpy_test_handle(f"robot_{rid}"))
        cfg = parse_config({"team": {"robot_id": rid, "prefix": topic.strip("/"), **link},
                            "topics": [route]})
        return node, BridgeNode(node, config=cfg)

    a, bridge_a = robot("a", listen=[f"tcp/127.0.0.1:{port}"])
    b, bridge_b = robot("b", connect=[f"tcp/127.0.0.1:{port}"])
    spin = a.container.executor.spin_until
    try:
        def crossed(node: TestHandle, sender: TestHandle, text: str) -> bool:
            sender.inject(topic, String(data=text))
            return node.container.executor.spin_until(
                lambda: any(m.data == text for m in node.published(topic)), timeout_s=0.2)

        assert wait_for(lambda: crossed(b, a, "probe"), 20), "a -> b never connected"
        before = len(a.published(topic))
        b.inject(topic, String(data="from b"))
        assert spin(lambda: any(m.data == "from b" for m in a.published(topic)), timeout_s=10)
        assert len(a.published(topic)) == before + 1
        b.container.executor.spin_for(0.3)
        # b's own sample did not come back to b's ROS 2 side, a did not send it back
        assert [m.data for m in b.published(topic)].count("from b") == 1  # the injected one
        assert bridge_a.router.loops_suppressed >= 1
        bridge_a.close()
        a, bridge_a = robot("a", listen=[f"tcp/127.0.0.1:{port}"])
        assert wait_for(lambda: crossed(b, a, "after restart"), 20)
        stats_b = {s.direction: s for s in bridge_b.stats()}
        assert "out_of_order" not in stats_b["from_team"].drops
    finally:
        bridge_a.close()
        bridge_b.close()
        handles.close()


def test_samples_lost_while_a_peer_restarts_are_counted(tmp_path: Path) -> None:
    """Robot a streams to robot b (separate processes, loopback TCP); b is killed and
    started again meanwhile. Every message is received by one of b's lives or counted:
    by a while nobody subscribed (``no_subscriber``), or by b as a gap (``lost``); at
    most the few b had taken off the link but not printed at the kill go uncounted. The
    new b takes samples at once, before and while its ROS 2 side comes up, without an
    error."""
    env = ros_env(isolated_domain_id())
    port = free_port()
    topic = "/team/stream"
    route = {"ros2": topic, "type": "std_msgs/msg/String", "peer": "team"}
    cfg_a = {"team": {"robot_id": "a", "listen": [f"tcp/127.0.0.1:{port}"]},
             "topics": [{**route, "direction": "to_peer"}]}
    cfg_b = {"team": {"robot_id": "b", "connect": [f"tcp/127.0.0.1:{port}"]},
             "topics": [{**route, "direction": "from_peer"}]}
    robot_b = [sys.executable, "-c", ROBOT, json.dumps({"config": cfg_b})]
    procs = []

    def numbers(reader: LineReader) -> list[int]:
        return [int(json.loads(line)["data"].split(" ")[0])
                for line in reader.drain() if '"topic"' in line]

    try:
        a, out_a = start(None, [sys.executable, "-c", ROBOT, json.dumps({"config": cfg_a})],
                         env)
        procs.append(a)
        b1, out_b1 = start(None, robot_b, env)
        procs.append(b1)
        got: list[int] = []
        first = 0
        while not got:  # until the link carries messages
            assert first < 500, "the team link never came up"
            command(a, f"send {topic} {first} 10 50")
            until(out_a, "sent")
            first += 10
            time.sleep(0.2)
            got += numbers(out_b1)
        command(a, "stats")
        _, before = until(out_a, "stats")["stats"][f"{topic} to_team"]  # type: ignore[index]
        command(a, f"send {topic} 1000 1000 100")  # 10 s or more: b restarts meanwhile

        def streaming() -> bool:
            got.extend(numbers(out_b1))
            return any(n >= 1050 for n in got)

        assert wait_for(streaming, 20, poll_s=0.005)
        os.killpg(b1.pid, 9)
        b1.wait(timeout=10)
        b2, out_b2 = start(None, robot_b, env, log=tmp_path / "b2.log")
        procs.append(b2)
        until(out_a, "sent")
        time.sleep(0.5)  # the last samples in flight
        second = numbers(out_b2)  # before "stats", whose reading skips other lines
        command(b2, "stats")
        stats_b2 = until(out_b2, "stats")["stats"]
        command(a, "stats")
        _, after = until(out_a, "stats")["stats"][f"{topic} to_team"]  # type: ignore[index]
        got += numbers(out_b1)
        received = {n for n in got + second if n >= 1000}
        missing = 1000 - len(received)
        unheard = after.get("no_subscriber", 0) - before.get("no_subscriber", 0)
        _, drops_b2 = stats_b2[f"{topic} from_team"]  # type: ignore[index]
        counted = unheard + drops_b2.get("lost", 0)
        assert second and missing >= 20, (missing, second[:3])  # the restart cost messages
        # Uncounted: what b1 had taken off the link but not yet printed when it was killed
        # (up to 50 ms of the 100 Hz stream on a loaded machine; 3 were seen beside the
        # suite's other workers).
        assert 0 <= missing - counted <= 5, (missing, unheard, drops_b2)
        assert max(received) == 1999
        errors = (tmp_path / "b2.log").read_text()
        assert "Traceback" not in errors and "Error" not in errors, errors
    finally:
        for p in procs:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(p.pid, 9)
            p.wait(timeout=10)
            for pipe in (p.stdin, p.stdout):
                if pipe is not None:
                    pipe.close()
