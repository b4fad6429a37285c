"""Lockstep between network namespaces: robots as on separate machines, joined by a link.

The world and robot blue1 run in namespace A, robot red1 in namespace B, joined by a veth
pair (the namespace link of tests/test_rf_bridge_team.py: 2 Mbit/s token bucket). DDS
discovers over the link (static peers, no shared memory, so every sample crosses it), and
the seeded run must print the same lines as the same run on one loopback: lockstep makes
the game independent of where the processes run. Root only (network namespaces).
"""

from __future__ import annotations

import json
import subprocess
import sys
from collections.abc import Iterator, Sequence
from contextlib import ExitStack, contextmanager
from pathlib import Path

from efficient_comm.testing import isolated_domain_id, ros_env, stop_process_group

from .test_rf_bridge_team import Link
from .test_rf_bridge_team import link as link  # the fixture: two namespaces and a veth

EXAMPLE = [sys.executable, "-m", "efficient_comm.examples.lockstep"]
STEPS = 40


def _env(domain: int, peer: str | None) -> dict[str, str]:
    env = ros_env(domain)
    if peer is not None:  # across the link: discovery beyond loopback, no shared memory
        env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "SUBNET"
        env["ROS_STATIC_PEERS"] = peer
        env["FASTDDS_BUILTIN_TRANSPORTS"] = "UDPv4"
    return env


@contextmanager
def _robot(ns: str | None, name: str, peer: str, env: dict[str, str],
           log: Path) -> Iterator[subprocess.Popen[bytes]]:
    prefix: Sequence[str] = ["ip", "netns", "exec", ns] if ns is not None else []
    with open(log, "wb") as out:
        proc = subprocess.Popen(
            [*prefix, *EXAMPLE, "robot", "--name", name, "--peer", peer, "--seed", "5"],
            env=env, stdout=out, stderr=subprocess.STDOUT, start_new_session=True,
        )
        try:
            yield proc
        finally:
            stop_process_group(proc)


def _game(tmp: Path, lk: Link | None) -> list[str]:
    """The world and blue1 in namespace A, red1 in B (or all three on this loopback)."""
    domain = isolated_domain_id()
    env_a = _env(domain, lk.addr_b if lk else None)
    env_b = _env(domain, lk.addr_a if lk else None)
    ns_a, ns_b = (lk.ns_a, lk.ns_b) if lk else (None, None)
    with ExitStack() as stack:
        stack.enter_context(_robot(ns_a, "blue1", "red1", env_a, tmp / "blue1.log"))
        stack.enter_context(_robot(ns_b, "red1", "blue1", env_b, tmp / "red1.log"))
        prefix = ["ip", "netns", "exec", ns_a] if ns_a else []
        world = subprocess.run(
            [*prefix, *EXAMPLE, "world", "--robots", "blue1", "red1", "--steps", str(STEPS),
             "--timeout", "30"],
            env=env_a, capture_output=True, text=True, timeout=240,
        )
    assert world.returncode == 0, world.stderr
    assert f"done {STEPS} steps" in world.stdout
    return [line for line in world.stdout.splitlines() if " value " in line]


def _received_bytes(lk: Link) -> int:
    """What namespace B's end of the veth received so far."""
    out = subprocess.run(["ip", "-n", lk.ns_b, "-s", "-j", "link", "show"],
                         capture_output=True, text=True, check=True, timeout=20).stdout
    return sum(dev["stats64"]["rx"]["bytes"] for dev in json.loads(out)
               if dev["ifname"] != "lo")


def test_lockstep_across_namespaces_plays_the_same_game(link: Link, tmp_path: Path) -> None:
    local = _game(tmp_path, None)
    before = _received_bytes(link)
    split = _game(tmp_path, link)
    assert len(split) == 2 * STEPS
    assert split == local
    # red1 heard the world's steps and blue1's values through the link, not around it.
    assert _received_bytes(link) - before > STEPS * 200
