"""A lockstep run is the same run whatever the machine's load.

The same seed is run twice in fresh processes: once as it comes, once at the lowest CPU
priority beside busy-looping processes (one per core), so that the emulator's thread gets
a small share of the machine. Nothing in lockstep may depend on wall time: the driver's
bus errors, the emulator's counters and every joint and the ball must come out the same.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from efficient_comm.testing import isolated_domain_id, ros_env

RUN = Path(__file__).with_name("_lockstep_run.py")
SECONDS, SEED, LINE_NOISE = "1.0", "2", "0.05"


def run(*, nice: int = 0) -> dict[str, object]:
    command = [sys.executable, str(RUN), SECONDS, SEED, LINE_NOISE]
    if nice:
        command = ["nice", "-n", str(nice), *command]
    result = subprocess.run(command, env=ros_env(isolated_domain_id()), capture_output=True,
                            text=True, timeout=600)
    assert result.returncode == 0, result.stderr
    outcome: dict[str, object] = json.loads(result.stdout.splitlines()[-1])
    return outcome


@pytest.mark.timeout(900)
@pytest.mark.xfail(reason="known defect (issue 18, 3): beside CPU hogs the emulated bus counted "
                   "394 packets against 393 idle, with equal comm errors; cause not found yet",
                   strict=False)
def test_a_lockstep_run_beside_cpu_hogs_equals_the_run_without_them() -> None:
    quiet = run()
    hogs = [subprocess.Popen([sys.executable, "-c", "while 1: pass"])
            for _ in range(os.cpu_count() or 2)]
    try:
        loaded = run(nice=19)
    finally:
        for hog in hogs:
            hog.kill()
            hog.wait()
    assert quiet["present"] == list(range(1, 21))
    assert loaded == quiet
