"""Smoke test of bench/playback_bench.py: the quick mode runs and reports every figure.

No timing assertions; what the benchmark cannot get wrong: every seek was delivered, every
robot's pose was the instant's after each, and both figures (seek, the window read with
TeamLog as the baseline) were measured.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

BENCH = Path(__file__).resolve().parents[1] / "bench" / "playback_bench.py"


@pytest.mark.timeout(100)
def test_playback_bench_quick(tmp_path: Path) -> None:
    out = tmp_path / "playback.json"
    done = subprocess.run([sys.executable, str(BENCH), "--quick", "--out", str(out)],
                          capture_output=True, text=True, timeout=90)
    assert done.returncode == 0, done.stdout + done.stderr
    (result,) = json.loads(out.read_text())["results"]
    assert result["robots"] == 2 and result["topics"] > 10
    assert result["held"] == result["seeks"] == len(result["seek_s"]) > 0
    assert all(s > 0 for s in result["seek_s"] + result["read_window_s"])
    assert "target: every view holds the new instant within 0.5 s" in done.stdout
