"""The test helpers users get: isolated DDS domains."""

from __future__ import annotations

import subprocess
import sys

from efficient_comm.testing import isolated_domain_id

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
