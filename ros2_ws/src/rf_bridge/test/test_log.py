"""The bridge's rate-limited log on rclpy's real logger: every level from every module."""

from __future__ import annotations

import uuid

import pytest
import rclpy.logging
from rclpy.impl.logging_severity import LoggingSeverity

from rf_bridge._log import RateLimitedLog
from rf_bridge.testing import CapturedLogs


def test_every_level_through_rclpys_logger(capfd: pytest.CaptureFixture[str]) -> None:
    """rclpy's logger raises when one call site logs at two severities; the bridge logs a
    peer's faults at several levels through one object, so every level must work, twice."""
    name = f"rf_bridge_log_{uuid.uuid4().hex[:8]}"
    logger = rclpy.logging.get_logger(name)
    logger.set_level(LoggingSeverity.DEBUG)
    log = RateLimitedLog(logger, period_s=0.0)
    levels = ("debug", "info", "warning", "error")
    for _ in range(2):
        for level in levels:
            getattr(log, level)(f"a {level} line")
    lines = [line for line in CapturedLogs(capfd).text().splitlines() if name in line]
    assert [line.split("]")[0].strip("[") for line in lines] == [
        level.upper() if level != "warning" else "WARN" for level in levels
    ] * 2
    expected = [f"a {level} line" for level in levels * 2]
    assert [line.rsplit(": ", 1)[1] for line in lines] == expected


def test_repeats_are_held_back_and_counted(capfd: pytest.CaptureFixture[str]) -> None:
    name = f"rf_bridge_log_{uuid.uuid4().hex[:8]}"
    log = RateLimitedLog(rclpy.logging.get_logger(name), period_s=3600.0)
    for _ in range(5):
        log.warning("the same fault")
    log.error("another fault")
    lines = [line for line in CapturedLogs(capfd).text().splitlines() if name in line]
    assert len(lines) == 2 and lines[0].endswith("the same fault")
    assert lines[1].endswith("another fault")
