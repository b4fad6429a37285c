"""The topics view: a robot's topics with rates; click one to echo it as a tree; pick a
numeric field to plot it over the last 30 s.

The tree is rebuilt from the newest message at the echo rate with every node expanded
(a message is small; a tree that kept its own expansion state would show stale values).
The echoed topic (relative to the robot, with its type) and the plotted field are kept in
the panel's layout (settings ``echo``, ``echo_type``, ``field``) and echoed and plotted
again whenever the view is shown.
"""

from __future__ import annotations

from typing import Any

from nicegui import ui

from ..errors import DebugGuiError
from ..models.topics import TopicsModel
from .registry import ViewContext, register

POLL_S = 0.25
LIST_POLL_S = 2.0
COLUMNS: list[dict[str, Any]] = [
    {"name": "name", "label": "topic", "field": "name", "sortable": True, "align": "left"},
    {"name": "type", "label": "type", "field": "type", "sortable": True, "align": "left"},
    {"name": "rate", "label": "rate Hz", "field": "rate", "sortable": True},
]


def tree_nodes(value: Any, key: str = "", path: str = "") -> list[dict[str, Any]]:
    """A message tree as ui.tree nodes: ``label`` ``field: value``, ids the dotted paths."""
    if isinstance(value, dict):
        items: list[tuple[str, Any]] = list(value.items())
    elif isinstance(value, list):
        items = [(str(i), v) for i, v in enumerate(value)]
    else:
        return [{"id": path or key, "label": f"{key}: {value!r}" if key else repr(value)}]
    children = [node for k, v in items for node in tree_nodes(v, k, f"{path}.{k}" if path else k)]
    if not key:
        return children
    return [{"id": path, "label": key, "children": children}]


@register(kind="topics", title="Topics", order=50)
def build(ctx: ViewContext) -> None:
    assert ctx.robot is not None
    robot = ctx.robot
    key = robot.key
    model = TopicsModel(ctx.source, robot)
    table = ui.table(columns=COLUMNS, rows=[], row_key="name", pagination=0).props(
        f"dense flat virtual-scroll data-testid=topics-{key}"
    ).classes("w-full cursor-pointer").style("max-height: 18rem")
    heading = ui.label("click a topic to echo it").classes("text-bold").props(
        f"data-testid=topics-echo-title-{key}")
    problem = ui.label("").classes("text-negative")
    with ui.row().classes("w-full items-start"):
        tree_box = ui.column().classes("min-w-[20rem]").props(
            f"data-testid=topics-echo-{key}")
        with ui.column().classes("flex-1 min-w-[20rem]"):
            field = ui.select([], label="plot a numeric field", clearable=True).props(
                f"dense data-testid=topics-plot-field-{key}").classes("w-72")
            chart = ui.echart({
                "animation": False,
                "xAxis": {"type": "value", "name": "s", "min": -30, "max": 0},
                "yAxis": {"type": "value", "scale": True},
                "series": [{"type": "line", "showSymbol": False, "data": []}],
            }).classes("w-full h-56").props(f"data-testid=topics-plot-{key}")

    #: The kept field, plotted again once the echoed messages offer it.
    wanted = {"field": ""}

    def echo(name: str, type_name: str) -> bool:
        try:
            model.echo(name, type_name)
        except DebugGuiError as exc:
            problem.text = str(exc)
            return False
        problem.text = ""
        heading.text = f"{robot.resolve(name)} ({type_name})"
        return True

    def on_row(event: Any) -> None:
        row = event.args[1] if isinstance(event.args, list) and len(event.args) > 1 else {}
        name, type_name = row.get("name"), row.get("type")
        if not isinstance(name, str) or not isinstance(type_name, str):
            return
        if echo(name, type_name):
            ctx.keep("echo", robot.relative(robot.resolve(name)))
            ctx.keep("echo_type", type_name)
            wanted["field"] = ""
            field.set_value(None)

    table.on("rowClick", on_row)

    def on_field(event: Any) -> None:
        try:
            model.plot(event.value or None)
            problem.text = ""
        except DebugGuiError as exc:
            problem.text = str(exc)
            return
        if event.value or not wanted["field"]:  # not while the kept one waits for options
            ctx.keep("field", event.value or None)

    field.on_value_change(on_field)

    def refresh_list() -> None:
        if not model.active:
            return
        rows = []
        for t in model.topics():
            rate = t["rate_hz"]
            shown = "" if rate is None else f"{rate:.1f}" + (
                " (received)" if t["rate_source"] == "received" else "")
            if rate is not None and t["rate_capped"]:
                shown = f"≥ {rate:.1f} (the echo's rate: the topic's is unknown)"
            rows.append({"name": t["name"], "type": ", ".join(t["types"]), "rate": shown})
        table.rows = rows
        table.update()

    def refresh_echo() -> None:
        if not model.active or model.echo_topic is None:
            return
        last = model.last()
        if last is not None:
            tree_box.clear()
            with tree_box:
                # Every node open: Quasar's default-expand-all works only on the first
                # render, so NiceGUI refuses it; expand() opens them all explicitly.
                ui.tree(tree_nodes(last), label_key="label").props("dense").expand()
            options = model.fields()
            if options != field.options:
                field.set_options(options, value=field.value if field.value in options else None)
            if wanted["field"] in options:
                field.set_value(wanted["field"])
                wanted["field"] = ""
        series = model.series()
        chart.options["series"][0]["data"] = [[round(t, 3), v] for t, v in series]
        chart.update()

    timers = [ui.timer(LIST_POLL_S, refresh_list, active=False),
              ui.timer(POLL_S, refresh_echo, active=False)]

    def show() -> None:
        model.activate()
        for t in timers:
            t.activate()
        kept, kept_type = ctx.text("echo"), ctx.text("echo_type")
        if model.echo_topic is None and kept and kept_type and echo(kept, kept_type):
            wanted["field"] = ctx.text("field")
        refresh_list()

    def hide() -> None:
        for t in timers:
            t.deactivate()
        model.deactivate()

    ctx.on_show(show)
    ctx.on_hide(hide)
