"""The components view (seed Fig. 5.3): one robot's callbacks, sortable, with history.

The table sorts in the browser (every column); rows whose own time exceeds their period
are marked ``over period`` and shaded. The view polls its model once a second, the rate
at which robots publish their statistics by default.
"""

from __future__ import annotations

from typing import Any

from nicegui import ui

from ..models.components import ComponentsModel, Row, sparkline
from .registry import ViewContext, register

POLL_S = 1.0
COLUMNS: list[dict[str, Any]] = [
    {"name": "flag", "label": "", "field": "flag", "sortable": True, "align": "left"},
    {"name": "node", "label": "component", "field": "node", "sortable": True, "align": "left"},
    {"name": "kind", "label": "kind", "field": "kind", "sortable": True, "align": "left"},
    {"name": "name", "label": "callback", "field": "name", "sortable": True, "align": "left"},
    {"name": "rate_hz", "label": "rate Hz", "field": "rate_hz", "sortable": True},
    {"name": "mean_ms", "label": "mean ms", "field": "mean_ms", "sortable": True},
    {"name": "p95_ms", "label": "p95 ms", "field": "p95_ms", "sortable": True},
    {"name": "max_ms", "label": "max ms", "field": "max_ms", "sortable": True},
    {"name": "period_ms", "label": "period ms", "field": "period_ms", "sortable": True},
    {"name": "calls", "label": "calls", "field": "calls", "sortable": True},
    {"name": "exceptions", "label": "exceptions", "field": "exceptions", "sortable": True},
    {"name": "drops", "label": "drops", "field": "drops", "sortable": True},
    {"name": "history", "label": "mean, last 30", "field": "history", "align": "left"},
    {"name": "process", "label": "process", "field": "process", "sortable": True,
     "align": "left"},
]


def _ms(ns: int) -> float:
    return round(ns / 1e6, 3)


def table_row(row: Row) -> dict[str, Any]:
    """A model row as the browser table shows it."""
    return {
        "id": "|".join(row.key),
        "flag": "over period" if row.over_period else "",
        "node": row.node, "kind": row.kind, "name": row.name,
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
    model = ComponentsModel(ctx.hub, ctx.robot)
    status = ui.label("waiting for the robot's statistics…").classes("text-caption").props(
        f"data-testid=components-status-{ctx.robot.key}"
    )
    table = ui.table(
        columns=COLUMNS, rows=[], row_key="id", pagination=0,
    ).props(
        f"dense flat data-testid=components-{ctx.robot.key}"
    ).classes("w-full")
    table.add_slot("body-cell-flag", r"""
        <q-td :props="props">
          <q-badge v-if="props.value" color="negative" :label="props.value" />
        </q-td>""")
    table.add_slot("body-cell-history", r"""
        <q-td :props="props" style="font-family: monospace">{{ props.value }}</q-td>""")

    def refresh() -> None:
        if not model.active:
            return
        rows = model.rows()
        table.rows = [table_row(r) for r in rows]
        table.update()
        age = model.age_s()
        flagged = sum(r.over_period for r in rows)
        if age is not None:
            status.text = (
                f"{len(rows)} callbacks, {flagged} over their period; "
                f"updated {age:.0f} s ago"
            )

    timer = ui.timer(POLL_S, refresh, active=False)

    def show() -> None:
        model.activate()
        timer.activate()

    def hide() -> None:
        timer.deactivate()
        model.deactivate()

    ctx.on_show(show)
    ctx.on_hide(hide)
