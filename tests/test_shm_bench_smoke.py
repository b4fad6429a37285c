"""Smoke test of bench/shm_bench.py: its smoke mode measures every backend in one run.

No figure is asserted (they depend on the machine and its load, and in smoke mode the
process pairs share the cores): only that each backend carried 1 MiB messages in both
patterns, that one message in flight lost none, and that the ratios against DDS and the
bare loop were printed from the same run.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from efficient_comm.testing import isolated_domain_id, ros_env

BENCH = Path(__file__).resolve().parents[1] / "bench" / "shm_bench.py"


@pytest.mark.timeout(180)
def test_smoke_shm_bench_measures_shm_dds_and_the_bare_loop(tmp_path: Path) -> None:
    """Six process pairs side by side (``--smoke``): about 15 s on 2 cores, most of it the
    children's start (``--quick``, one pair after the other and two sizes, took 100 s)."""
    out = tmp_path / "shm.json"
    proc = subprocess.run(
        [sys.executable, str(BENCH), "--smoke", "--out", str(out)],
        capture_output=True, text=True, timeout=170, env=ros_env(isolated_domain_id()),
        cwd=tmp_path, check=False,
    )
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-4000:]
    records = json.loads(out.read_text())["records"]
    seen = [(r["backend"], r["label"], r["mode"]) for r in records]
    assert sorted(seen) == sorted((b, "1MiB", m) for b in ("bare", "shm", "dds")
                                  for m in ("ping", "rate"))
    for record in records:
        assert record["received"] > 0 and record["median_us"] > 0, record
        if record["mode"] == "ping":
            assert record["received"] == record["sent"], record
    assert "1MiB: shm / bare latency" in proc.stdout and "shm / dds CPU" in proc.stdout
