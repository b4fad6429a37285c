"""The match video benchmark runs end to end (a short run) and measures what it claims to:
every due frame rendered, encoding and rendering both cost something, and the figures are
held against a baseline measured in the same run."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

BENCH = Path(__file__).resolve().parents[1] / "bench" / "match_video_bench.py"


@pytest.mark.timeout(180)
def test_match_video_bench_smoke(tmp_path: Path) -> None:
    out = tmp_path / "video.json"
    result = subprocess.run([sys.executable, str(BENCH), "--quick", "--out", str(out)],
                            capture_output=True, text=True, timeout=170, check=False)
    assert result.returncode == 0, result.stdout + result.stderr
    summary = json.loads(out.read_text())["summary"]
    assert summary["frames"] == summary["frames_expected"] == 13  # 1 s at 12.5 fps, both ends
    assert summary["physics_ms_per_period"] > 0 and summary["encode_ms"] > 0
    assert summary["render_wall_ms"] > 0 and summary["ratio_to_physics"] > 0
    assert "render" in result.stdout and "encode" in result.stdout
