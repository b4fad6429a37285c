"""The recorder view (seed Fig. 4.10): each robot's recorder, its status live, its controls.

A team kind: bound to the team, one instance shows every robot's recorders side by side
under **start all robots** / **stop all robots** (one click records the whole team); bound
to one robot, that robot's alone. Per recorder: its state, messages, bytes, drops and free
disk, updating with its status topic; start (into a bag name of one's choice, or the
recorder's own), stop, split and snapshot; the recorded topics with their counters; and a
topic selection editor (the robot's topics to tick, each with ``max_rate_hz`` /
``every_nth``, plus free entries in robot_recorder's syntax). Every answer, refused or not,
is shown under the recorder.

A page without the token shows the controls disabled; the model checks the token again on
the server for every write, so a browser cannot get around it.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from nicegui import run, ui

from ..errors import NOT_LIVE, DebugGuiError
from ..models.recorder import (
    ControlResult,
    RecorderModel,
    RecorderState,
    RecorderTeam,
    format_entry,
    relative,
)
from ..robots import RobotId
from .registry import TEAM_GRID, ViewContext, register

POLL_S = 0.5
#: The graph is asked for new recorders every this many polls (and at once when shown).
DISCOVER_EVERY = 4
READ_ONLY = "controlling recorders needs the server's token (open the URL it printed)"
_STATE_COLOURS = {"recording": "positive", "idle": "grey-7", "failed": "negative",
                  "waiting": "grey-5"}
#: Topic and type names are long and have no spaces: they break at any character rather
#: than push the figures out of a team layout's narrow card.
_BREAK = {"style": "overflow-wrap: anywhere; min-width: 6rem"}
TOPIC_COLUMNS: list[dict[str, Any]] = [
    {"name": "name", "label": "topic", "field": "name", "align": "left", "sortable": True,
     **_BREAK},
    {"name": "messages", "label": "messages", "field": "messages", "sortable": True},
    {"name": "bytes", "label": "bytes", "field": "bytes", "sortable": True},
    {"name": "drops", "label": "drops", "field": "drops", "sortable": True},
    {"name": "type", "label": "type", "field": "type", "align": "left", **_BREAK},
]


def human_bytes(count: int) -> str:
    """``12.3 MB``: decimal units, as disks are sold and ``df -H`` shows them."""
    value = float(count)
    for unit in ("B", "kB", "MB", "GB", "TB"):
        if value < 1000 or unit == "TB":
            return f"{value:.0f} {unit}" if unit == "B" else f"{value:.1f} {unit}"
        value /= 1000
    return f"{value:.1f} TB"  # unreachable; for the type checker


def figures(state: RecorderState) -> str:
    """The status line: messages, bytes, drops, free disk, the ring buffer."""
    line = (f"{state.messages:,} messages, {state.bytes:,} bytes ({human_bytes(state.bytes)}), "
            f"{state.drops:,} drops, {human_bytes(state.free_bytes)} free")
    if state.snapshot_bytes or state.snapshot_seconds:
        line += (f"; snapshot buffer {human_bytes(state.snapshot_bytes)}, "
                 f"{state.snapshot_seconds:.1f} s")
    return line


def entry_for(name: str, rate: object, nth: object) -> str:
    """One ticked topic as a selection entry; the numbers are left for robot_recorder's
    parser to judge (``every_nth=2.5`` is refused there, with its reason)."""
    parts = [name]
    if isinstance(rate, int | float) and rate:
        parts.append(f"max_rate_hz={rate:g}")
    if isinstance(nth, int | float) and nth and nth != 1:
        parts.append(f"every_nth={nth:g}")
    return " ".join(parts)


class _RecorderPanel:
    """One recorder's elements (built once per recorder found)."""

    def __init__(self, ctx: ViewContext, model: RecorderModel, node: str) -> None:
        self.ctx, self.model, self.node = ctx, model, node
        robot = model.robot
        key = f"{robot.key}-{relative(node, robot)}"
        self.key = key
        with ui.card().classes("w-full").props(f"flat bordered data-testid=recorder-{key}"):
            with ui.row().classes("items-center gap-2"):
                ui.label(relative(node, robot)).classes("text-bold")
                self.badge = ui.badge("waiting", color="grey-5").props(
                    f"data-testid=recorder-state-{key}")
            self.figures = ui.label("waiting for the recorder's status…").props(
                f"data-testid=recorder-figures-{key}")
            self.bag = ui.label("").classes("text-caption").style(
                "overflow-wrap: anywhere").props(f"data-testid=recorder-bag-{key}")
            self.error = ui.label("").classes("text-negative").props(
                f"data-testid=recorder-error-{key}")
            with ui.row().classes("items-center gap-1"):
                self.bag_name = ui.input("bag (optional)").props(
                    f"dense clearable data-testid=recorder-bagname-{key}").classes("w-48")
                self.buttons = [
                    ui.button(action, on_click=lambda a=action: self.act(a)).props(
                        f"dense data-testid=recorder-{action}-{key}")
                    for action in ("start", "stop", "split", "snapshot")
                ]
            self.result = ui.label("").classes("text-caption").props(
                f"data-testid=recorder-result-{key}")
            self.table = ui.table(columns=TOPIC_COLUMNS, rows=[], row_key="name",
                                  pagination=0).props(
                f"dense flat hide-pagination wrap-cells data-testid=recorder-topics-{key}"
            ).classes("w-full")
            with ui.expansion("topic selection", on_value_change=self._opened).props(
                    f"dense data-testid=recorder-editor-{key}").classes("w-full"):
                self.picks = ui.column().classes("gap-0").props(
                    f"data-testid=recorder-picks-{key}")
                self.entries = ui.textarea(
                    "more entries, one a line: NAME [TYPE] [max_rate_hz=R] [every_nth=N]"
                ).props(f"dense data-testid=recorder-entries-{key}").classes("w-full")
                with ui.row().classes("gap-1"):
                    self.apply = ui.button("apply selection", on_click=self.apply_selection
                                           ).props(f"dense data-testid=recorder-apply-{key}")
                    self.reload = ui.button("reload topics", on_click=self.load_topics).props(
                        f"flat dense data-testid=recorder-reload-{key}")
        self.rows: dict[str, tuple[Any, Any, Any]] = {}
        if not ctx.source.live:  # a log's recorder status, nothing to command
            self.result.text = f"{NOT_LIVE}: the recorder's status as the log recorded it"
        if not ctx.can_write or not ctx.source.live:
            for element in (*self.buttons, self.bag_name, self.apply, self.entries):
                element.disable()
            for button in (*self.buttons, self.apply):
                button.tooltip(READ_ONLY if ctx.source.live else NOT_LIVE)

    def update(self, state: RecorderState) -> None:
        if self.badge.text != state.state:  # props() would resend the badge every poll
            self.badge.text = state.state
            self.badge.props(f"color={_STATE_COLOURS.get(state.state, 'grey-7')}")
        if state.statuses:
            self.figures.text = figures(state)
        where = f"bag {state.bag}" if state.bag else "no bag yet"
        self.bag.text = where + (f", file {state.file}" if state.file else "")
        self.error.text = state.error
        rows = [{"name": relative(t.name, state.robot), "type": t.type,
                 "messages": t.messages, "bytes": t.bytes, "drops": t.drops}
                for t in state.topics]
        if rows != self.table.rows:
            self.table.rows = rows
            self.table.update()

    def show(self, text: str, *, ok: bool) -> None:
        self.result.text = text
        # Shown in place, under the recorder it concerns (a notification would cover
        # the controls below it for seconds).
        self.result.classes(replace="text-caption " + ("text-positive" if ok
                                                       else "text-negative"))

    async def act(self, action: str) -> None:
        bag = str(self.bag_name.value or "")
        calls: dict[str, Callable[[], ControlResult]] = {
            "start": lambda: self.model.start(self.node, bag=bag),
            "stop": lambda: self.model.stop(self.node),
            "split": lambda: self.model.split(self.node),
            "snapshot": lambda: self.model.snapshot(self.node, bag=bag),
        }
        await self._run(calls[action])

    async def _run(self, call: Callable[[], ControlResult]) -> None:
        try:
            self.ctx.policy.check_write(self.ctx.token)  # the model checks again
            result = await run.io_bound(call)
        except DebugGuiError as exc:
            self.show(str(exc), ok=False)
            return
        if result is None:  # the server is shutting down
            return
        self.show(result.text, ok=result.success)

    # -- topic selection editor ------------------------------------------------------------

    def _opened(self, event: Any) -> None:
        if event.value and not self.rows:
            self.load_topics()

    def load_topics(self) -> None:
        """List the robot's topics, ticked as the recorder records them."""
        robot = self.model.robot
        try:
            topics = self.ctx.source.topics(robot)
            selected = {robot.resolve(s.name): s for s in self.model.selection(self.node)}
        except DebugGuiError as exc:
            self.show(str(exc), ok=False)
            return
        self.picks.clear()
        self.rows.clear()
        with self.picks:
            for name in topics:
                chosen = selected.pop(name, None)
                with ui.row().classes("items-center gap-1 no-wrap"):
                    tick = ui.checkbox(relative(name, robot), value=chosen is not None).props(
                        f"dense data-testid=recorder-pick-{self.key}-{relative(name, robot)}")
                    rate = ui.number("max Hz", value=chosen.max_rate_hz if chosen and
                                     chosen.max_rate_hz else None, min=0).props(
                        "dense").classes("w-20")
                    nth = ui.number("every nth", value=chosen.every_nth if chosen and
                                    chosen.every_nth > 1 else None, min=1, precision=0).props(
                        "dense").classes("w-20")
                    if not self.ctx.can_write or not self.ctx.source.live:
                        for element in (tick, rate, nth):
                            element.disable()
                self.rows[name] = (tick, rate, nth)
        # Selected topics not on the graph (no publisher yet) stay as free entries.
        if selected:
            self.entries.value = "\n".join(format_entry(s) for s in selected.values())

    async def apply_selection(self) -> None:
        entries = [entry_for(name, rate.value, nth.value)
                   for name, (tick, rate, nth) in self.rows.items() if tick.value]
        entries += str(self.entries.value or "").splitlines()
        await self._run(lambda: self.model.set_topics(entries, self.node))


