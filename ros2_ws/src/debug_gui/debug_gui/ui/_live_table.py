"""A table the server updates cell by cell: what changed is sent, nothing else.

Why not ``ui.table``: a NiceGUI element update re-renders the page's whole Vue tree, and a
``ui.table`` slot template (a badge, a hover title) is a new Vue component type at every
render, so *every* slotted cell of every table on the page was destroyed and re-created
whenever anything changed, and an update re-sent every row. With three robots' tables of
40 callbacks that kept the browser's main thread busy (issue 18, docs/BENCHMARKS.md).

Here the cell templates are part of one component (``live_table.js``, compiled once), and
:meth:`LiveTable.show` sends only the cells that differ from what the browser already
shows (:func:`row_changes`), through a method call on the component: no element update,
no page re-render. The component draws plain rows in Quasar's table classes, each row
memoised, rather than a QTable (which re-rendered all its rows, with a QTd component per
slotted cell, for any changed cell), and applies the changes that reach the page's tables
within one second together, in one render and one layout; a row out of sight (below the
window) is drawn when it comes into sight, not on every change. The rows the browser shows are
kept on the server too, so a page that NiceGUI re-sends (a column switch, a reconnect)
starts from the current figures.

Columns are QTable's column dicts, plus an optional ``cell``: ``"badge"`` (a red badge
where the value is not empty) or ``"titled"`` (the full value on hover, for names cut
with an ellipsis).
"""

from __future__ import annotations

from typing import Any

from nicegui.element import Element

#: One row as the browser shows it: field -> value (JSON), with the row key among them.
TableRow = dict[str, Any]


def row_changes(shown: dict[Any, TableRow], rows: list[TableRow], *,
                key: str) -> dict[str, list[Any]] | None:
    """What turns the rows the browser ``shown`` (by key) into ``rows``: ``{"set": [...],
    "remove": [...]}``, each ``set`` entry the key and only the fields whose value changed
    (a whole row for a new one); None when nothing changed, so nothing is sent."""
    wanted = {row[key]: row for row in rows}
    remove = [k for k in shown if k not in wanted]
    set_: list[TableRow] = []
    for k, row in wanted.items():
        old = shown.get(k)
        if old is None:
            set_.append(dict(row))
            continue
        changed = {f: v for f, v in row.items() if old.get(f) != v or f not in old}
        if changed:
            set_.append({key: k, **changed})
    if not set_ and not remove:
        return None
    return {"set": set_, "remove": remove}


class LiveTable(Element, component="live_table.js"):
    """A table like a dense QTable (sortable in the browser by a click on a heading, columns
    shown or hidden by ``props["visible-columns"]``) whose rows change only through
    :meth:`show`."""

    def __init__(self, *, columns: list[dict[str, Any]], row_key: str = "id",
                 sort_by: str | None = None, descending: bool = False, caption: str = "",
                 caption_testid: str | None = None) -> None:
        super().__init__()
        self.row_key = row_key
        self._shown: dict[Any, TableRow] = {}
        #: Cell-change messages sent (what a test and the benchmark count).
        self.patches = 0
        self._props["columns"] = columns
        self._props["row-key"] = row_key
        self._props["rows"] = []
        self._props["caption"] = caption
        if caption_testid is not None:
            self._props["caption-testid"] = caption_testid
        pagination: dict[str, Any] = {"rowsPerPage": 0}
        if sort_by is not None:
            pagination.update(sortBy=sort_by, descending=descending)
        self._props["pagination"] = pagination

    def set_visible(self, columns: list[str]) -> None:
        """Show these columns (by name), in one small message rather than the whole table
        (a click on a column switch is answered without re-sending the rows)."""
        with self.props.suspend_updates():
            self._props["visible-columns"] = list(columns)
        self.run_method("setVisible", list(columns))

    @property
    def caption(self) -> str:
        """The line above the table (a status)."""
        return str(self._props["caption"])

    def show(self, rows: list[TableRow], *, caption: str | None = None) -> bool:
        """Make the browser show ``rows`` (in this order for rows it has not seen) and the
        ``caption`` (None: the same), sending only what changed; False when nothing did
        (and nothing was sent). The caption travels with the cells rather than as a
        label's text: a label's change is an element update, which re-renders the page."""
        changes: dict[str, Any] = row_changes(self._shown, rows, key=self.row_key) or {
            "set": [], "remove": []}
        if caption is not None and caption != self.caption:
            changes["caption"] = caption
        if not changes["set"] and not changes["remove"] and "caption" not in changes:
            return False
        self._shown = {row[self.row_key]: dict(row) for row in rows}
        # Kept for a re-sent element (see the module docstring), without sending it now.
        with self.props.suspend_updates():
            self._props["rows"] = list(self._shown.values())
            self._props["caption"] = changes.get("caption", self.caption)
        self.patches += 1
        self.run_method("patch", changes)
        return True
