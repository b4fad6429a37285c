"""exit_with_parent: a child started with it does not outlive its parent, even a killed one."""

from __future__ import annotations

import os
import select
import signal
import subprocess
import sys

import pytest

from efficient_comm.testing import isolated_domain_id

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


# A container (no DDS) whose one component's timer callback is busy when Ctrl-C comes: it
# says so, runs on for a while, says it finished; close() says it ran.
BUSY = """
import sys, time
from efficient_comm import Container

class Busy:
    def __init__(self, node):
        self.calls = 0
        node.create_timer(0.05, self.tick)

    def tick(self):
        self.calls += 1
        if self.calls == 2:
            print("in callback", flush=True)
            end = time.monotonic() + 1.0
            while time.monotonic() < end:  # pure Python: where KeyboardInterrupt lands
                pass
            print("callback done", flush=True)

    def close(self):
        print("closed", flush=True)

RUN
print("spin returned", flush=True)
"""
RUNS = {
    "container": 'with Container("busy", dds=False) as c:\n    c.add(Busy, name="busy")\n'
                 '    c.spin()',
    "standalone": 'from efficient_comm import Standalone\n'
                  'with Standalone(Busy, name="busy", args=[]) as s:\n    s.spin()',
}


@pytest.mark.parametrize("run", sorted(RUNS))
def test_ctrl_c_stops_between_callbacks_not_inside_one(run: str) -> None:
    """A first Ctrl-C lets the running callback finish and unloads every component; a
    ``KeyboardInterrupt`` raised mid-callback (inside rclpy's take, a RuntimeError) would
    end the program with a traceback instead."""
    env = {**os.environ, "ROS_DOMAIN_ID": str(isolated_domain_id())}
    proc = subprocess.Popen([sys.executable, "-c", BUSY.replace("RUN", RUNS[run])], env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert proc.stdout is not None
        assert proc.stdout.readline().strip() == "in callback"
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=30)
    finally:
        proc.kill()
        proc.wait()
    assert out.split() == ["callback", "done", "closed", "spin", "returned"], (out, err)
    assert proc.returncode == 0 and "Traceback" not in err, err
