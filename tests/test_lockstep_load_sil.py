"""A lockstep run is the same run whatever the machine's load.

The same seed (5 % line noise, so garbled packets and the driver's retries are part of the
run) is run three times in fresh processes, side by side and beside busy-looping processes
(one per core): as it comes; with the emulator's thread slowed down before every packet;
and with the run's figures read only once the emulator has handled everything sent to it.
The two injected delays stand for a loaded machine at the points where lockstep once
depended on the wall clock, so the test fails on such a defect whether or not the machine
happens to be busy: the driver's last sync write of a run was still on its way to the
emulator when the figures were read, or not (394 bus packets beside CPU hogs, 393 idle).
(A run at ``nice 19`` beside the hogs, as this test once had, proves no more and can take
a quarter of an hour on a shared machine: 878 s for one simulated second at load 19.)
Nothing in lockstep may depend on wall time: the driver's bus errors, the emulator's
counters and every joint and the ball must come out the same.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from efficient_comm.testing import isolated_domain_id, ros_env, stop_process_group

RUN = Path(__file__).with_name("_lockstep_run.py")
#: Simulated seconds: the servos' adoption with its retries on the noisy line, then
#: enough cycles of reading and writing all of them.
SECONDS, SEED, LINE_NOISE = "0.3", "2", "0.05"
#: How long the slowed emulator takes before each packet (longer than the few
#: microseconds between a run's last write and the reading of its figures).
SLOW_EMULATOR_MS = "30"
VARIANTS = {
    "as it comes": [],
    "slow emulator": ["--slow-emulator", SLOW_EMULATOR_MS],
    "figures read late": ["--look-late"],
}


def start(options: list[str]) -> subprocess.Popen[str]:
    command = [sys.executable, str(RUN), SECONDS, SEED, LINE_NOISE, *options]
    return subprocess.Popen(command, env=ros_env(isolated_domain_id()), text=True,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            start_new_session=True)


def outcome(process: subprocess.Popen[str]) -> dict[str, object]:
    stdout, stderr = process.communicate(timeout=400)
    assert process.returncode == 0, stderr
    result: dict[str, object] = json.loads(stdout.splitlines()[-1])
    return result


@pytest.mark.timeout(600)
def test_a_lockstep_run_is_the_same_slowed_down_late_read_and_beside_cpu_hogs() -> None:
    hog = [sys.executable, "-c", "while 1: pass"]
    processes: list[subprocess.Popen[Any]] = [
        subprocess.Popen(hog, start_new_session=True) for _ in range(os.cpu_count() or 2)]
    try:
        runs = {name: start(options) for name, options in VARIANTS.items()}
        processes += runs.values()
        results = {name: outcome(process) for name, process in runs.items()}
    finally:
        for process in processes:
            stop_process_group(process, sig=signal.SIGKILL)
    reference = results["as it comes"]
    assert reference["present"] == list(range(1, 21))
    assert reference["crc_errors"], "the line noise garbled no request: nothing was retried"
    for name, result in results.items():
        assert result == reference, name
