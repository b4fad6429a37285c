"""The components view (seed Fig. 5.3): one robot's callbacks, sortable, with history.

The table sorts in the browser (every column, by p95 at first); rows whose own time
exceeds their period are marked ``over period`` and shaded. The view polls its model once a
second, the rate at which robots publish their statistics by default, and sends the browser
only the cells that changed (:class:`LiveTable`), at most every :data:`UPDATE_S`.
"""

from __future__ import annotations

import os
import time
from typing import Any

from nicegui import ui

from ..models.components import ComponentsModel, Row, sparkline
from ..robots import RobotId
from ._live_table import LiveTable
from .registry import ViewContext, register

POLL_S = 1.0
#: The table's changed cells are sent at most this often, and only when a statistics
#: message came: the figures are read by a person, and every update costs the browser's
#: main thread a re-render and a layout of the table (docs/BENCHMARKS.md).
UPDATE_S = 2.0
#: The status line says how old the statistics are only beyond this.
STALE_S = 5.0
#: ``every-second`` restores the policy before issue 18 (every table rebuilt every second,
#: whether anything changed or not): what bench/gui_page_bench.py compares against.
POLICY_VARIABLE = "DEBUG_GUI_UPDATE_POLICY"
NO_STATISTICS = ("this robot publishes no efficient_comm statistics (a plain ROS 2 robot): "
                 "nothing to show here; its parameters and topics are in those views")
#: Long names (services, parameter events) wrap, after a ``/``, ``.`` or ``_`` where they
#: can (:data:`_BREAKABLE`), so that the figures of three robots' tables side by side stay
#: in view rather than behind a scroll bar.
_NARROW = {"style": "overflow-wrap: anywhere; min-width: 4rem"}
COLUMNS: list[dict[str, Any]] = [
    {"name": "flag", "label": "", "field": "flag", "sortable": True, "align": "left"},
    {"name": "node", "label": "component", "field": "node", "sortable": True, "align": "left",
     **_NARROW},
    {"name": "name", "label": "callback", "field": "name", "sortable": True, "align": "left",
     **_NARROW},
    {"name": "mean_ms", "label": "mean ms", "field": "mean_ms", "sortable": True},
    {"name": "p95_ms", "label": "p95 ms", "field": "p95_ms", "sortable": True},
    {"name": "max_ms", "label": "max ms", "field": "max_ms", "sortable": True},
    {"name": "rate_hz", "label": "rate Hz", "field": "rate_hz", "sortable": True},
    {"name": "history", "label": "mean, last 30", "field": "history", "align": "left"},
    {"name": "period_ms", "label": "period ms", "field": "period_ms", "sortable": True},
    {"name": "calls", "label": "calls", "field": "calls", "sortable": True},
    {"name": "exceptions", "label": "exceptions", "field": "exceptions", "sortable": True},
    {"name": "drops", "label": "drops", "field": "drops", "sortable": True},
    {"name": "kind", "label": "kind", "field": "kind", "sortable": True, "align": "left"},
    {"name": "process", "label": "process", "field": "process", "sortable": True,
     "align": "left"},
]

#: Half Quasar's dense padding between columns: nine columns of three robots side by side
#: need the room.
for _column in COLUMNS:
    for _key in ("style", "headerStyle"):
        _column[_key] = "; ".join(filter(None, (_column.get(_key), "padding: 4px")))


#: The columns as the live table shows them: the flag as a badge, names with their full
#: text on hover, the history in a fixed-width font.
_CELLS = {"flag": {"cell": "badge"}, "node": {"cell": "titled"}, "name": {"cell": "titled"},
          "history": {"style": "font-family: monospace; white-space: nowrap"}}
LIVE_COLUMNS = [{**c, **_CELLS.get(c["name"], {})} for c in COLUMNS]
ALL = [c["name"] for c in COLUMNS]
#: What fits when several robots' tables stand side by side (28rem each, ui.registry's
#: TEAM_GRID): the history's thirty characters do not, it shows with all columns.
COMPACT = [n for n in ALL if n not in {"history", "period_ms", "calls", "kind", "process"}]
#: A name's cell with a line-break opportunity after each ``/``, ``.`` and ``_``.
_BREAKABLE = r"""
        <q-td :props="props" :title="props.value"><template
          v-for="part in String(props.value).split(/(?<=[/._])/)">{{ part }}<wbr></template>
        </q-td>"""


def _ms(ns: int) -> float:
    return round(ns / 1e6, 3)


