"""The components view (seed Fig. 5.3): one robot's callbacks, sortable, with history.

The table sorts in the browser (every column); rows whose own time exceeds their period
are marked ``over period`` and shaded. The view polls its model once a second, the rate
at which robots publish their statistics by default.
"""

from __future__ import annotations

from typing import Any

from nicegui import ui

from ..models.components import ComponentsModel, Row, sparkline
from ..robots import RobotId
from .registry import ViewContext, register

POLL_S = 1.0
NO_STATISTICS = ("this robot publishes no efficient_comm statistics (a plain ROS 2 robot): "
                 "nothing to show here; its parameters and topics are in those views")
#: Long names (services, parameter events) are cut with an ellipsis; the full name shows on
#: hover. Otherwise one long name pushes the figures out of a team layout's narrow table.
_NARROW = {"classes": "ellipsis", "style": "max-width: 12rem", "headerStyle": "max-width: 12rem"}
COLUMNS: list[dict[str, Any]] = [
    {"name": "flag", "label": "", "field": "flag", "sortable": True, "align": "left"},
    {"name": "node", "label": "component", "field": "node", "sortable": True, "align": "left",
     **_NARROW},
    {"name": "name", "label": "callback", "field": "name", "sortable": True, "align": "left",
     **_NARROW},
    {"name": "rate_hz", "label": "rate Hz", "field": "rate_hz", "sortable": True},
    {"name": "mean_ms", "label": "mean ms", "field": "mean_ms", "sortable": True},
    {"name": "p95_ms", "label": "p95 ms", "field": "p95_ms", "sortable": True},
    {"name": "max_ms", "label": "max ms", "field": "max_ms", "sortable": True},
    {"name": "history", "label": "mean, last 30", "field": "history", "align": "left"},
    {"name": "period_ms", "label": "period ms", "field": "period_ms", "sortable": True},
    {"name": "calls", "label": "calls", "field": "calls", "sortable": True},
    {"name": "exceptions", "label": "exceptions", "field": "exceptions", "sortable": True},
    {"name": "drops", "label": "drops", "field": "drops", "sortable": True},
    {"name": "kind", "label": "kind", "field": "kind", "sortable": True, "align": "left"},
    {"name": "process", "label": "process", "field": "process", "sortable": True,
     "align": "left"},
]


ALL = [c["name"] for c in COLUMNS]
#: What fits when several robots' tables stand side by side.
COMPACT = [n for n in ALL if n not in {"period_ms", "calls", "kind", "process"}]


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
        f"dense flat data-testid=components-{robot.key}"
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
          <q-badge v-if="props.value" color="negative" :label="props.value" />
        </q-td>""")
    for column in ("node", "name"):
        table.add_slot(f"body-cell-{column}", r"""
        <q-td :props="props" :title="props.value">{{ props.value }}</q-td>""")
    table.add_slot("body-cell-history", r"""
        <q-td :props="props" style="font-family: monospace">{{ props.value }}</q-td>""")

    def refresh() -> None:
        if not model.active:
            return
        rows = model.rows()
        table.rows = [table_row(r, robot) for r in rows]
        table.update()
        age = model.age_s()
        flagged = sum(r.over_period for r in rows)
        if age is None and not model.statistics_published():
            status.text = NO_STATISTICS
        elif age is not None:
            status.text = (
                f"{len(rows)} callbacks, {flagged} over their period; "
                f"updated {age:.0f} s ago"
            )

    ctx.follow(model, ui.timer(POLL_S, refresh, active=False))
