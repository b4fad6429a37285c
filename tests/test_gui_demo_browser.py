"""The demo of robots that each play alone (`--solo`, the README's main command before the
team match): three simulated robots and the GUI, seen in a browser."""

from __future__ import annotations

import os
import re
import signal
import sys
from functools import partial
from pathlib import Path

import pytest

from debug_gui import Hub, RobotId
from debug_gui.models.recorder import RecorderModel
from debug_gui.security import AccessPolicy
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


# The one end-to-end test with the real demo: three real-time soccer simulations, the GUI
# and chromium share two cores, and each robot's pipeline starts in turn (about two minutes).
@pytest.mark.timeout(300)
def test_demo_serves_three_robots_in_two_domains_and_stops_them_all(
    tmp_path: Path, browser
) -> None:
    d1, d2 = isolated_domain_id(), isolated_domain_id()
    log = tmp_path / "demo.log"
    # Relative, as a user types it: the demo runs in tmp_path (the log's folder).
    cmd = [sys.executable, "-m", "debug_gui.demo", "--solo", "--robots", "3", "--port", "0",
           "--domains", f"{d1},{d2}", "--log-dir", str(tmp_path / "robots"),
           "--record-dir", "rec"]
    with started(cmd, env=ros_env(d1), log=log) as proc:
        demo = Process(proc=proc, log=log)
        url = wait_for(lambda: re.search(r"at (http://\S+)", demo.output()), timeout_s=60,
                       what="the URL", alive=[demo]).group(1)
        pids = [int(p) for p in re.findall(r"pid (\d+)", demo.output())]
        assert len(pids) == 3
        # Issue 18, 4d: recordings go to a folder that outlives the demo, said absolute.
        records = tmp_path / "rec"
        assert f"recordings go to {records} (kept after the demo)" in demo.output()
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


def test_the_demos_recordings_outlive_it_where_it_says(tmp_path: Path) -> None:
    """Issue 18, 4d: a robot's bag lands under --record-dir (absolute in the recorder's
    answers, which the recorder view shows) and is still there after the demo stopped."""
    d1, d2 = isolated_domain_id(), isolated_domain_id()
    log = tmp_path / "demo.log"
    cmd = [sys.executable, "-m", "debug_gui.demo", "--solo", "--robots", "1", "--port", "0",
           "--domains", f"{d1},{d2}", "--lockstep", "--record-dir", "rec"]
    with started(cmd, env=ros_env(d1), log=log) as proc:
        demo = Process(proc=proc, log=log)
        wait_for(lambda: "at http://" in demo.output(), timeout_s=60, what="the URL",
                 alive=[demo])
        records = tmp_path / "rec"
        assert f"recordings go to {records} (kept after the demo)" in demo.output()
        bag = _record_briefly(RobotId(d1, "/robot1"), alive=[demo])
        assert bag.is_absolute() and bag.parent == records / "robot1", bag
        os.killpg(proc.pid, signal.SIGTERM)
        assert proc.wait(timeout=30) == 0, demo.output()
    assert list(bag.glob("*.mcap")), f"{bag} went with the demo"


def _record_briefly(robot: RobotId, *, alive: list[Process]) -> Path:
    """Start and stop the robot's recorder as the recorder view does (its default bag)."""
    policy = AccessPolicy.for_server()
    with Hub(domains=[robot.domain]) as hub:
        model = RecorderModel(hub, robot, policy=policy, token=policy.token)
        wait_for(lambda: model.discover() == ["/robot1/recorder"], timeout_s=60,
                 what="robot1's recorder", alive=alive)
        model.activate()
        try:
            started_ = model.start()
            assert started_.success, started_
            wait_for(lambda: (s := model.states()) and s[0].messages > 0,
                     what="messages recorded", alive=alive)
            stopped = model.stop()
            assert stopped.success, stopped
        finally:
            model.deactivate()
    return Path(stopped.bag)
