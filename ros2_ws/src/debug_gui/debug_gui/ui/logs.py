"""The diagnostics and log view: one robot's /diagnostics statuses and /rosout records.

Statuses show the newest per name, worst first; records newest first. One filter (a
minimum level and a text matched against names and messages) applies to both, so "what
is wrong with the servo driver" is one word typed. Entries no robot's namespace claims are
marked ``shared`` (see :mod:`debug_gui.models.logs`). The level and the text are kept in
the panel's layout (settings ``level`` and ``filter``).
"""

from __future__ import annotations

import time
from typing import Any

from nicegui import ui

from ..errors import InvalidInput
from ..models.logs import LEVELS, LogEntry, LogsModel, StatusEntry
from .registry import ViewContext, register

POLL_S = 0.5

STATUS_COLUMNS: list[dict[str, Any]] = [
    {"name": "level", "label": "level", "field": "level", "align": "left"},
    {"name": "name", "label": "status", "field": "name", "align": "left"},
    {"name": "message", "label": "message", "field": "message", "align": "left"},
    {"name": "values", "label": "values", "field": "values", "align": "left"},
]
LOG_COLUMNS: list[dict[str, Any]] = [
    {"name": "time", "label": "time", "field": "time", "align": "left"},
    {"name": "level", "label": "level", "field": "level", "align": "left"},
    {"name": "logger", "label": "logger", "field": "logger", "align": "left"},
    {"name": "text", "label": "message", "field": "text", "align": "left"},
]


def status_row(s: StatusEntry) -> dict[str, Any]:
    return {"id": s.name, "level": s.level_name, "name": s.name + (" (shared)" * s.shared),
            "message": s.message, "values": ", ".join(f"{k}={v}" for k, v in s.values[:6])}


def log_row(i: int, e: LogEntry) -> dict[str, Any]:
    seconds = e.stamp_ns / 1e9
    clock = time.strftime("%H:%M:%S", time.localtime(seconds)) + f".{int(seconds % 1 * 1e3):03d}"
    return {"id": i, "time": clock, "level": e.level_name,
            "logger": e.logger + (" (shared)" * e.shared), "text": e.text}


@register(kind="logs", title="Diagnostics and log", order=60)
def build(ctx: ViewContext) -> None:
    assert ctx.robot is not None
    robot = ctx.robot
    model = LogsModel(ctx.source, robot)
    key = robot.key
    with ui.row().classes("items-center gap-2"):
        kept_level = ctx.text("level", "debug")
        level = ui.select(list(LEVELS), label="at least",
                          value=kept_level if kept_level in LEVELS else "debug").props(
            f"dense data-testid=logs-level-{key}").classes("w-32")
        text = ui.input("filter: name or text", value=ctx.text("filter")).props(
            f"dense clearable data-testid=logs-filter-{key}").classes("w-64")
        level.on_value_change(lambda e: ctx.keep("level", str(e.value or "")))
        text.on_value_change(lambda e: ctx.keep("filter", str(e.value or "")))
        problem = ui.label("").classes("text-negative")
    ui.label("Diagnostics").classes("text-bold")
    statuses = ui.table(columns=STATUS_COLUMNS, rows=[], row_key="id", pagination=0).props(
        f"dense flat virtual-scroll data-testid=logs-diagnostics-{key}"
    ).classes("w-full").style("max-height: 16rem")
    ui.label("Log").classes("text-bold")
    records = ui.table(columns=LOG_COLUMNS, rows=[], row_key="id", pagination=0).props(
        f"dense flat virtual-scroll data-testid=logs-records-{key}"
    ).classes("w-full").style("max-height: 24rem")

    def refresh() -> None:
        if not model.active:
            return
        try:
            lv, tx = str(level.value), str(text.value or "")
            statuses.rows = [status_row(s) for s in model.statuses(level=lv, text=tx)]
            records.rows = [log_row(i, e) for i, e in enumerate(model.logs(level=lv, text=tx))]
            problem.text = ""
        except InvalidInput as exc:
            problem.text = str(exc)
        statuses.update()
        records.update()

    ctx.follow(model, ui.timer(POLL_S, refresh, active=False))
