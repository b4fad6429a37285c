"""The world benchmark runs end to end (a short run) and measures what it claims to.

It asserts what the figures mean, not how fast this machine is: 1, 3 and 6 robots were
simulated standing, physics and rendering were both measured, and the ratios are against the
one-robot world of the same run.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

BENCH = Path(__file__).resolve().parents[1] / "bench" / "world_bench.py"


@pytest.mark.timeout(180)
def test_world_bench_smoke(tmp_path: Path) -> None:
    out = tmp_path / "world.json"
    result = subprocess.run([sys.executable, str(BENCH), "--quick", "--out", str(out)],
                            capture_output=True, text=True, timeout=170, check=False)
    assert result.returncode == 0, result.stdout + result.stderr
    summary = json.loads(out.read_text())["summary"]
    assert set(summary) == {"1", "3", "6"}
    for n, row in summary.items():
        assert row["standing"] == int(n)  # every robot held its crouch: real physics
        assert row["physics_ms"] > 0 and row["render_frame_ms"] > 0
        assert row["render_separate_frame_ms"] > 0 and row["render_fine_frame_ms"] > 0
        assert row["total_ms"] == pytest.approx(row["physics_ms"] + row["render_ms"])
    assert summary["1"]["physics_ratio"] == summary["1"]["render_ratio"] == 1.0
    # More robots, more contacts and more cameras: the same world costs more, not less.
    assert summary["6"]["physics_ms"] > summary["1"]["physics_ms"]
    assert summary["6"]["render_ms"] > summary["1"]["render_ms"]
    assert "render ms/frame" in result.stdout and "RTF bound" in result.stdout
