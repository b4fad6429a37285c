"""Smoke test of bench/image_view_bench.py: its quick mode measures a browser's frame rate.

No figure is asserted (it depends on the machine and its load): only that the page drew
frames and the camera baseline was counted in the same window.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from efficient_comm.testing import ros_env

BENCH = Path(__file__).resolve().parents[1] / "bench" / "image_view_bench.py"


@pytest.mark.timeout(115)
def test_quick_image_view_bench_measures_frames_drawn_and_the_camera(tmp_path: Path) -> None:
    out = tmp_path / "image.json"
    proc = subprocess.run(
        [sys.executable, str(BENCH), "--quick", "--out", str(out)],
        capture_output=True, text=True, timeout=110, env=ros_env(0), cwd=tmp_path, check=False,
    )
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-4000:]
    (record,) = json.loads(out.read_text())["records"]
    assert record["shown_fps"] > 0 and record["camera_fps"] > 0
    assert "browser drew" in proc.stdout and "median of 1" in proc.stdout
