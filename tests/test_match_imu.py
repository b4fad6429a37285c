"""A robot process of the team match hears its IMU at the rate the world sends it.

The world publishes one IMU message per robot at each tick (100 Hz when it keeps up); the
robot takes it from DDS on its own domain. Before the fix a loaded robot's executor took
one DDS sample per wait and per reader, and the robot heard its IMU at about a third of the
world's tick rate (and fell). Measured by the match itself (its report: IMU messages the
world sent while the robot's reader was matched, and those the robot heard), as a user runs
it; the match is ended with Ctrl-C after the robot has played for 20 live lines.
"""

from __future__ import annotations

import re
import time
from pathlib import Path

import pytest

from ._match import MatchProcess

#: Share of the IMU messages the world sent while the robot's reader was matched that the
#: robot must have heard (both counts are their last status lines before the stop).
HEARD_SHARE = 0.85


@pytest.mark.timeout(200)
def test_a_robot_hears_its_imu_at_the_worlds_rate(tmp_path: Path) -> None:
    report = tmp_path / "report.md"
    with MatchProcess(["--robots", "1v0", "--duration", "0", "--camera-hz", "10",
                       "--stats-period", "1", "--out-dir", str(tmp_path / "out"),
                       "--report", str(report)], cwd=tmp_path) as match:
        # 20 live lines since the robot reported (it runs its software).
        deadline = time.monotonic() + 150
        for _ in range(20):
            match.until(r"^  blue1 +(?!starting)\S", deadline - time.monotonic())
        match.interrupt()
        match.wait(60)
    text = report.read_text()
    m = re.search(r"matched: blue1 (\d+) of (\d+)\.", text)
    assert m, text
    heard, sent = int(m[1]), int(m[2])
    # Both counts are the last status lines before the robot was stopped (each up to a
    # second old): a few percent of the 20 s either way.
    assert sent > 0 and heard >= HEARD_SHARE * sent, text
