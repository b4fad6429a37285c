"""Smoke test of bench/comm_bench.py: its quick mode runs and reports every scenario.

No timing assertions: the numbers depend on the machine and its load; only that each
scenario produced a positive figure for every backend is checked.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
BENCH = ROOT / "bench" / "comm_bench.py"

BACKENDS = ("single", "multi", "events", "composed", "composed_bf", "composed_dds")
EXPECTED = {
    ("latency", b, p, "median_us")
    for b in BACKENDS
    for p in ("string", "image_64B", "image_64KiB", "image_1MiB", "image_8MiB")
}
EXPECTED |= {("throughput", b, p, "msgs_per_s") for b in BACKENDS for p in ("string", "empty")}
EXPECTED |= {("dispatch", b, "timer", "us_per_callback") for b in BACKENDS}
EXPECTED |= {("chain", b, p, "median_us") for b in BACKENDS for p in ("string", "image_1MiB")}
EXPECTED |= {
    ("external", b, p, "median_us") for b in ("plain", "composed") for p in ("string", "image_1MiB")
}


@pytest.mark.timeout(250)
def test_quick_bench_reports_every_scenario(tmp_path: Path) -> None:
    out = tmp_path / "comm_bench.json"
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
    proc = subprocess.run(
        # A child that hangs is ended after 60 s and named in the errors (not the whole
        # run ended by the timeout below with nothing said).
        [sys.executable, str(BENCH), "--quick", "--no-plot", "--timeout", "60", "--out",
         str(out)],
        capture_output=True,
        text=True,
        timeout=240,  # 45 s on an idle machine; beside the suite's other workers often 2x
        env=env,
        cwd=ROOT,
        check=False,
    )
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-4000:]
    doc = json.loads(out.read_text())
    assert doc["errors"] == []
    found = {}
    for rec in doc["results"]:
        for metric in ("median_us", "p99_us", "msgs_per_s", "us_per_callback"):
            if metric in rec:
                found[(rec["scenario"], rec["backend"], rec["payload"], metric)] = rec[metric]
    missing = sorted(EXPECTED - found.keys())
    assert not missing, missing
    for key in EXPECTED:
        assert found[key] > 0, key
    for rec in doc["results"]:
        if "p99_us" in rec:
            assert rec["p99_us"] >= rec["median_us"] > 0, rec
    assert "Targets" in proc.stdout
