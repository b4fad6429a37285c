"""Two robots' team layers over rf_bridge's real team link.

Each robot is a process of its own (tests/_team_robot.py: TeamComm and rf_bridge composed,
on a DDS domain of its own) in a network namespace of its own, the two joined by a veth
pair (the link fixture of tests/test_rf_bridge_team.py, with its bandwidth limit). Robot 1
sees the ball, robot 2 does not: over the link, robot 2 knows where the ball is, the two
agree on striker and supporter, and each sends within the link's byte budget, as rf_bridge
counts it and as the veth counts it (everything on the wire). Then the
veth goes down: each robot ages its teammate out and plays striker alone.
"""

from __future__ import annotations

import contextlib
import json
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from efficient_comm.testing import isolated_domain_id, ros_env, stop_process_group
from rf_bridge.testing import LineReader, free_port

from .test_rf_bridge_team import Link, start
from .test_rf_bridge_team import link as link

ROBOT = str(Path(__file__).with_name("_team_robot.py"))
BUDGET = 2048  # bytes per second and robot


def _status(reader: LineReader, predicate: Callable[[dict[str, Any]], bool],
            timeout_s: float) -> dict[str, Any]:
    """The first status line (after those already read) for which ``predicate`` holds."""
    deadline = time.monotonic() + timeout_s
    last: dict[str, Any] = {}
    while time.monotonic() < deadline:
        line = reader.next(max(0.1, deadline - time.monotonic()))
        if not line.startswith("{"):
            continue
        last = json.loads(line)
        if predicate(last):
            return last
    raise AssertionError(f"not in {timeout_s} s; the last status: {last}")


def _veth_bytes(link: Link) -> tuple[int, int]:
    """Bytes robot 1's end of the veth has sent and received (all that crossed)."""
    shown = subprocess.run(["ip", "-n", link.ns_a, "-s", "-j", "link", "show", link.dev_a],
                           check=True, capture_output=True, text=True, timeout=20).stdout
    stats = json.loads(shown)[0]["stats64"]
    return int(stats["tx"]["bytes"]), int(stats["rx"]["bytes"])


def test_two_robots_share_the_ball_and_roles_within_budget_and_part_when_cut(
        link: Link) -> None:
    port = free_port()
    topic = {"ros2": "team/messages", "type": "soccer_interfaces/msg/TeamMessage",
             "peer": "team", "direction": "both"}
    team = {"prefix": "team_play", "budget_bytes_per_s": BUDGET, "budget_burst_bytes": BUDGET}
    parameters = {"team_number": 1, "teammate_timeout_s": 2.0, "role_min_hold_s": 0.5}
    robots = [
        (link.ns_a, {"config": {"team": {**team, "robot_id": "blue1",
                                         "listen": [f"tcp/{link.addr_a}:{port}"]},
                                "topics": [topic]},
                     "parameters": {**parameters, "player_number": 1},
                     "pose": [-1.0, 0.0, 0.0], "ball": [0.5, 0.2]}),
        (link.ns_b, {"config": {"team": {**team, "robot_id": "blue2",
                                         "connect": [f"tcp/{link.addr_a}:{port}"]},
                                "topics": [topic]},
                     "parameters": {**parameters, "player_number": 2},
                     "pose": [-3.0, 1.0, 0.0], "ball": None}),
    ]
    procs: list[subprocess.Popen[bytes]] = []
    try:
        readers = []
        for ns, args in robots:
            env = ros_env(isolated_domain_id())  # a domain each, as separate computers
            proc, reader = start(ns, [sys.executable, ROBOT, json.dumps(args)], env)
            procs.append(proc)
            readers.append(reader)
        one, two = readers
        # Robot 2 sees no ball but knows where it is from robot 1, and both agree on roles.
        _status(one, lambda s: s["mates"] == [2] and s["role"] == "striker", 60)
        shared = _status(two, lambda s: s["mates"] == [1] and s["ball"] is not None
                         and s["role"] == "supporter", 30)
        bx, by, sources = shared["ball"]
        assert abs(bx - 0.5) < 1e-3 and abs(by - 0.2) < 1e-3 and sources == [1]
        # Within the budget: a few seconds of exchange, every message sent, none refused;
        # on the wire too (Zenoh's framing, TCP/IP and Ethernet headers, acknowledgements).
        wire_before, wire_start = _veth_bytes(link), time.monotonic()
        for reader in readers:
            first = _status(reader, lambda s: True, 5)["usage"]
            until_s: float = first["elapsed_s"] + 4.0

            def later_than(s: dict[str, Any], t: float = until_s) -> bool:
                return bool(s["usage"]["elapsed_s"] > t)

            later = _status(reader, later_than, 10)["usage"]
            sent = later["sent_bytes"] - first["sent_bytes"]
            seconds = later["elapsed_s"] - first["elapsed_s"]
            messages = later["sent_messages"] - first["sent_messages"]
            assert 6 <= messages <= 11, later  # 2 Hz
            assert sent / messages < 100  # bytes per message, attachment included
            assert sent / seconds <= BUDGET and later["peak_bytes_per_s"] <= BUDGET
            assert later["over_budget"] == 0 and later["received_messages"] > 0
        wire_after, wire_s = _veth_bytes(link), time.monotonic() - wire_start
        for before, after in zip(wire_before, wire_after, strict=True):
            assert 0 < (after - before) / wire_s <= BUDGET, (wire_before, wire_after, wire_s)
        # The link is cut: each robot ages its teammate out and plays striker alone.
        link.ip("-n", link.ns_a, "link", "set", link.dev_a, "down")
        for reader in readers:
            _status(reader, lambda s: s["mates"] == [] and s["role"] == "striker", 30)
    finally:
        for proc in procs:
            with contextlib.suppress(ProcessLookupError):
                stop_process_group(proc, sig=9, timeout_s=10)
            for pipe in (proc.stdin, proc.stdout):
                if pipe is not None:
                    pipe.close()
