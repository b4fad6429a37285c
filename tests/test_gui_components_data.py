"""The components view's model against a robot process, through the Hub (no browser)."""

from __future__ import annotations

from pathlib import Path

from debug_gui import Hub, RobotId
from debug_gui.models.components import ComponentsModel
from debug_gui.testing import FakeSource
from efficient_comm.testing import isolated_domain_id

from ._gui import fake_robot, wait_for


def test_the_model_fills_while_active_and_lets_go_when_not(tmp_path: Path) -> None:
    domain = isolated_domain_id()
    with Hub(domains=[domain]) as hub, \
            fake_robot(tmp_path, domain_id=domain, namespace="/m") as proc:
        robot = RobotId(domain, "/m")
        wait_for(lambda: robot in hub.robots(), what="the robot", alive=[proc])
        model = ComponentsModel(hub, robot)
        model.activate()
        rows = wait_for(lambda: len(model.rows()) == 3 and model.rows(), what="3 rows",
                        alive=[proc])
        assert rows[0].node == "/m/m_component2"  # slowest p95 first
        assert [r.over_period for r in rows] == [True, False, False]
        wait_for(lambda: len(model.rows()[0].history) >= 3, what="a history", alive=[proc])
        model.deactivate()
        heard = model.messages
        counted = hub.counters()[(robot, "/m/efficient_comm/stats")].messages
        # Closed: nothing more arrives (the stats are published every 0.5 s).
        wait_for(lambda: proc.output().count("stats readers 0") >= 2, what="no reader",
                 alive=[proc])
        assert model.messages == heard
        assert hub.counters()[(robot, "/m/efficient_comm/stats")].messages <= counted + 1


def test_the_status_line_changes_only_when_what_it_says_does() -> None:
    """A line that counted seconds made every robot's table panel redraw every second."""
    from debug_gui.ui.components import STALE_S, status_text
    from efficient_comm_interfaces.msg import CallbackStats, ExecutorStats

    now = [100.0]
    model = ComponentsModel(FakeSource(), RobotId(0, "/s"), clock=lambda: now[0])
    model.on_stats(ExecutorStats(process_name="p", hostname="h", pid=1, callbacks=[
        CallbackStats(node="/s/a", kind="timer", name="/s/t", rate_hz=10.0, mean_ns=1000,
                      p95_ns=1000, max_ns=1000, period_ns=100_000_000)]))
    lines = set()
    for age in (0.2, 1.0, 2.5, STALE_S - 0.5):
        now[0] = 100.0 + age
        lines.add(status_text(model))
    assert lines == {"1 callbacks, 0 over their period"}
    now[0] = 100.0 + STALE_S + 2
    assert "no statistics for 7 s" in status_text(model)


def _stats_at(stamp_s: float):
    from efficient_comm import to_msg
    from efficient_comm_interfaces.msg import CallbackStats, ExecutorStats

    return ExecutorStats(
        stamp=to_msg(round(stamp_s * 1e9)), process_name="p",
        hostname="h", pid=1, callbacks=[CallbackStats(node="/s/a", kind="timer", name="/s/t",
                                                      rate_hz=10.0, period_ns=100_000_000)])


def test_the_status_line_says_when_rates_are_in_the_robots_own_time() -> None:
    """Under --lockstep a robot counts rates in simulated seconds; the line says so (and
    how fast that clock runs), and says nothing for a robot on the wall clock."""
    from debug_gui.ui.components import status_text

    epoch = 1_790_000_000.0
    for robot_start, speed, expected in ((epoch, 1.0, ""), (0.0, 0.4, "0.4x real time"),
                                         (epoch, 0.5, "0.5x real time")):
        now = [100.0]

        def gui_clock(now: list[float] = now) -> float:
            return now[0]

        def wall_clock(now: list[float] = now) -> float:
            return epoch + now[0] - 100.0

        model = ComponentsModel(FakeSource(), RobotId(0, "/s"),
                                clock=gui_clock, wall_clock=wall_clock)
        for step in range(6):
            now[0] = 100.0 + step
            model.on_stats(_stats_at(robot_start + speed * step))
            if step == 1:  # too short a span to judge the clock
                assert "robot's time" not in status_text(model)
        line = status_text(model)
        if expected:
            assert "rates in the robot's time" in line and expected in line, line
        else:
            assert line == "1 callbacks, 0 over their period"
