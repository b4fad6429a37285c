"""The throttle benchmark runs end to end across two network namespaces (a short run).

It asserts what the benchmark exists to show, not timings: each throttled subscriber gets
its requested share of the bytes, and an output nobody wants is not computed.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import uuid
from pathlib import Path

import pytest

BENCH = Path(__file__).resolve().parents[1] / "bench" / "throttle_bench.py"


def _netns_possible() -> bool:
    if os.geteuid() != 0 or shutil.which("ip") is None:
        return False
    name = f"ecprobe{uuid.uuid4().hex[:6]}"
    if subprocess.run(["ip", "netns", "add", name], capture_output=True).returncode:
        return False
    subprocess.run(["ip", "netns", "del", name], check=False)
    return True


@pytest.mark.timeout(240)
@pytest.mark.skipif(not _netns_possible(), reason="needs root and network namespaces")
def test_throttle_bench_smoke(tmp_path: Path) -> None:
    out = tmp_path / "throttle.json"
    result = subprocess.run(
        [sys.executable, str(BENCH), "--repeat", "1", "--seconds", "3",
         "--out", str(out), "--plot", str(tmp_path / "throttle.png")],
        capture_output=True, text=True, timeout=230,
    )
    assert result.returncode == 0, result.stdout + result.stderr
    runs = {r["mode"]: r for r in json.loads(out.read_text())}
    received = {s["kind"]: s["bytes"] for s in runs["throttled"]["subscribers"]}
    assert received["full"] > 0
    assert received["rate5"] <= received["full"] * (5 / 30) * 1.05
    assert received["nth10"] <= received["full"] * 0.1 * 1.05
    assert received["rate5"] > 0 and received["nth10"] > 0
    assert runs["plain"]["link_tx_bytes"] > runs["throttled"]["link_tx_bytes"]
    assert runs["expensive_none"]["computed"] == 0
    assert runs["expensive_full"]["computed"] > runs["expensive_1hz"]["computed"] > 0
    assert (tmp_path / "throttle.png").exists()
