"""The bridge benchmark runs end to end against the real ROS 1 system (a short run).

It checks what the benchmark reports, not timings: both paths carried every message of
each burst, and the summary has a ratio for each message kind.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

BENCH = Path(__file__).resolve().parents[1] / "bench" / "bridge_bench.py"


def test_bridge_bench_smoke(tmp_path: Path) -> None:
    out = tmp_path / "bridge.json"
    result = subprocess.run(
        [sys.executable, str(BENCH), "--repeat", "1", "--small-n", "30", "--image-n", "5",
         "--small-burst", "50", "--image-burst", "5", "--out", str(out)],
        capture_output=True, text=True, timeout=100,
    )
    assert result.returncode == 0, result.stdout + result.stderr
    data = json.loads(out.read_text())
    assert {(r["kind"], r["path"]) for r in data["runs"]} == {
        (k, p) for k in ("small", "image") for p in ("direct", "bridge", "bridge_dds")}
    for r in data["runs"]:
        assert r["burst_received"] == r["burst_n"], r
        assert r["lat_n"] > 0 and r["rtt_us"] > 0
    for kind in ("small", "image"):
        assert data["summary"][kind]["bridge"]["latency_ratio"] > 0
    assert "target:" in result.stdout
