"""The components view (seed Fig. 5.3): one robot's callbacks, sortable, with history.

The table sorts in the browser (every column); rows whose own time exceeds their period
are marked ``over period`` and shaded. The view polls its model once a second, the rate
at which robots publish their statistics by default.
"""

from __future__ import annotations

import os
import time
from typing import Any

from nicegui import ui

from ..models.components import ComponentsModel, Row, sparkline
from ..robots import RobotId
from .registry import ViewContext, register

POLL_S = 1.0
#: The table is redrawn at most this often, and only when a statistics message came: the
#: figures are read by a person, and a redrawn table of a few dozen rows per robot costs
#: the browser's main thread more than anything else on the page (docs/BENCHMARKS.md).
UPDATE_S = 3.0
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
    model = ComponentsModel(ctx.hub, robot)
    status = ui.label("waiting for the robot's statistics…").classes("text-caption").props(
        f"data-testid=components-status-{robot.key}"
    )
    table = ui.table(
        columns=COLUMNS, rows=[], row_key="id", pagination=0,
    ).props(
        f"dense flat wrap-cells data-testid=components-{robot.key}"
    ).classes("w-full").style("max-height: 32rem")
    table.props["visible-columns"] = COMPACT

    def all_columns(show: bool) -> None:
        table.props["visible-columns"] = ALL if show else COMPACT
        table.update()

    ui.switch("all columns", on_change=lambda e: all_columns(bool(e.value))).props(
        f"dense data-testid=components-columns-{robot.key}"
    )
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

    pushed: dict[str, Any] = {"messages": -1, "at": -UPDATE_S, "rows": None}
    every_second = os.environ.get(POLICY_VARIABLE) == "every-second"

    def refresh() -> None:
        if not model.active:
            return
        now = time.monotonic()
        if every_second or (model.messages != pushed["messages"]
                            and now - pushed["at"] >= UPDATE_S):
            rows = model.rows()
            shown = [table_row(r, robot) for r in rows]
            pushed["messages"], pushed["at"] = model.messages, now
            if every_second or shown != pushed["rows"]:
                pushed["rows"] = shown
                table.rows = shown
                table.update()
        text = status_text(model)
        if text != status.text:
            status.text = text

    ctx.follow(model, ui.timer(POLL_S, refresh, active=False))


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
