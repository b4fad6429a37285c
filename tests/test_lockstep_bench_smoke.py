"""Smoke test of bench/lockstep_bench.py: the quick mode runs and reports every figure.

No timing assertions: only that each participant count was measured against its baseline.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

BENCH = Path(__file__).resolve().parents[1] / "bench" / "lockstep_bench.py"


@pytest.mark.timeout(200)
def test_lockstep_bench_quick(tmp_path: Path) -> None:
    out = tmp_path / "lockstep.json"
    done = subprocess.run([sys.executable, str(BENCH), "--quick", "--out", str(out)],
                          capture_output=True, text=True, timeout=180)
    assert done.returncode == 0, done.stdout + done.stderr
    results = json.loads(out.read_text())["results"]
    assert [r["participants"] for r in results] == [1, 2, 1]
    assert results[-1]["default_acks"] and results[-1]["steps_per_s"] > 0
    for r in results[:-1]:
        assert r["steps_per_s"] > 0 and r["baseline_steps_per_s"] > 0
        assert r["ratio"] == pytest.approx(r["steps_per_s"] / r["baseline_steps_per_s"])
    assert "lockstep ÷ baseline" in done.stdout
