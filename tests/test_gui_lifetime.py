"""Feeds come and go, the GUI stops: never a traceback in its log.

* Data side: feeds opened and closed from another thread (as browser tabs open and close)
  while the domain's executor delivers: rclpy's executor must never find a subscription
  destroyed under it (``InvalidHandle: cannot use Destroyable because destruction was
  requested``), which the Hub logged as a failed executor.
* The process: ``ros2 run debug_gui debug_gui`` with tabs opened and closed against a robot,
  then Ctrl-C (SIGINT): its log holds no traceback, and it exits with status 0.
"""

from __future__ import annotations

import json
import logging
import signal
import sys
from pathlib import Path
from typing import Any

import pytest
from std_msgs.msg import String

from debug_gui import Hub, RobotId
from efficient_comm.testing import isolated_domain_id

from ._gui import fake_robot, gui, new_browser, wait_for, wait_for_text

FEEDS_PER_ROUND = 6
ROUNDS = 300
#: Python switches threads this often during the churn (default 5 ms): the race between
#: a destroying thread and the executor then shows within a few hundred rounds.
SWITCH_INTERVAL_S = 1e-6


def test_feeds_closed_from_another_thread_never_break_the_executor(
    tmp_path: Path, caplog: pytest.LogCaptureFixture,
) -> None:
    domain = isolated_domain_id()
    robot = RobotId(domain, "/churn")
    received: list[Any] = []
    with fake_robot(tmp_path, domain_id=domain, namespace="/churn", period_s=0.05,
                    callbacks=20) as proc, Hub(domains=[domain]) as hub:
        wait_for(lambda: robot in hub.robots(), what="the robot", alive=[proc])
        caplog.set_level(logging.ERROR, logger="debug_gui")
        feed = hub.subscribe(robot, "chatter", String, received.append)
        wait_for(lambda: received, what="the first chatter message", alive=[proc])
        feed.close()
        interval = sys.getswitchinterval()
        sys.setswitchinterval(SWITCH_INTERVAL_S)
        try:
            for _ in range(ROUNDS):
                feeds = [hub.subscribe(robot, topic, String, received.append)
                         for topic in ("chatter", "counter") * (FEEDS_PER_ROUND // 2)]
                wait_for(lambda: len(received) > 0, what="messages")
                for f in feeds:
                    f.close()
        finally:
            sys.setswitchinterval(interval)
        # Everything opened is closed on the executor thread: the robot's graph says so.
        node = hub._domain(robot).node
        wait_for(lambda: node.count_subscribers("/churn/chatter") == 0,
                 what="the GUI's chatter subscriptions to go", alive=[proc])
    errors = [r for r in caplog.records if r.levelno >= logging.ERROR]
    assert not errors, "\n".join(r.getMessage() + "\n" + (r.exc_text or "") for r in errors)


def test_tabs_opened_and_closed_then_ctrl_c_leave_no_traceback(tmp_path: Path) -> None:
    """With components and image views open: the image view asks the robot for its JPEG
    quality (a fake robot has no compressor: the answer is a timeout) while Ctrl-C
    deletes the page under it."""
    domain = isolated_domain_id()
    layout = tmp_path / "layout.json"
    layout.write_text(json.dumps({"version": 1, "panels": [
        {"kind": "components", "team": True}, {"kind": "image", "team": True}]}))
    with fake_robot(tmp_path, domain_id=domain, namespace="/tabs", callbacks=20) as proc, \
            gui(tmp_path, domains=[domain], args=["--layout", str(layout)]) as server:
        browser = new_browser()
        try:
            for _ in range(3):
                # A second tab, closed once it shows the robot; the first stays.
                browser.switch_to.new_window("tab")
                browser.get(server.url)
                wait_for_text(browser, "tabs_component0", alive=[proc, server])
                browser.close()
                browser.switch_to.window(browser.window_handles[0])
            browser.get(server.url)
            wait_for_text(browser, "tabs_component0", alive=[proc, server])
            # Ctrl-C while a tab is connected and its views subscribed.
            server.proc.send_signal(signal.SIGINT)
            status = server.proc.wait(timeout=30)
        finally:
            browser.quit()
        log = server.output()
        assert "Traceback" not in log, log
        assert "Stack (most recent call last)" not in log, log
        assert "InvalidHandle" not in log, log
        assert status == 0, log
