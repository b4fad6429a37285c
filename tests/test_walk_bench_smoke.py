"""The walking benchmark runs end to end (one seed, a few seconds) and measures what it claims.

It asserts what the figures mean, not how fast this machine is: trials ran through the
driver and reported pass rates and drift per direction, every joint's servo peaks were
read, and the walk engine's cost was measured against the driver's cycle.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

BENCH = Path(__file__).resolve().parents[1] / "bench" / "walk_bench.py"


@pytest.mark.timeout(120)
def test_walk_bench_smoke(tmp_path: Path) -> None:
    out = tmp_path / "walk.json"
    result = subprocess.run(
        [sys.executable, str(BENCH), "--only", "cost", "--only", "reliability", "--seeds", "1",
         "--direction", "turning", "--seconds", "0.5", "--out", str(out)],
        capture_output=True, text=True, timeout=115, check=False)
    assert result.returncode == 0, result.stdout + result.stderr
    summary = json.loads(out.read_text())["summary"]
    assert summary["gait_update_us"] > 0 and summary["driver_cycle_us"] > 0
    assert {"turning_pass", "turning_speed", "turning_drift_rad"} <= set(summary)
    assert set(summary["peak_torque"]) >= {"l_knee", "r_hip_pitch"}
    assert 0 < max(summary["peak_torque"].values()) < 10  # N m: the servos were read
    assert 0 < max(summary["peak_speed"].values()) < 10  # rad/s
    assert "no fall in" in result.stdout and "peak servo use" in result.stdout
