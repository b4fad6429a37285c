"""The parameters view (seed Fig. 5.4): any node's parameters, edited with typed widgets.

Pick one of the robot's nodes (type in the select to filter them); each parameter gets a
widget of its type: a switch for a boolean, a number field for an integer or a double
(its descriptor's range as the field's limits), a text field for a string, and for arrays
their text (``[1, 2, 3]``, checked when submitted). Enter (or a switch's flip) sets the
value on the node; beside the parameter the view then shows ``setting to ...…`` until the
node answers, then ``set to ...`` or the refusal, a node's veto in its own words. A typed
value outside the descriptor's range (shown under the parameter) is refused before it is
sent. Read-only parameters are disabled, and without the
server's token every widget is (the model refuses the write on the server all the same).
A change made elsewhere shows up live, marked ``changed elsewhere``. The chosen node and
the filter are kept in the panel's layout (settings ``node``, relative to the robot, and
``filter``) and chosen again when the view is rebuilt.
"""

from __future__ import annotations

import contextlib
from typing import Any

from nicegui import background_tasks, run, ui
from rcl_interfaces.msg import ParameterType as RosType

from ..errors import NOT_LIVE, DebugGuiError, NotLive
from ..models.parameters import Outcome, ParametersModel
from ..params import Described
from .registry import ViewContext, register

POLL_S = 0.5
NODES_POLL_S = 2.0


def _testid(prefix: str, key: str, name: str = "") -> str:
    return f"{prefix}-{key}" + (f"-{name}" if name else "")


def caption(param: Described) -> str:
    """Type, description and constraints, as the line under a parameter shows them."""
    parts = [param.type_name]
    if param.description:
        parts.append(param.description)
    if (limits := param.constraints()):
        parts.append(limits)
    return " · ".join(parts)


def outcome_text(outcome: Outcome | None) -> tuple[str, str]:
    """The text beside a parameter and its colour class."""
    if outcome is None:
        return "", ""
    if not outcome.ok:
        return outcome.message, "text-negative"
    if outcome.pending:
        return outcome.message, "text-grey-7"
    return outcome.message, "text-positive" if outcome.here else "text-info"


class _Row:
    """One parameter's widgets: its input and the outcome label beside it."""

    def __init__(self, param: Described, widget: Any, status: Any) -> None:
        self.param = param
        self.widget = widget
        self.status = status
        self.shown: Any = param.value

    def show_value(self, param: Described) -> None:
        self.param, self.shown = param, param.value
        if param.type == RosType.PARAMETER_BOOL:
            self.widget.value = bool(param.value)
        elif param.type in (RosType.PARAMETER_INTEGER, RosType.PARAMETER_DOUBLE):
            self.widget.value = param.value
        else:
            self.widget.value = param.text


