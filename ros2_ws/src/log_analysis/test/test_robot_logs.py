"""Several robots' own bags, each on its own clock, read as one team log: the events are
those of team_clock's merged log of the same bags, at the same times, windows included."""

from __future__ import annotations

from pathlib import Path

import pytest
from std_msgs.msg import String

from log_analysis import Event, EventGenerator, LogSourceError, TeamLog, detect
from log_analysis.generators import Falls, RoleOscillation
from log_analysis.testing import LogBuilder, RobotBag
from team_clock import RobotLog, merge

ROLES = ["striker", "supporter"]


def _bags(folder: Path) -> tuple[Path, Path]:
    """blue1 (clock 2.5 s ahead) falls at 4 s and gets up at 6 s; red1 (1.3 s behind,
    100 ppm fast) falls at 8 s and flips its role every 0.4 s from 10 s to 12 s; in
    reference seconds from the epoch."""
    with RobotBag(folder / "blue1", robot="blue1", ahead_s=2.5) as blue:
        for t in range(0, 21):
            blue.add("fall/state", String(data="fallen" if 4 <= t < 6 else "standing"), t=t)
            blue.add("role", String(data="striker"), t=t + 0.5)
    with RobotBag(folder / "red1", robot="red1", ahead_s=-1.3, drift_ppm=100) as red:
        for t in range(0, 21):
            red.add("fall/state", String(data="fallen" if t >= 8 else "standing"), t=t)
        for k in range(6):
            red.add("role", String(data=ROLES[k % 2]), t=10 + 0.4 * k)
    return folder / "blue1", folder / "red1"


def _seen(found: list[Event]) -> list[tuple[str, str, int, int]]:
    return [(e.name, e.robot, e.start_ns, e.end_ns) for e in found]


def test_robots_bags_give_the_merged_logs_events_at_the_same_times(tmp_path: Path) -> None:
    blue, red = _bags(tmp_path)
    logs = [RobotLog(blue), RobotLog(red, namespace="red1")]
    merged = TeamLog(merge(logs, tmp_path / "merged").output)
    team = TeamLog.from_robot_logs(logs)
    assert team.robots == merged.robots == ["blue1", "red1"]
    assert team.time_range() == merged.time_range()
    read = [(m.log_time_ns, m.name, m.data) for m in team.messages()]
    assert read == sorted(read, key=lambda r: r[0])  # in time order
    assert sorted(read) == sorted((m.log_time_ns, m.name, m.data) for m in merged.messages())

    def generators() -> list[EventGenerator]:
        return [Falls(), RoleOscillation()]

    found = detect(team, generators())
    assert _seen(found.events) == _seen(detect(merged, generators()).events)
    epoch = 1000 * 10**9
    # Where the reference time says, not where either robot's clock did.
    assert [(name, robot, (start - epoch) / 1e9) for name, robot, start, _ in
            _seen(found.events)] == [("fell", "blue1", 4.0), ("got up", "blue1", 6.0),
                                     ("fell", "red1", 8.0),
                                     ("role oscillation", "red1", pytest.approx(10.4))]
    # A window on the team's time reads each bag's window on its own clock.
    start, end = epoch + 5 * 10**9, epoch + 9 * 10**9
    windowed = detect(team, generators(), start_ns=start, end_ns=end)
    assert _seen(windowed.events) == _seen(
        detect(merged, generators(), start_ns=start, end_ns=end).events)
    assert [(e.name, e.robot) for e in windowed.events] == [
        ("fell", "blue1"), ("got up", "blue1"), ("fell", "red1")]  # blue1 down at 5 s
    assert windowed.messages < found.messages


def test_bags_that_cannot_be_aligned_are_refused_with_the_reason(tmp_path: Path) -> None:
    blue, _ = _bags(tmp_path)
    with LogBuilder(tmp_path / "plain") as plain:
        plain.add("", "fall/state", String(data="standing"), t=1.0)
    with pytest.raises(LogSourceError, match=r"cannot put .*plain on the team's time"):
        TeamLog.from_robot_logs([RobotLog(blue), RobotLog(tmp_path / "plain")])
    with pytest.raises(LogSourceError, match="two logs of one robot"):
        TeamLog.from_robot_logs([RobotLog(blue), RobotLog(blue)])
    with pytest.raises(LogSourceError, match="no bag at"):
        TeamLog.from_robot_logs([RobotLog(blue), RobotLog(tmp_path / "nothing")])
