"""Smoke test of bench/clock_bench.py: the quick mode runs and reports every figure.

No timing assertions; only what the benchmark exists to show and cannot get wrong: the
stated uncertainty covered every error, and merging brought the skewed logs together.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

BENCH = Path(__file__).resolve().parents[1] / "bench" / "clock_bench.py"


@pytest.mark.timeout(100)
def test_clock_bench_quick(tmp_path: Path) -> None:
    out = tmp_path / "clock.json"
    done = subprocess.run([sys.executable, str(BENCH), "--quick", "--out", str(out)],
                          capture_output=True, text=True, timeout=90)
    assert done.returncode == 0, done.stdout + done.stderr
    results = json.loads(out.read_text())["results"]
    kinds = {r["kind"] for r in results}
    assert kinds == {"accuracy", "alignment", "merge"}
    for r in results:
        if r["kind"] == "accuracy":
            assert r["covered"] == 1.0
            assert r["a"]["p99_us"] > 0 and r["b"]["cristian_p99_us"] > 0
        elif r["kind"] == "alignment":
            assert r["events"] > 0
            assert r["max_spread_us"] < r["unmerged_median_spread_us"] / 100
        else:
            assert r["merge_msgs_per_s"] > 0 and r["copy_msgs_per_s"] > 0
    assert "merge" in done.stdout and "Cristian" in done.stdout
