"""Time across processes: ``/clock`` published by ``ros2 topic pub`` (as a simulator would)
drives a container's timers and a standalone node's clock, and a clock that goes back is not
followed; container processes started with ``--clock-offset`` run skewed."""

from __future__ import annotations

import functools
import shutil
import subprocess
import time
from collections.abc import Callable
from contextlib import AbstractContextManager, ExitStack
from pathlib import Path

from efficient_comm import STATS_TOPIC, Container, SimClock, Standalone, from_msg
from efficient_comm.dds import prepare_process
from efficient_comm.handle import NodeHandle
from efficient_comm.testing import isolated_domain_id
from efficient_comm_interfaces.msg import ExecutorStats

from ._ros import child, executable, peer

# This process composes (a Container with DDS below): prepare its DDS before any participant.
prepare_process()

MS = 1_000_000


class Ticker:
    """Remembers the clock's reading at each of its timer's calls."""

    def __init__(self, node: NodeHandle) -> None:
        self.node = node
        self.calls: list[int] = []
        node.create_timer(0.1, lambda: self.calls.append(node.clock.now_ns()))


def _clock_source(
    domain: int, time_ns: int, log: Path
) -> AbstractContextManager[subprocess.Popen[bytes]]:
    """``ros2 topic pub`` of one /clock time, repeated until stopped."""
    ros2 = shutil.which("ros2")
    assert ros2, "the ros2 command (ros2_pip_cli) is not on PATH"
    sec, nanosec = divmod(time_ns, 1_000_000_000)
    return child([ros2, "topic", "pub", "-r", "20", "/clock", "rosgraph_msgs/msg/Clock",
                  f"{{clock: {{sec: {sec}, nanosec: {nanosec}}}}}"], domain_id=domain, log=log)


def test_container_timers_follow_clock_of_another_process(tmp_path: Path) -> None:
    domain = isolated_domain_id()
    with Container("follower", sim_time=True, domain_id=domain, stats_period_s=0) as c:
        ticker: Ticker = c.add(Ticker, name="ticker")
        clock = c.executor.clock
        assert isinstance(clock, SimClock) and ticker.node.clock_kind == "sim"
        with _clock_source(domain, 350 * MS, tmp_path / "pub1.log"):
            assert c.spin_until(lambda: clock.now_ns() == 350 * MS, timeout_s=60)
        # Each timer call at its own deadline, not when the message happened to arrive.
        assert ticker.calls == [100 * MS, 200 * MS, 300 * MS]
        with _clock_source(domain, 200 * MS, tmp_path / "pub2.log"):
            assert c.spin_until(lambda: clock.ignored > 0, timeout_s=60)
        assert clock.now_ns() == 350 * MS and len(ticker.calls) == 3  # never backwards


def _spin_until(node: Standalone, predicate: Callable[[], bool], timeout_s: float = 60) -> None:
    end = time.monotonic() + timeout_s
    while not predicate():
        assert time.monotonic() < end, "timed out"
        node.spin_once(0.1)


def test_standalone_follows_clock_of_another_process(tmp_path: Path) -> None:
    domain = isolated_domain_id()
    with Standalone(Ticker, name="ticker", sim_time=True, domain_id=domain) as node:
        handle = node.handle
        rclpy_clock = node.node.get_clock()
        assert handle.clock_kind == "sim" and handle.clock.now_ns() == 0
        with _clock_source(domain, 350 * MS, tmp_path / "pub1.log"):
            _spin_until(node, lambda: handle.clock.now_ns() == 350 * MS)
        with _clock_source(domain, 200 * MS, tmp_path / "pub2.log"):
            # rclpy's own clock went back...
            _spin_until(node, lambda: rclpy_clock.now().nanoseconds == 200 * MS)
        assert handle.clock.now_ns() == 350 * MS  # ...the handle's did not


def _skew_of(seen: dict[str, int], ns: str, msg: ExecutorStats) -> None:
    seen.setdefault(ns, from_msg(msg.stamp) - time.time_ns())


def test_container_processes_run_on_their_own_skewed_clocks(tmp_path: Path) -> None:
    """Two robot containers as separate computers: ``--clock-offset`` of +100 s and -50 s.
    Their components' time (the stamp of the statistics they publish) is off by that much."""
    domain = isolated_domain_id()
    exe = executable("efficient_comm", "container")
    offsets = {"/fast": 100.0, "/slow": -50.0}
    seen: dict[str, int] = {}  # namespace -> stamp minus this process's clock at receipt
    with peer(domain) as p, ExitStack() as stack:
        for ns, offset in offsets.items():
            p.node.create_subscription(ExecutorStats, f"{ns}/{STATS_TOPIC}",
                                       functools.partial(_skew_of, seen, ns), 10)
            stack.enter_context(child(
                [exe, "--name", f"robot{ns.replace('/', '_')}", "--stats-namespace", ns,
                 "--stats-period", "0.2", "--clock-offset", str(offset)],
                domain_id=domain, log=tmp_path / f"{ns[1:]}.log",
            ))
        assert p.wait_for(lambda: len(seen) == len(offsets), timeout_s=60), seen
    for ns, offset in offsets.items():
        # A second of slack for delivery on a loaded machine, against offsets of 50 s+.
        assert abs(seen[ns] - offset * 1e9) < 1e9, (ns, seen[ns])