class _RobotColumn:
    """One robot's recorders; rebuilt when the recorders found change."""

    def __init__(self, ctx: ViewContext, model: RecorderModel, *, titled: bool) -> None:
        self.ctx, self.model = ctx, model
        robot: RobotId = model.robot
        with ui.column().classes("min-w-0 gap-1").props(
                f"data-testid=recorder-robot-{robot.key}"):
            if titled:
                ui.label(robot.label).classes("text-bold")
            self.box = ui.column().classes("w-full gap-1")
        self.panels: dict[str, _RecorderPanel] = {}
        self.nodes: list[str] | None = None

    def refresh(self, *, discover: bool) -> None:
        nodes = self.nodes
        if discover or nodes is None:
            try:
                nodes = self.model.discover()
            except DebugGuiError as exc:  # the robot's domain went away
                nodes = []
                self.box.clear()
                with self.box:
                    ui.label(str(exc)).classes("text-negative")
        if nodes != self.nodes:
            self.nodes = nodes
            self.box.clear()
            self.panels.clear()
            with self.box:
                if not nodes:
                    ui.label(f"{self.model.robot.label} has no recorder (yet): none of its "
                             "nodes offers a recorder's status and start service"
                             if self.ctx.source.live else
                             f"{self.model.robot.label}: {NOT_LIVE}: the log holds no "
                             "recorder's status").classes(
                        "italic").props(f"data-testid=recorder-none-{self.model.robot.key}")
                for node in nodes:
                    self.panels[node] = _RecorderPanel(self.ctx, self.model, node)
        for state in self.model.states():
            panel = self.panels.get(state.node)
            if panel is not None:
                panel.update(state)


