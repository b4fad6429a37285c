"""Smoke test of bench/gui_bench.py: its quick mode (one robot, one run) measures every mode.

No figures are asserted (they depend on the machine and its load): only that each mode ran
against a real robot process, that the GUI subscribed the typical layout through the Hub and
the generic bridge every topic of the robot, and that both received bytes.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from efficient_comm.testing import ros_env

ROOT = Path(__file__).resolve().parent.parent
BENCH = ROOT / "bench" / "gui_bench.py"


@pytest.mark.timeout(115)
def test_quick_gui_bench_measures_every_mode(tmp_path: Path) -> None:
    out = tmp_path / "gui.json"
    proc = subprocess.run(
        [sys.executable, str(BENCH), "--quick", "--out", str(out)],
        capture_output=True, text=True, timeout=110, env=ros_env(0), cwd=tmp_path, check=False,
    )
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-4000:]
    doc = json.loads(out.read_text())
    records = {r["mode"]: r for r in doc["records"]}
    assert set(records) == {"none", "gui", "generic"}
    for rec in records.values():
        assert rec["robot_cpu_cores"] > 0 and rec["window_s"] > 0
    gui, generic = records["gui"], records["generic"]
    assert gui["bytes_per_s"] > 0 and generic["bytes_per_s"] > 0
    topics = {t.split(":", 1)[1] for t in gui["topics"]}
    assert {"/robot1/efficient_comm/stats", "/robot1/ground_truth/robot",
            "/robot1/ball/estimate"} <= topics
    assert any(t.startswith("/robot1/camera/image_raw") for t in topics)
    assert gui["throttled_feeds"] >= 3  # the world view's topics are throttle-aware
    assert set(gui["topics"]) <= set(generic["topics"])  # the generic bridge takes them all
    assert "generic bridge / GUI" in proc.stdout
