"""ClockSync as real processes over DDS: a reference and two robots with skewed clocks.

Each robot process skews its own clock (``sim_offset_ns``, ``sim_drift_ppm``) from the
moment it starts, so the truth is known: robot time = system time + offset + drift since
start. Another process (this test's peer) reads the published estimates and checks them.
"""

from __future__ import annotations

import time
from contextlib import ExitStack
from pathlib import Path

from efficient_comm import from_msg
from efficient_comm.testing import isolated_domain_id
from team_clock.sync import OFFSET_QOS, OFFSET_TOPIC
from team_clock_interfaces.msg import ClockOffset

from ._ros import child, executable, peer

MS = 1_000_000


def test_robots_in_separate_processes_estimate_their_skew(tmp_path: Path) -> None:
    domain = isolated_domain_id()
    exe = executable("team_clock", "clock_sync")
    robots = {"ref": (0, 0.0), "a": (250 * MS, 50.0), "b": (-400 * MS, -50.0)}
    latest: dict[str, ClockOffset] = {}
    with peer(domain) as p, ExitStack() as stack:
        def on_offset(msg: ClockOffset) -> None:
            latest[msg.robot] = msg

        p.node.create_subscription(ClockOffset, OFFSET_TOPIC, on_offset, OFFSET_QOS)
        started = time.time_ns()
        for robot, (offset, drift) in robots.items():
            stack.enter_context(child(
                [exe, "--ros-args", "-r", f"__node:=clock_sync_{robot}",
                 "-p", f"robot:={robot}", "-p", "reference:=ref", "-p", "period_s:=0.2",
                 "-p", f"sim_offset_ns:={offset}", "-p", f"sim_drift_ppm:={drift}"],
                domain_id=domain, log=tmp_path / f"{robot}.log"))

        def ready() -> bool:
            return all(r in latest and latest[r].valid and latest[r].samples >= 10
                       for r in ("a", "b"))

        if not p.wait_for(ready, timeout_s=40.0):
            logs = "\n".join(f.read_text() for f in sorted(tmp_path.glob("*.log")))
            raise AssertionError(f"no estimates with 10 samples: {latest}\n{logs}")
        elapsed_s = (time.time_ns() - started) / 1e9
        for robot in ("a", "b"):
            msg = latest[robot]
            offset, drift = robots[robot]
            # Every robot hears the reference here; a relay through the other robot (two
            # hops) is allowed only when it was the tighter estimate at that moment.
            assert msg.reference == "ref" and msg.valid
            assert (msg.source, msg.hops) in (("ref", 1), ({"a": "b", "b": "a"}[robot], 2))
            # Truth: -(offset + drift * time since the robot started); the start is known to
            # within the test's run time, so allow that much drift on top of the bound.
            allowance = abs(drift) * 1e-6 * elapsed_s * 1e9
            error = abs(msg.offset_ns + offset)
            assert error <= msg.uncertainty_ns + allowance, (robot, msg)
            assert msg.uncertainty_ns < 20 * MS  # loopback: a tight bound, not a vague one
            assert abs(from_msg(msg.stamp) - time.time_ns() - offset) < 2_000 * MS
        assert latest["ref"].valid and latest["ref"].offset_ns == 0
