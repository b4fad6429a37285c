"""What the live table sends the browser: the cells that changed, nothing when none did."""

from __future__ import annotations

import itertools

from debug_gui.ui._live_table import row_changes


def _row(key: str, **fields: object) -> dict[str, object]:
    return {"id": key, "mean_ms": 1.0, "history": "▁", **fields}


def test_unchanged_rows_send_nothing() -> None:
    shown = {"a": _row("a"), "b": _row("b")}
    assert row_changes(shown, [_row("b"), _row("a")], key="id") is None


def test_only_the_changed_cells_are_sent() -> None:
    shown = {"a": _row("a"), "b": _row("b")}
    changes = row_changes(shown, [_row("a", mean_ms=2.5), _row("b")], key="id")
    assert changes == {"set": [{"id": "a", "mean_ms": 2.5}], "remove": []}


def test_new_rows_are_sent_whole_and_gone_ones_by_key() -> None:
    shown = {"a": _row("a"), "b": _row("b")}
    changes = row_changes(shown, [_row("a"), _row("c", flag="over period")], key="id")
    assert changes == {"set": [_row("c", flag="over period")], "remove": ["b"]}


def test_a_field_that_appears_is_sent_even_when_falsy() -> None:
    shown = {"a": {"id": "a"}}
    assert row_changes(shown, [{"id": "a", "flag": ""}], key="id") == {
        "set": [{"id": "a", "flag": ""}], "remove": []}


def test_tables_polled_at_different_phases_send_within_the_same_second() -> None:
    """Issue 18, 4a: each table polls once a second at its own phase; their changes must
    reach the browser together (one render and layout of the page), not spread over the
    update period (one each)."""
    from debug_gui.ui.components import UPDATE_S, update_slot

    start = 1_000_000.3  # any wall-clock time
    sends: dict[float, list[float]] = {}
    for phase in (0.0, 0.45, 0.9):  # three tables' timers
        last = None
        for tick in range(12):
            now = start + phase + tick
            if update_slot(now) != last:
                last = update_slot(now)
                sends.setdefault(phase, []).append(now)
    rounds = list(zip(*sends.values(), strict=False))
    assert len(rounds) >= 5
    for together in rounds:
        assert max(together) - min(together) < 1.0, together
        assert update_slot(min(together)) == update_slot(max(together))
    for times in sends.values():  # at most once per period, after the first
        assert all(b - a > UPDATE_S - 1e-6 for a, b in itertools.pairwise(times[1:])), times
