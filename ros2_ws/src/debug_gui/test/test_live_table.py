"""What the live table sends the browser: the cells that changed, nothing when none did."""

from __future__ import annotations

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
