"""The team match's command line: a bad argument is one line and exit status 2, before
anything starts; ``--robots 1`` is the one-robot demo's parser."""

from __future__ import annotations

import subprocess
import sys

import pytest

from efficient_comm.testing import isolated_domain_id, ros_env


@pytest.mark.parametrize(("args", "says"), [
    (["--robots", "4v1"], "--robots: '4v1': need 1, 2, 3"),
    (["--robots", "3v3", "--duration", "-1"], "--duration: '-1': need seconds >= 0"),
    (["--robots", "2", "--camera-hz", "100"], "--camera-hz: '100': need 0 to 60 Hz"),
    (["--robots", "2", "--team-link-cut-at", "-3"],
     "--team-link-cut-at: '-3': need seconds >= 0"),
    (["--robots", "1", "--ball", "9,0"], "off the field"),  # the demo's own parser
])
def test_a_bad_argument_is_one_line_and_exit_status_2(args: list[str], says: str) -> None:
    done = subprocess.run([sys.executable, "-m", "humanoid_sim.match", *args],
                          capture_output=True, text=True, timeout=60,
                          env=ros_env(isolated_domain_id()))
    assert done.returncode == 2, done
    assert done.stdout == "" and len(done.stderr.splitlines()) == 1, done.stderr
    assert says in done.stderr and "error:" in done.stderr, done.stderr
