"""ClockSync as real processes over DDS: a reference and two robots with skewed clocks.

The last test runs three robots as their users deploy them: each a container process with
its clock sync and its recorder, all on one DDS domain, so every recorder hears every
robot's estimates.

Each robot process skews its own clock (``sim_offset_ns``, ``sim_drift_ppm``) from the
moment it starts, so the truth is known: robot time = system time + offset + drift since
start. Another process (this test's peer) reads the published estimates and checks them.
"""

from __future__ import annotations

import os
import signal
import subprocess
import time
from collections.abc import Callable
from contextlib import ExitStack
from pathlib import Path
from typing import Any

from rosbags.highlevel import AnyReader

from efficient_comm import from_msg
from efficient_comm.testing import isolated_domain_id
from robot_recorder_interfaces.msg import RecorderStatus
from team_clock.merge import RobotLog, merge
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


def _robot_file(path: Path, robot: str, offset_ns: int, out: Path) -> Path:
    """A container file for one robot: its clock sync and its recorder, side by side."""
    path.write_text(f"""\
components:
  - class: team_clock.sync:ClockSync
    name: clock_sync
    namespace: /{robot}
    parameters:
      /{robot}/clock_sync:
        ros__parameters: {{robot: {robot}, reference: a, period_s: 0.2,
                           sim_offset_ns: {offset_ns}}}
  - class: robot_recorder.recorder:Recorder
    name: recorder
    namespace: /{robot}
    parameters:
      /{robot}/recorder:
        ros__parameters: {{output_dir: {out}, autostart: true, status_period_s: 0.2,
                           min_free_bytes: 0}}
""")
    return path


def _recorded_estimates(bag: Path) -> tuple[set[str], set[str]]:
    """Robots named by the estimates a bag holds: as messages, and as file metadata."""
    from team_clock.bag import LogReader
    from team_clock.model import METADATA_NAME

    with AnyReader([bag]) as reader:
        conns = [c for c in reader.connections if c.topic == OFFSET_TOPIC]
        in_messages = set()
        for c, _, raw in reader.messages(connections=conns):
            msg: Any = reader.deserialize(raw, c.msgtype)
            in_messages.add(str(msg.robot))
    in_metadata = {values.get("robot", "") for name, values in LogReader(bag).metadata()
                   if name == METADATA_NAME}
    return in_messages, in_metadata


def test_three_robots_on_one_domain_each_log_their_own_clock(tmp_path: Path) -> None:
    """Each robot's log holds its own estimates; ``merge b=LOG`` is robot b or refused."""
    domain = isolated_domain_id()
    container_exe = executable("efficient_comm", "container")
    offsets = {"a": 0, "b": -400 * MS, "c": 250 * MS}  # a is the reference
    statuses: dict[str, RecorderStatus] = {}
    latest: dict[str, ClockOffset] = {}
    with peer(domain) as p, ExitStack() as stack:
        def on_offset(msg: ClockOffset) -> None:
            latest[msg.robot] = msg

        def on_status(robot: str) -> Callable[[RecorderStatus], None]:
            return lambda msg: statuses.__setitem__(robot, msg)

        p.node.create_subscription(ClockOffset, OFFSET_TOPIC, on_offset, OFFSET_QOS)
        procs = {}
        for robot, offset in offsets.items():
            p.node.create_subscription(RecorderStatus, f"/{robot}/recorder/status",
                                       on_status(robot), 10)
            config = _robot_file(tmp_path / f"{robot}.yaml", robot, offset, tmp_path / robot)
            procs[robot] = stack.enter_context(child(
                [container_exe, "--config", config, "--name", f"robot_{robot}"],
                domain_id=domain, log=tmp_path / f"{robot}.log"))

        def recorded(robot: str) -> int:
            status = statuses.get(robot)
            return sum(t.messages for t in status.topics
                       if t.name == OFFSET_TOPIC) if status else 0

        def ready() -> bool:
            return (all(r in latest and latest[r].valid and latest[r].samples >= 10
                        for r in ("b", "c"))
                    and all(recorded(r) >= 20 for r in offsets))

        if not p.wait_for(ready, timeout_s=60.0):
            logs = "\n".join(f.read_text() for f in sorted(tmp_path.glob("*.log")))
            raise AssertionError(f"not ready: {latest} {statuses}\n{logs}")
        for proc in procs.values():
            os.killpg(proc.pid, signal.SIGINT)
        for robot, proc in procs.items():
            assert proc.wait(30) == 0, (tmp_path / f"{robot}.log").read_text()

    bags = {}
    for robot in offsets:
        (bags[robot],) = [d for d in (tmp_path / robot).iterdir() if d.is_dir()]
        # Every recorder heard all three robots' estimates; each kept its own robot's.
        assert _recorded_estimates(bags[robot]) == ({robot}, {robot}), robot

    # Robot b's log aligns robot b: its offset is b's skew, within the bound it states.
    merged = tmp_path / "merged_b"
    report = merge([RobotLog(bags["b"], namespace="b")], merged)
    model = report.robots[0].model
    assert model.robot == "b" and model.reference == "a"
    # A bound that still tells the skews apart: ping round trips on a loaded two-core
    # machine take tens of ms (25 ms seen), an idle one a few. What matters is below:
    # every stamp moved to within the bound the model states.
    assert report.robots[0].max_uncertainty_ns < 100 * MS
    with AnyReader([bags["b"]]) as before, AnyReader([merged]) as after:
        local = [t for _, t, _ in before.messages()]
        moved = [t for _, t, _ in after.messages()]
    assert len(local) == len(moved) == report.messages > 0
    for t_local, t_ref in zip(sorted(local), sorted(moved), strict=True):
        # Truth: reference time = robot b's time - b's skew.
        assert abs((t_ref - t_local) + offsets["b"]) <= model.uncertainty_at(t_local) + MS

    # Robot c's log named as robot b: refused in one line naming both, nothing written.
    out = tmp_path / "wrong"
    result = subprocess.run(
        [str(executable("team_clock", "team_clock")), "merge", "-o", str(out),
         f"b={bags['c']}"], capture_output=True, text=True, timeout=60)
    assert result.returncode == 1, result
    assert result.stderr.count("\n") == 1 and "Traceback" not in result.stderr
    assert "robot c" in result.stderr and "robot b" in result.stderr, result.stderr
    assert not out.exists()
    # Named right, the three logs merge.
    result = subprocess.run(
        [str(executable("team_clock", "team_clock")), "merge", "-o", str(tmp_path / "all"),
         *(f"{r}={bags[r]}" for r in offsets)], capture_output=True, text=True, timeout=60)
    assert result.returncode == 0, result.stderr
