"""Smoke test of bench/match_bench.py: the quick mode runs one short one-robot match in real
time and one in lockstep and reports every part of their CPU. No timing assertions: only
that each figure was measured."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

BENCH = Path(__file__).resolve().parents[1] / "bench" / "match_bench.py"


@pytest.mark.timeout(420)
def test_match_bench_quick(tmp_path: Path) -> None:
    out = tmp_path / "match.json"
    done = subprocess.run([sys.executable, str(BENCH), "--quick", "--out", str(out)],
                          capture_output=True, text=True, timeout=400, cwd=tmp_path)
    assert done.returncode == 0, done.stdout + done.stderr
    summary = json.loads(out.read_text())["summary"]
    for key in ("1v0", "1v0 lockstep"):  # real time and lockstep
        row = summary[key]
        for part in ("physics", "render", "bus", "world_other", "robot_software"):
            assert row[part] > 0, (key, part, row)
        assert row["rtf"] > 0 and row["tick_hz"] > 0 and row["imu_hz_min"] > 0, (key, row)
    assert summary["1v0"]["total_ratio"] == pytest.approx(1.0)
    assert "robot software" in done.stdout and "1v0 |" in done.stdout
    assert "1v0 lockstep |" in done.stdout
