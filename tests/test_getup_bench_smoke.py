"""The get-up benchmark runs end to end (one trial) and measures what it claims.

It asserts what the figures mean, not how fast this machine is: a trial ran through the
driver and reported a share and a time per side, the get-up component's cost was read from
the container's callback statistics against the driver's cycle, and the reach analysis
found the hands on the ground with the centre of mass over the feet.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

BENCH = Path(__file__).resolve().parents[1] / "bench" / "getup_bench.py"


@pytest.mark.timeout(180)
def test_getup_bench_smoke(tmp_path: Path) -> None:
    out = tmp_path / "getup.json"
    result = subprocess.run(
        [sys.executable, str(BENCH), "--only", "reach", "--only", "cost", "--only", "getup",
         "--quick", "--side", "front", "--start", "lay", "--out", str(out)],
        capture_output=True, text=True, timeout=175, check=False)
    assert result.returncode == 0, result.stdout + result.stderr
    summary = json.loads(out.read_text())["summary"]
    assert summary["getup_callback_us"] > 0 and summary["driver_cycle_us"] > 0
    assert summary["getup_cycles"] > 100  # it played while measured
    assert summary["lowest_hand_m"] < 0 < summary["lowest_hand_short_m"]
    assert summary["front_falls"] == 1 and 0.0 <= summary["front_share"] <= 1.0
    assert "standing again within 5 s" in result.stdout