@register(kind="recorder", title="Recorder", team=True, order=70)
def build(ctx: ViewContext) -> None:
    robots = [ctx.robot] if ctx.robot is not None else list(ctx.robots)
    team = RecorderTeam([RecorderModel(ctx.source, r, policy=ctx.policy, token=ctx.token)
                         for r in robots])
    if ctx.robot is None:
        with ui.row().classes("items-center gap-2"):
            start_all = ui.button("start all robots", icon="fiber_manual_record").props(
                "color=negative data-testid=recorder-start-all")
            stop_all = ui.button("stop all robots", icon="stop").props(
                "data-testid=recorder-stop-all")
            if not ctx.can_write or not ctx.source.live:
                for button in (start_all, stop_all):
                    button.disable()
                    button.tooltip(READ_ONLY if ctx.source.live else NOT_LIVE)
        all_result = ui.column().classes("gap-0 text-caption").props(
            "data-testid=recorder-all-result")

        async def for_all(action: str) -> None:
            try:
                ctx.policy.check_write(ctx.token)  # each model checks again
                results = await run.io_bound(team.for_all, action) or []
            except DebugGuiError as exc:
                all_result.clear()
                with all_result:
                    ui.label(str(exc)).classes("text-negative")
                return
            all_result.clear()
            with all_result:
                for result in results:
                    ui.label(result.text).classes(
                        "text-positive" if result.success else "text-negative")

        start_all.on_click(lambda: for_all("start"))
        stop_all.on_click(lambda: for_all("stop"))
    if not robots:
        ui.label("no robots yet").classes("italic")
    with ui.element("div").classes("w-full items-start").style(TEAM_GRID):
        columns = [_RobotColumn(ctx, m, titled=ctx.robot is None) for m in team.models]
    ticks = {"n": 0}

    def refresh() -> None:
        if not team.active:
            return
        discover = ticks["n"] % DISCOVER_EVERY == 0
        ticks["n"] += 1
        for column in columns:
            column.refresh(discover=discover)

    ctx.follow(team, ui.timer(POLL_S, refresh, active=False))
