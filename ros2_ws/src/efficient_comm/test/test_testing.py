"""The test helpers users get: isolated DDS domains, ending process groups."""

from __future__ import annotations

import itertools
import os
import signal
import subprocess
import sys
import time

import pytest
from domain_coordinator import domain_id  # type: ignore[import-untyped]

from efficient_comm import testing
from efficient_comm.dds import SHM_FOLDER
from efficient_comm.testing import isolated_domain_id, ros_env, stop_process_group

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
    with subprocess.Popen(
            [sys.executable, "-c", "import time; print('sleeping', flush=True); time.sleep(120)"],
            start_new_session=True, stdout=subprocess.PIPE, text=True) as proc:
        # Stopped once it runs its code: a SIGINT while the interpreter still starts up may
        # end it with status 1 (a KeyboardInterrupt in site's imports), which once failed
        # this test.
        assert proc.stdout is not None and proc.stdout.readline() == "sleeping\n"
        # Python ends on Ctrl-C by SIGINT (KeyboardInterrupt, then the signal re-raised).
        assert stop_process_group(proc) == -signal.SIGINT
        assert stop_process_group(proc) == -signal.SIGINT  # already ended: nothing sent


#: Two participants in one process, as debug_gui's Hub makes (one context a domain).
TWO_PARTICIPANTS = """
import rclpy
from rclpy.context import Context
from rclpy.node import Node

nodes = []
for index in range(2):
    context = Context()
    rclpy.init(context=context)
    nodes.append(Node(f"participant_{index}", context=context, enable_rosout=False))
print("both up")
"""


def test_a_domain_handed_out_has_no_half_made_shm_port_to_hang_a_participant_on(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """A process SIGKILLed while Fast DDS made a port's shared-memory segment leaves it empty,
    and the next participant to get that port spun for ever in its creation (full runs hung
    in debug_gui's Hub so, in rclpy's Node(...)). isolated_domain_id removes such segments
    of the domain it hands out; a young one, maybe in the making, stays."""
    with domain_id() as wanted:  # free now: plant in it, then have isolated_domain_id take it
        wanted = int(wanted)
    first_port = 7400 + 250 * wanted
    # User-traffic ports of participant indices 1 and 2 (7411 + 250 d + 2 i).
    stale = SHM_FOLDER / f"fastrtps_port{first_port + 13}"
    young = SHM_FOLDER / f"fastrtps_port{first_port + 15}"
    # Below every domain's ports, as the discovery ports all domains share (no one uses 6999).
    shared = SHM_FOLDER / "fastrtps_port6999"
    try:
        long_ago = time.time() - 60
        for path in (stale, shared):
            path.touch()
            os.utime(path, (long_ago, long_ago))
        young.touch()
        monkeypatch.setattr(testing, "_next_candidate",
                            itertools.chain([wanted - 1], testing._next_candidate))
        domain = isolated_domain_id()
        if domain != wanted:
            pytest.skip(f"another process took domain {wanted} meanwhile")
        try:
            run = subprocess.run([sys.executable, "-c", TWO_PARTICIPANTS], env=ros_env(domain),
                                 capture_output=True, text=True, timeout=30, check=False)
        except subprocess.TimeoutExpired:
            pytest.fail("the second participant hung on the half-made port segment")
        assert run.stdout.strip() == "both up", run.stderr[-2000:]
        assert not shared.exists()
        assert young.exists()
    finally:
        for path in (stale, shared, young):
            path.unlink(missing_ok=True)
