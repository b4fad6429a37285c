"""The README's main command: three simulated robots and the GUI, seen in a browser."""

from __future__ import annotations

import os
import re
import signal
import sys
from functools import partial
from pathlib import Path

from efficient_comm.testing import isolated_domain_id, ros_env

from ._gui import (
    Process,
    present,
    screenshot,
    started,
    text_of,
    wait_for,
    wait_for_text,
)


def _shows(browser, testid: str, text: str) -> bool:
    return text in text_of(browser, testid)


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    return True


def test_demo_serves_three_robots_in_two_domains_and_stops_them_all(
    tmp_path: Path, browser
) -> None:
    d1, d2 = isolated_domain_id(), isolated_domain_id()
    log = tmp_path / "demo.log"
    cmd = [sys.executable, "-m", "debug_gui.demo", "--robots", "3", "--port", "0",
           "--domains", f"{d1},{d2}", "--log-dir", str(tmp_path / "robots")]
    with started(cmd, env=ros_env(d1), log=log) as proc:
        demo = Process(proc=proc, log=log)
        url = wait_for(lambda: re.search(r"at (http://\S+)", demo.output()), timeout_s=60,
                       what="the URL", alive=[demo]).group(1)
        pids = [int(p) for p in re.findall(r"pid (\d+)", demo.output())]
        assert len(pids) == 3
        browser.set_window_size(2400, 1200)  # three robots' tables side by side (README)
        browser.get(url)
        robots = {f"{d1}:/robot1", f"{d2}:/robot2", f"{d2}:/robot3"}
        # Each robot's components view fills with its own soccer pipeline's callbacks.
        for key in sorted(robots):
            row = "ball_detector"
            table = f"components-{key}"
            wait_for(partial(_shows, browser, table, row),
                     timeout_s=90, what=f"{key}'s components", alive=[demo])
            wait_for(partial(present, browser, f"robot-{key}"), what=f"{key} in the header",
                     alive=[demo])
        wait_for_text(browser, re.compile(r"robot3 @ domain \d+\n.*callbacks", re.S),
                      alive=[demo])
        screenshot(browser, "debug_gui_demo")
        os.killpg(proc.pid, signal.SIGTERM)
        assert proc.wait(timeout=30) == 0, demo.output()
        wait_for(lambda: not any(_alive(p) for p in pids), timeout_s=15,
                 what="every robot to stop")
