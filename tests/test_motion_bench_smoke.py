"""The motion benchmark runs end to end (one kick) and measures what it claims.

It asserts what the figures mean, not how fast this machine is: a kick ran through the
driver and its ball was measured, the servos' peaks were read, and the kick's and the
arbiter's cost per callback were taken from the container's statistics next to the driver's.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

BENCH = Path(__file__).resolve().parents[1] / "bench" / "motion_bench.py"


@pytest.mark.timeout(240)
def test_motion_bench_smoke(tmp_path: Path) -> None:
    out = tmp_path / "motion.json"
    result = subprocess.run(
        [sys.executable, str(BENCH), "--seeds", "1", "--seconds", "4", "--out", str(out)],
        capture_output=True, text=True, timeout=235, check=False)
    assert result.returncode == 0, result.stdout + result.stderr
    data = json.loads(out.read_text())
    summary, (kick,) = data["summary"], data["results"]["kick"]
    assert summary["kick_callback_us"] > 0 and summary["arbiter_callback_us"] > 0
    assert summary["driver_cycle_us"] > 0
    assert kick["completed"] and kick["ball_speed"] > 0.3  # the ball was kicked
    assert 0 < kick["distance_m"] < 10 and abs(kick["angle_deg"]) < 90
    assert 0 < max(summary["peak_torque"].values()) < 10  # N m: the servos were read
    assert "success (>= 0.3 m" in result.stdout and "peak servo use" in result.stdout
