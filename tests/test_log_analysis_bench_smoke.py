"""Smoke test of bench/log_analysis_bench.py: the quick mode runs and reports every figure.

No timing assertions; what the benchmark cannot get wrong: the augmented video has every
frame of the film at 640 x 480 with every robot drawn, the floor encoded the same frames,
the A/B replay saw every image the floor decoded, both detectors found the ball, and the
targets are reported against the floors measured in the same run.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

BENCH = Path(__file__).resolve().parents[1] / "bench" / "log_analysis_bench.py"


@pytest.mark.timeout(100)
def test_log_analysis_bench_quick(tmp_path: Path) -> None:
    out = tmp_path / "bench.json"
    done = subprocess.run([sys.executable, str(BENCH), "--quick", "--out", str(out)],
                          capture_output=True, text=True, timeout=90)
    assert done.returncode == 0, done.stdout + done.stderr
    (result,) = json.loads(out.read_text())["results"]
    assert result["video_frames"] == result["augmented_frames"] == 50  # 2 s at 25 fps
    assert result["augmented_robots"] == ["blue1", "blue2"]
    assert result["images"] == result["decoded_images"] == 30
    assert result["hit_rate"]["colour"] > 0.5 and result["hit_rate"]["blob"] > 0.5
    for figure in ("decode_encode_s", "augment_s", "read_decode_s", "compare_s"):
        assert result[figure] > 0
    assert "augmented video: 50 frames of 640x480" in done.stdout
    assert "target: augment <= 1.0 of the video's duration (real time)" in done.stdout
    assert "target: compare >= 10x real time" in done.stdout