def _short(name: str, robot: RobotId) -> str:
    """``/robot2/camera/image_raw`` as ``camera/image_raw`` (the robot is the view's title)."""
    prefix = robot.namespace.rstrip("/") + "/"
    return name[len(prefix):] if robot.namespace != "/" and name.startswith(prefix) else name


def table_row(row: Row, robot: RobotId) -> dict[str, Any]:
    """A model row as the browser table shows it (names relative to the robot)."""
    return {
        "id": "|".join(row.key),
        "flag": "over period" if row.over_period else "",
        "node": _short(row.node, robot), "kind": row.kind, "name": _short(row.name, robot),
        "rate_hz": round(row.rate_hz, 2),
        "mean_ms": _ms(row.mean_ns), "p95_ms": _ms(row.p95_ns), "max_ms": _ms(row.max_ns),
        "period_ms": _ms(row.period_ns) if row.period_ns else "",
        "calls": row.calls, "exceptions": row.exceptions, "drops": row.drops,
        "history": sparkline(row.history),
        "process": row.process,
    }


@register(kind="components", title="Components", order=10)
def build(ctx: ViewContext) -> None:
    assert ctx.robot is not None  # a per-robot kind: the shell binds every instance
    robot = ctx.robot
    model = ComponentsModel(ctx.source, robot)
    waiting = "waiting for the robot's statistics…"
    status_id = f"components-status-{robot.key}"
    every_second = os.environ.get(POLICY_VARIABLE) == "every-second"
    if every_second:
        status = ui.label(waiting).classes("text-caption").props(f"data-testid={status_id}")
    # The live table shows the status line itself, sent with its cells (LiveTable.show).
    table: Any = _old_table() if every_second else LiveTable(
        columns=LIVE_COLUMNS, row_key="id", sort_by="p95_ms", descending=True,
        caption=waiting, caption_testid=status_id)
    table.props(f"dense flat wrap-cells data-testid=components-{robot.key}").classes(
        "w-full").style("max-height: 32rem")
    table.props["visible-columns"] = COMPACT

    def all_columns(show: bool) -> None:
        if every_second:
            table.props["visible-columns"] = ALL if show else COMPACT
        else:
            table.set_visible(ALL if show else COMPACT)

    ui.switch("all columns", on_change=lambda e: all_columns(bool(e.value))).props(
        f"dense data-testid=components-columns-{robot.key}"
    )
    pushed: dict[str, Any] = {"messages": -1, "slot": None}

    def refresh() -> None:
        if not model.active:
            return
        text, slot = status_text(model), update_slot(time.time())
        if every_second:
            table.rows = [table_row(r, robot) for r in model.rows()]
            table.update()
            if text != status.text:
                status.text = text
        elif slot != pushed["slot"] and (model.messages != pushed["messages"]
                                         or text != table.caption):
            pushed["messages"], pushed["slot"] = model.messages, slot
            table.show([table_row(r, robot) for r in model.rows()], caption=text)

    ctx.follow(model, ui.timer(POLL_S, refresh, active=False))


def update_slot(now: float) -> int:
    """The :data:`UPDATE_S` period of the wall clock that ``now`` falls in: a table sends
    at most once per period, and as every table of every tab counts the same periods,
    their changes reach the browser within the same second (where ``live_table.js``
    applies them in one render) rather than spread over the period, one render each."""
    return int(now // UPDATE_S)


def _old_table() -> Any:
    """The table before issue 18 (``ui.table`` with slot templates, every row re-sent every
    second): only what bench/gui_page_bench.py measures the new one against."""
    table = ui.table(columns=COLUMNS, rows=[], row_key="id", pagination=0)
    table.add_slot("body-cell-flag", r"""
        <q-td :props="props">
          <q-badge v-if="props.value" color="negative" multi-line :label="props.value"
                   style="word-break: keep-all; text-align: center" />
        </q-td>""")
    for column in ("node", "name"):
        table.add_slot(f"body-cell-{column}", _BREAKABLE)
    table.add_slot("body-cell-history", r"""
        <q-td :props="props" style="font-family: monospace; white-space: nowrap">
          {{ props.value }}</q-td>""")
    return table


def status_text(model: ComponentsModel) -> str:
    """The line above the table; it changes only when what it says does (a counter of
    seconds would make the page redraw every second for nothing)."""
    age = model.age_s()
    if age is None:
        return "waiting for the robot's statistics…" if model.statistics_published() \
            else NO_STATISTICS
    rows = model.rows()
    text = f"{len(rows)} callbacks, {sum(r.over_period for r in rows)} over their period"
    note = model.clock_note()
    if note:
        text = f"{text}; {note}"
    return text if age < STALE_S else f"{text}; no statistics for {age:.0f} s"
