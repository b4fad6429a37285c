"""Smoke test of bench/events_bench.py: the quick mode runs and reports every figure.

No timing assertions; what the benchmark cannot get wrong: every reader saw every message,
the built-in generators found the issues the log stages (a fall a minute, role flips, a
goal every two minutes) and none of them failed.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

BENCH = Path(__file__).resolve().parents[1] / "bench" / "events_bench.py"


@pytest.mark.timeout(100)
def test_events_bench_quick(tmp_path: Path) -> None:
    out = tmp_path / "events.json"
    done = subprocess.run([sys.executable, str(BENCH), "--quick", "--out", str(out)],
                          capture_output=True, text=True, timeout=90)
    assert done.returncode == 0, done.stdout + done.stderr
    (result,) = json.loads(out.read_text())["results"]
    assert result["messages"] == result["ours_messages"] > 10_000
    assert result["failures"] == {}
    assert result["by_name"]["fell"] == result["by_name"]["got up"] > 0
    assert result["by_name"]["role oscillation"] > 0
    assert 0 < result["window_events"] <= result["events"]
    for figure in ("read_rosbags_s", "read_ours_s", "detect_s", "detect_window_s"):
        assert result[figure] > 0
    assert "target: detect <= 10 % of the log's duration" in done.stdout
