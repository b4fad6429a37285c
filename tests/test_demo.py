"""The README's demo runs, reports and exits cleanly (examples are run by CI)."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

from efficient_comm.testing import isolated_domain_id, ros_env


@pytest.mark.parametrize("extra", [[], ["--no-dds", "--strategy", "breadth_first"]])
def test_demo_runs_and_reports(tmp_path: Path, extra: list[str]) -> None:
    result = subprocess.run(
        [sys.executable, "-m", "efficient_comm.examples.demo", "--duration", "2",
         "--stats-period", "1", *extra],
        env=ros_env(isolated_domain_id()),
        capture_output=True,
        text=True,
        timeout=60,
        cwd=tmp_path,
    )
    assert result.returncode == 0, result.stdout + result.stderr
    tracks = re.search(r"tracks received: (\d+)", result.stdout)
    assert tracks is not None and int(tracks.group(1)) > 10, result.stdout
    assert "/demo/camera" in result.stdout and "callback exceptions: 0" in result.stdout
