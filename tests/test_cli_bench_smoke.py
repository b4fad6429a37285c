"""The ros2 command's benchmark runs end to end (one short run).

It asserts what the benchmark exists to show, not timings: the list verbs' answers are
complete, the graph daemon's answers equal those without it, and hz and echo see the
messages sent (loosely: the machine is shared).
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

BENCH = Path(__file__).resolve().parents[1] / "bench" / "cli_bench.py"


@pytest.mark.timeout(300)
def test_cli_bench_smoke(tmp_path: Path) -> None:
    out = tmp_path / "cli.json"
    # Two of the daemon's five cases: tests/test_ros2_cli_daemon.py compares every answer.
    result = subprocess.run([sys.executable, str(BENCH), "--repeat", "1", "--listen", "3",
                             "--cases", "topic_list,topic_info", "--out", str(out)],
                            capture_output=True, text=True, timeout=290)
    assert result.returncode == 0, result.stderr
    assert "| `ros2 topic list`" in result.stdout
    run = json.loads(out.read_text())[0]
    assert run["graph"]["topic_list_complete"] == 1.0
    assert run["graph"]["node_list_complete"] == 1.0
    assert "| `ros2 topic info T` |" in result.stdout
    assert "| `ros2 node list` |" not in result.stdout  # a case not asked for
    for case in ("topic_list", "topic_info"):
        assert run["graph"][f"{case}_same"] == 1.0, case  # the daemon answers as without it
    for section in ("string_1khz", "image_30hz_1mib"):
        assert run[section]["hz_seen"] > 0.5 * run[section]["hz_sent"]
        assert run[section]["echo_ratio"] > 0.5
