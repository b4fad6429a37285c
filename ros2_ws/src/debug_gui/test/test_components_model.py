"""The components view's data (no DDS: messages handed to the model as the Hub would)."""

from __future__ import annotations

import pytest

from debug_gui import InvalidInput, RobotId
from debug_gui.models.components import HISTORY, STALE_AFTER_S, ComponentsModel, sparkline
from debug_gui.testing import FakeSource
from efficient_comm_interfaces.msg import CallbackStats, ExecutorStats


class _Clock:
    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


def _stats(pid: int, *callbacks: CallbackStats) -> ExecutorStats:
    return ExecutorStats(process_name="robot", hostname="h", pid=pid, window_ns=10**9,
                         callbacks=list(callbacks))


def _cb(node: str, mean_ms: float, *, kind: str = "subscription", rate: float = 10.0,
        p95_ms: float = 0.0, period_ms: float = 0.0, calls: int = 1) -> CallbackStats:
    return CallbackStats(node=node, kind=kind, name=f"{node}/in", calls=calls,
                         rate_hz=rate, mean_ns=int(mean_ms * 1e6),
                         p95_ns=int((p95_ms or mean_ms) * 1e6), max_ns=int(mean_ms * 2e6),
                         period_ns=int(period_ms * 1e6))


def _model(clock: _Clock) -> ComponentsModel:
    return ComponentsModel(FakeSource(), robot=RobotId(0, "/r"), clock=clock)


def test_rows_sort_flag_and_keep_a_short_history() -> None:
    clock = _Clock()
    model = _model(clock)
    for i in range(HISTORY + 5):
        model.on_stats(_stats(
            1,
            _cb("/r/fast", 1.0 + i % 3),
            # a timer whose p95 (60 ms) exceeds its 50 ms period
            _cb("/r/timer", 5.0, kind="timer", p95_ms=60.0, period_ms=50.0, rate=20.0),
            # a subscription busy more than all the time: 150 ms per call at 10 Hz
            _cb("/r/slow", 150.0, calls=i),
        ))
    rows = model.rows(sort_by="mean_ns")
    assert [r.node for r in rows] == ["/r/slow", "/r/timer", "/r/fast"]
    assert [r.over_period for r in rows] == [True, True, False]
    assert [r.node for r in model.rows(sort_by="node", descending=False)] == [
        "/r/fast", "/r/slow", "/r/timer"]
    fast = rows[2]
    assert len(fast.history) == HISTORY  # a short history: the last HISTORY values
    assert fast.history[-1] == int((1.0 + (HISTORY + 4) % 3) * 1e6)
    with pytest.raises(InvalidInput, match="cannot sort by"):
        model.rows(sort_by="__class__")


def test_processes_stay_apart_and_a_silent_one_drops_out() -> None:
    clock = _Clock()
    model = _model(clock)
    model.on_stats(_stats(1, _cb("/r/a", 1.0)))
    model.on_stats(_stats(2, _cb("/r/a", 2.0)))
    assert len(model.rows()) == 2  # same node name, two processes
    clock.now += STALE_AFTER_S / 2
    model.on_stats(_stats(2, _cb("/r/a", 2.0)))
    clock.now += STALE_AFTER_S / 2 + 1
    assert [r.process for r in model.rows()] == ["robot (h:2)"]
    # A callback missing from a process's next message was destroyed.
    model.on_stats(_stats(2))
    assert model.rows() == []


def test_sparkline_scales_to_the_rows_maximum() -> None:
    assert sparkline([]) == ""
    assert sparkline([0, 0]) == "▁▁"
    line = sparkline([1, 4, 8])
    assert line[0] < line[1] < line[2] and line[-1] == "█"
