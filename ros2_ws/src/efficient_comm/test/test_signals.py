"""exit_with_parent: a child started with it does not outlive its parent, even a killed one."""

from __future__ import annotations

import os
import select
import signal
import subprocess
import sys

import pytest

# The parent starts a long sleeper with exit_with_parent, says its pid, and waits for ever.
PARENT = """
import subprocess, sys, time
from efficient_comm import exit_with_parent
child = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(600)"],
                         start_new_session=True, preexec_fn=exit_with_parent)
print(child.pid, flush=True)
time.sleep(600)
"""


@pytest.mark.skipif(sys.platform != "linux", reason="PR_SET_PDEATHSIG is Linux's")
@pytest.mark.parametrize("use_it", [True, False])
def test_a_child_ends_when_its_parent_is_killed(use_it: bool) -> None:
    code = PARENT if use_it else PARENT.replace(", preexec_fn=exit_with_parent", "")
    parent = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True)
    try:
        assert parent.stdout is not None
        child_pid = int(parent.stdout.readline())
        child = os.pidfd_open(child_pid)
        parent.kill()
        parent.wait()
        # The pidfd becomes readable when the child has exited: an event, not a poll.
        ended = bool(select.select([child], [], [], 10.0 if use_it else 2.0)[0])
        os.close(child)
        assert ended is use_it
    finally:
        parent.kill()
        parent.wait()
        if parent.stdout is not None:
            parent.stdout.close()
        if not use_it:
            os.kill(child_pid, signal.SIGKILL)
