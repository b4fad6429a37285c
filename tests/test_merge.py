"""The ``team_clock`` command (and the ``player`` beside it) as a user types them: robots'
logs merged in reference time, and bad input answered in one line, never a traceback.

The merge itself is tested in team_clock's own suite (ros2_ws/src/team_clock/test).
"""

from __future__ import annotations

import subprocess
from pathlib import Path

from geometry_msgs.msg import PointStamped
from mcap.reader import make_reader
from rclpy.serialization import serialize_message

from efficient_comm import to_msg
from rosbag2_layout import BagWriter
from team_clock.testing import SimDelay, SimTeam

from ._ros import executable

MS = 1_000_000
EVENT_TYPE = "geometry_msgs/msg/PointStamped"


def _run(package: str, name: str, *args: str | Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([str(executable(package, name)), *map(str, args)],
                          capture_output=True, text=True, timeout=60)


def _points(path: Path, *, count: int, start_ns: int, chunk_bytes: int = 1 << 20) -> Path:
    """A log of ``count`` stamped points 10 ms apart and no clock estimate."""
    with BagWriter(path, min_free_bytes=0, chunk_bytes=chunk_bytes) as writer:
        for k in range(count):
            point = PointStamped()
            point.header.stamp = to_msg(start_ns + k * 10 * MS)
            writer.write("/points", EVENT_TYPE, bytes(serialize_message(point)),
                         start_ns + k * 10 * MS)
    return path


def test_console_script_merges_a_simulated_team(tmp_path: Path) -> None:
    team = SimTeam({"ref": (1000 * MS, 0.0), "a": (250 * MS, 50.0)}, reference="ref",
                   links=[("ref", "a")], loss=0.1, seed=3,
                   delay=SimDelay(min_s=0.001, jitter_s=0.002))
    paths, _ = team.record_flashes(tmp_path, events=10, seed=3)
    done = _run("team_clock", "team_clock", "merge", "-o", tmp_path / "m", paths["ref"],
                paths["a"])
    assert done.returncode == 0, done.stderr
    assert "merged" in done.stdout


def test_commands_refuse_foreign_and_damaged_inputs_in_one_line(tmp_path: Path) -> None:
    good = _points(tmp_path / "good.mcap", count=300, start_ns=10**18, chunk_bytes=2048)
    with open(good, "rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None
    chunk = sorted(summary.chunk_indexes, key=lambda c: c.chunk_start_offset)[1]
    flipped = bytearray(good.read_bytes())
    flipped[chunk.chunk_start_offset + chunk.chunk_length // 2] ^= 0xFF
    corrupt = tmp_path / "corrupt.mcap"
    corrupt.write_bytes(bytes(flipped))
    foreign = tmp_path / "notes.mcap"
    foreign.write_text("not a log")
    bad_meta = tmp_path / "bad_meta"
    bad_meta.mkdir()
    (bad_meta / "metadata.yaml").write_text("rosbag2_bagfile_information: [unclosed\n")
    for log in (foreign, bad_meta, corrupt, tmp_path / "missing"):
        runs = [_run("team_clock", "team_clock", "merge", "-o", tmp_path / f"out_{log.name}",
                     f"a={log}"),
                _run("team_clock", "team_clock", "merge", "-o", tmp_path / f"out2_{log.name}",
                     "--assume-synced", "a", f"a={log}")]
        if log is not corrupt:  # offsets and the player read only what they need first
            runs += [_run("team_clock", "team_clock", "offsets", log),
                     _run("robot_recorder", "player", log)]
        for done in runs:
            assert done.returncode == 1, (log, done.args, done.stdout, done.stderr)
            lines = done.stderr.strip().splitlines()
            assert len(lines) == 1 and "error:" in lines[0], (log, done.args, done.stderr)
        assert not (tmp_path / f"out_{log.name}").exists()
        assert not (tmp_path / f"out2_{log.name}").exists()


def test_assume_synced_states_a_zero_bound_not_one_grown_since_1970(tmp_path: Path) -> None:
    today = 1_700_000_000 * 1_000_000_000  # far from the epoch, as every real log is
    laptop = _points(tmp_path / "laptop.mcap", count=3, start_ns=today)
    later = _points(tmp_path / "later.mcap", count=3, start_ns=today + 3600 * 10**9)
    done = _run("team_clock", "team_clock", "merge", "-o", tmp_path / "out",
                "--assume-synced", "laptop", "--assume-synced", "later",
                f"laptop={laptop}", f"later={later}")
    assert done.returncode == 0, done.stderr
    bounds = [line for line in done.stdout.splitlines() if "offset ±" in line]
    assert len(bounds) == 2
    assert all("offset ±0.000 ms" in line for line in bounds), bounds