@register(kind="parameters", title="Parameters", order=20)
def build(ctx: ViewContext) -> None:
    assert ctx.robot is not None  # a per-robot kind: the shell binds every instance
    robot = ctx.robot
    key = robot.key
    model = ParametersModel(ctx.source, robot, policy=ctx.policy, token=ctx.token)
    with ui.row().classes("items-center gap-2"):
        node = ui.select([], label="node", with_input=True).props(
            f"dense data-testid={_testid('params-node', key)}").classes("w-80")
        name_filter = ui.input("filter parameters", value=ctx.text("filter")).props(
            f"dense clearable data-testid={_testid('params-filter', key)}").classes("w-56")
    read_only = ("" if ctx.can_write else " (read-only: changes need the server's token)")
    if not ctx.source.live:  # a log: its parameter events, nothing to set or describe
        read_only = f" ({NOT_LIVE}: the values as the log recorded them, read-only)"
    status = ui.label("pick a node" + read_only).classes("text-caption").props(
        f"data-testid={_testid('params-status', key)}")
    box = ui.column().classes("w-full gap-1").props(f"data-testid={_testid('params', key)}")
    rows: dict[str, _Row] = {}
    drawn = {"shape": -1, "version": -1, "filter": ""}
    busy = {"loading": False}
    guard = {"on": False}

    async def load(chosen: str) -> None:
        busy["loading"] = True
        status.text = f"reading {chosen}…"
        try:
            got = await run.io_bound(model.load, chosen)
            status.text = f"{chosen}: {len(got or [])} parameters" + read_only
        except NotLive:  # chosen all the same: its values show as the log's events come
            status.text = chosen + read_only
        except DebugGuiError as exc:
            status.text = str(exc)
        finally:
            busy["loading"] = False
        refresh()

    async def submit(name: str) -> None:
        row = rows.get(name)
        if row is None:
            return
        raw = row.widget.value
        # At once, not at the next poll: the set may take a while (a slow node, a veto).
        _show_outcome(row, Outcome(True, "setting…", pending=True))
        outcome = await run.io_bound(model.set, name, raw)
        if rows.get(name) is not row:
            return  # redrawn meanwhile (another node, a filter): the new row shows it
        _show_outcome(row, outcome)
        now = model.value(name)
        if now is not None:  # the node's value: the new one, or the old after a refusal
            guard["on"] = True
            try:
                row.show_value(now)
            finally:
                guard["on"] = False

    def _show_outcome(row: _Row, outcome: Outcome | None) -> None:
        text, colour = outcome_text(outcome)
        row.status.text = text
        row.status.classes(replace=f"text-caption {colour}")

    async def on_switch(name: str) -> None:
        if not guard["on"]:  # a flip by the user, not the view showing the node's value
            await submit(name)

    def widget_for(param: Described) -> Any:
        testid = _testid("param", key, param.name)
        if param.type == RosType.PARAMETER_BOOL:
            widget: Any = ui.switch(value=bool(param.value),
                                    on_change=lambda _e, n=param.name: on_switch(n))
        elif param.type in (RosType.PARAMETER_INTEGER, RosType.PARAMETER_DOUBLE):
            rng = param.integer_range or param.floating_point_range
            integer = param.type == RosType.PARAMETER_INTEGER
            widget = ui.number(
                value=param.value,
                min=min(rng[0], rng[1]) if rng else None,
                max=max(rng[0], rng[1]) if rng else None,
                step=(rng[2] or None) if rng else (1 if integer else None),
            ).classes("w-40")
            if not integer and not (rng and rng[2]):
                widget.props("step=any")
            widget.on("keydown.enter", lambda _e, n=param.name: submit(n))
        else:
            widget = ui.input(value=param.text).classes("w-72")
            widget.on("keydown.enter", lambda _e, n=param.name: submit(n))
        widget.props(f"dense data-testid={testid}")
        if param.read_only or not ctx.can_write or not ctx.source.live \
                or param.type == RosType.PARAMETER_NOT_SET:
            widget.disable()
        return widget

    def rebuild() -> None:
        box.clear()
        rows.clear()
        with box:
            for param in model.parameters(str(name_filter.value or "")):
                with ui.row().classes("items-center gap-3 w-full no-wrap"):
                    with ui.column().classes("gap-0 w-64"):
                        ui.label(param.name).classes("text-bold").props(
                            f"title={param.name}")
                        ui.label(caption(param)).classes("text-caption text-grey-8")
                    widget = widget_for(param)
                    label = ui.label("").classes("text-caption").props(
                        f"data-testid={_testid('param-status', key, param.name)}")
                row = _Row(param, widget, label)
                rows[param.name] = row
                _show_outcome(row, model.outcome(param.name))

    def refresh() -> None:
        if not model.active:
            return
        if model.stale and not busy["loading"] and model.node is not None:
            reload(str(model.node))
        text = str(name_filter.value or "")
        if drawn["shape"] != model.shape or drawn["filter"] != text:
            drawn["shape"], drawn["filter"], drawn["version"] = model.shape, text, model.version
            rebuild()
            return
        if drawn["version"] == model.version:
            return
        drawn["version"] = model.version
        guard["on"] = True
        try:
            for param in model.parameters(text):
                row = rows.get(param.name)
                if row is None:
                    continue
                if param.value != row.shown or param.type != row.param.type:
                    row.show_value(param)
                _show_outcome(row, model.outcome(param.name))
        finally:
            guard["on"] = False

    def refresh_nodes() -> None:
        if not model.active:
            return
        with contextlib.suppress(DebugGuiError):  # the robot went: its nodes go with it
            options = model.nodes()
            if model.node is not None and model.node not in options:
                options.append(model.node)
            if options != node.options:
                node.set_options(options, value=node.value)

    def reload(chosen: str) -> None:
        busy["loading"] = True
        background_tasks.create(load(chosen), name=f"parameters of {chosen}")

    def on_node(event: Any) -> None:
        if isinstance(event.value, str) and event.value:
            ctx.keep("node", robot.relative(event.value))
            reload(event.value)

    def on_show() -> None:
        refresh_nodes()
        if model.node is not None:  # changes made while hidden were not followed
            reload(model.node)
        elif (kept := ctx.text("node")) and node.value is None:
            try:
                chosen = robot.resolve(kept)  # the layout's node: chosen as the user did
            except DebugGuiError as exc:
                status.text = f"the layout's node {kept!r}: {exc}"
                return
            node.set_options([*(o for o in node.options if o != chosen), chosen],
                             value=chosen)

    def on_filter(_event: Any) -> None:
        ctx.keep("filter", str(name_filter.value or ""))
        refresh()

    node.on_value_change(on_node)
    name_filter.on_value_change(on_filter)
    nodes_timer = ui.timer(NODES_POLL_S, refresh_nodes, active=False)
    ctx.follow(model, ui.timer(POLL_S, refresh, active=False), nodes_timer)
    ctx.on_show(on_show)
