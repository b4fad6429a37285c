"""The test helpers users get: isolated DDS domains, ending process groups."""

from __future__ import annotations

import signal
import subprocess
import sys
import time

from efficient_comm.testing import isolated_domain_id, stop_process_group

CHILD = """
import sys
from domain_coordinator import domain_id
taken = []
for wanted in map(int, sys.argv[1:]):
    try:
        with domain_id(selector=lambda: wanted):
            pass
    except RuntimeError:  # no attempt got it: someone holds it
        taken.append(wanted)
print(*taken)
"""


def test_isolated_domain_ids_are_reserved_against_other_processes() -> None:
    mine = [isolated_domain_id() for _ in range(3)]
    assert len(set(mine)) == 3 and all(1 <= d <= 100 for d in mine)
    # Another process reserving the way launch_testing does cannot get them meanwhile.
    child = subprocess.run(
        [sys.executable, "-c", CHILD, *map(str, mine)],
        capture_output=True, text=True, timeout=60, check=True,
    )
    assert sorted(map(int, child.stdout.split())) == sorted(mine), child.stderr


STUBBORN = """
import signal, subprocess, sys, time
signal.signal(signal.SIGINT, signal.SIG_IGN)
child = subprocess.Popen([sys.executable, "-c",
                          "import signal, time; signal.signal(signal.SIGINT, signal.SIG_IGN); "
                          "time.sleep(120)"])
print(child.pid, flush=True)
time.sleep(120)
"""


def _gone(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().split(")")[-1].split()[0] == "Z"  # killed, not yet reaped
    except FileNotFoundError:
        return True


def test_stop_process_group_ends_a_process_that_ignores_sigint_and_its_children() -> None:
    proc = subprocess.Popen([sys.executable, "-c", STUBBORN], stdout=subprocess.PIPE,
                            text=True, start_new_session=True)
    assert proc.stdout is not None
    grandchild = int(proc.stdout.readline())
    assert stop_process_group(proc, timeout_s=0.5) == -signal.SIGKILL
    deadline = time.monotonic() + 10
    while not _gone(grandchild) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert _gone(grandchild)
    proc.stdout.close()


def test_stop_process_group_gives_the_exit_status_of_a_clean_stop() -> None:
    proc = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(120)"],
                            start_new_session=True)
    # Python ends on Ctrl-C by SIGINT (KeyboardInterrupt, then the signal re-raised).
    assert stop_process_group(proc) == -signal.SIGINT
    assert stop_process_group(proc) == -signal.SIGINT  # already ended: nothing sent
