"""The shell: robots, the central binding view, panels of view instances, layouts.

Each browser tab gets its own copy of the server's current layout (read from ``--layout``
at start, replaced by "save layout"), and its own view instances: a view's models live as
long as the tab shows it. A panel is one view kind bound to one robot, or a team panel with
one instance per robot side by side; robots that appear join team panels live.

A tab's working layout (panels and each panel's settings) is kept in NiceGUI's tab storage
at every change, so a page that NiceGUI reloads (a lost connection, a failed handshake) or
the user reloads comes back as it was rather than as the server's layout. "save layout"
never silently replaces a saved layout this tab did not see: each tab remembers the file's
text as it last loaded or saved it, and a save over a file that changed since is refused
with a message; saving again then replaces it.

The binding view (seed Fig. 5.7) lists every panel with a robot selector (rebind), "clone
for" another robot (Fig. 5.8) and remove; below it a view kind can be added for one robot or
as a team panel.
"""

from __future__ import annotations

import functools
import logging
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

from nicegui import Client, app, ui

from ..errors import DebugGuiError, InvalidInput, LayoutConflict
from ..layout import Layout, Panel, Setting, saved_text
from ..robots import RobotId
from ..security import AccessPolicy
from ..source import Source
from . import registry
from .registry import ViewContext

_log = logging.getLogger(__name__)
TEAM = "team"
#: How often the shell looks for robots coming and going.
ROBOTS_POLL_S = 1.0
#: The key of a tab's working layout in NiceGUI's tab storage.
TAB_KEY = "debug_gui_layout"


@dataclass
class Shell:
    """Server-wide state: the Hub, the access policy and the layout new tabs start from."""

    source: Source
    policy: AccessPolicy
    layout: Layout
    layout_path: Path | None = None
    #: The layout file's text when :attr:`layout` was read or written (None: no file).
    seen: str | None = None
    #: Builds what goes above the views on each tab, given the tab's token (the playback
    #: bar of ``debug_gui --log``); None live.
    bar: Callable[[str | None], None] | None = None

    def __post_init__(self) -> None:
        if self.layout_path is not None:
            self.seen = saved_text(self.layout_path)

    def default_layout(self) -> Layout:
        kinds = [k.kind for k in registry.kinds()]
        return Layout((Panel(kind="components"),)) if "components" in kinds else Layout()

    def save(self, layout: Layout, token: str | None, *, seen: str | None) -> str:
        """Save ``layout`` unless the file changed since it was ``seen`` (LayoutConflict);
        the text written, the tab's new ``seen``."""
        self.policy.check_write(token)
        if self.layout_path is None:
            raise InvalidInput("no layout file: start debug_gui with --layout FILE")
        self.seen = layout.save_over(self.layout_path, seen=seen)
        self.layout = layout
        return self.seen

    def restore(self) -> Layout:
        if self.layout_path is None:
            raise InvalidInput("no layout file: start debug_gui with --layout FILE")
        self.layout = Layout.load(
            self.layout_path, known_kinds=[k.kind for k in registry.kinds()]
        )
        self.seen = saved_text(self.layout_path)
        return self.layout


@dataclass
class _Instance:
    robot: RobotId | None
    ctx: ViewContext
    container: Any


@dataclass
class _PanelView:
    panel: Panel
    expansion: Any
    body: Any
    instances: list[_Instance] = field(default_factory=list)
    robots: tuple[RobotId, ...] = ()


class _Tab:
    """One browser tab's shell: its layout, its panels, its view instances."""

    def __init__(self, shell: Shell, client: Client, token: str | None) -> None:
        self.shell = shell
        self.client = client
        self.token = token
        #: The saved layout's text as this tab last loaded or wrote it (see Shell.save).
        self.seen = shell.seen
        #: Whether this page looked for its tab's working layout (on its first connect).
        self.adopted = False
        self._layout = shell.layout
        self.views: list[_PanelView] = []
        self.robots: list[RobotId] = shell.source.robots()
        #: The view kind and robot last chosen for "add": kept across the binding view's
        #: re-renders (each add, each robot coming or going), so adding several views for
        #: one robot does not mean choosing it again every time.
        self.add_kind: str | None = None
        self.add_robot = TEAM
        #: Whether this tab has seen a robot: "no robots yet" until then, "no robots" after.
        self.seen_robots = bool(self.robots)

    @property
    def layout(self) -> Layout:
        return self._layout

    @layout.setter
    def layout(self, layout: Layout) -> None:
        """Every change of the working layout is kept in the tab's storage at once."""
        self._layout = layout
        self._keep()

    def _keep(self) -> None:
        if not self.adopted or not self.client.has_socket_connection:
            return  # before the first connect there is no tab storage (nor a change)
        with self.client:
            app.storage.tab[TAB_KEY] = {"layout": self._layout.to_json(), "seen": self.seen}

    def _adopt(self) -> None:
        """On this page's first connect: take the tab's working layout if an earlier page
        of the same tab left one (NiceGUI reloaded it, or the user did)."""
        if self.adopted:
            self._keep()
            return
        self.adopted = True
        with self.client:
            kept = app.storage.tab.get(TAB_KEY)
        if isinstance(kept, dict) and isinstance(kept.get("layout"), str):
            try:
                layout = Layout.from_json(kept["layout"], known_kinds=_kinds())
            except InvalidInput as exc:
                _log.warning("the tab's kept layout is not used: %s", exc)
            else:
                seen = kept.get("seen")
                self.seen = seen if isinstance(seen, str) else None
                if layout != self._layout:
                    self._set_layout(layout)
        self._keep()

    # -- page --------------------------------------------------------------------------

    def build(self) -> None:
        with ui.header().classes("items-center gap-4"):
            ui.label("debug_gui").classes("text-h6")
            self.robots_row = ui.row().classes("items-center gap-2").props(
                "data-testid=robots"
            )
            ui.space()
            access = "write access" if self.shell.policy.valid(self.token) else "read-only"
            ui.label(access).props("data-testid=access")
        if self.shell.bar is not None:
            self.shell.bar(self.token)
        self.binding = ui.card().classes("w-full").props("data-testid=binding")
        self.panels = ui.column().classes("w-full gap-2")
        self._render_robots()
        self._render_binding()
        self._render_panels()
        ui.timer(ROBOTS_POLL_S, self._poll_robots)
        # A tab that goes (or loses its connection) stops its views' feeds; one that
        # reconnects gets those of its open panels back.
        self.client.on_delete(self._hide_all)
        self.client.on_disconnect(self._hide_all)
        self.client.on_connect(self._adopt)
        self.client.on_connect(self._show_open)

    def _poll_robots(self) -> None:
        robots = self.shell.source.robots()
        if robots == self.robots:
            return
        self.robots = robots
        self.seen_robots = self.seen_robots or bool(robots)
        self._render_robots()
        self._render_binding()
        for view in self.views:
            if view.panel.team and tuple(robots) != view.robots:
                self._fill(view)
            elif not view.panel.team:
                online = view.panel.robot in robots
                view.expansion.props(f"caption='{'' if online else 'robot gone'}'")

    def _render_robots(self) -> None:
        self.robots_row.clear()
        with self.robots_row:
            if not self.robots:
                ui.label(self._no_robots()).classes("italic")
            for robot in self.robots:
                ui.chip(robot.label, icon="smart_toy").props(
                    f"dense data-testid=robot-{robot.key}"
                )

    def _no_robots(self) -> str:
        return "no robots" if self.seen_robots else "no robots yet"

    # -- binding view ------------------------------------------------------------------

    def _robot_options(self, *, team: bool) -> dict[str, str]:
        options = {r.key: r.label for r in self.robots}
        if team:
            options[TEAM] = "team: every robot"
        return options

    def _robot_of(self, key: str) -> RobotId | None:
        if key == TEAM:
            return None
        for robot in self.robots:
            if robot.key == key:
                return robot
        raise InvalidInput(f"no robot {key!r} (robots: {[r.key for r in self.robots]})")

    def _render_binding(self) -> None:
        self.binding.clear()
        with self.binding:
            ui.label("Views and robots").classes("text-subtitle1")
            for index, panel in enumerate(self.layout.panels):
                self._binding_row(index, panel)
            with ui.row().classes("items-center gap-2"):
                kinds = {k.kind: k.title for k in registry.kinds()}
                if self.add_kind not in kinds:
                    self.add_kind = next(iter(kinds), None)
                robots = self._robot_options(team=True)
                if self.add_robot not in robots:
                    self.add_robot = TEAM  # the robot chosen last has gone
                kind = ui.select(kinds, label="view", value=self.add_kind,
                                 on_change=lambda e: setattr(self, "add_kind", e.value)).props(
                    "dense data-testid=add-kind"
                ).classes("w-40")
                robot = ui.select(robots, label="robot", value=self.add_robot,
                                  on_change=lambda e: setattr(self, "add_robot", e.value)).props(
                    "dense data-testid=add-robot"
                ).classes("w-56")
                ui.button("add", on_click=lambda: self._guard(
                    lambda: self._add(Panel(kind=kind.value, robot=self._robot_of(robot.value)))
                )).props("data-testid=add-view")
                ui.button("team layout", on_click=lambda: self._guard(
                    lambda: self._add(Panel(kind=kind.value))
                )).props("flat data-testid=team-layout")
            with ui.row().classes("items-center gap-2"):
                where = self.shell.layout_path or "no --layout file"
                ui.button("save layout", on_click=lambda: self._guard(self._save)).props(
                    "flat data-testid=save-layout"
                )
                ui.button("restore layout", on_click=lambda: self._guard(self._restore)).props(
                    "flat data-testid=restore-layout"
                )
                ui.label(str(where)).classes("text-caption")

    def _binding_row(self, index: int, panel: Panel) -> None:
        title = registry.get(panel.kind).title if panel.kind in _kinds() else panel.kind
        with ui.row().classes("items-center gap-2").props(f"data-testid=binding-{index}"):
            ui.label(f"{index + 1}. {title}").classes("w-40")
            options = self._robot_options(team=True)
            value = TEAM if panel.robot is None else panel.robot.key
            if value not in options and panel.robot is not None:
                options[value] = f"{panel.robot.label} (gone)"
            ui.select(
                options, value=value,
                on_change=lambda e, i=index: self._guard(
                    lambda: self._rebind(i, e.value)
                ),
            ).props(f"dense data-testid=bind-{index}").classes("w-56")
            clone = ui.select(
                self._robot_options(team=False), label="clone for",
            ).props(f"dense data-testid=clone-{index}").classes("w-56")
            clone.on_value_change(lambda e, i=index: self._guard(lambda: self._clone(i, e.value)))
            ui.button(icon="close", on_click=lambda i=index: self._guard(
                lambda: self._remove(i)
            )).props(f"flat dense data-testid=remove-{index}")

    def _guard(self, action: Callable[[], Any]) -> None:
        """Run a user's action; our errors become a notification, never a dead page."""
        try:
            action()
        except DebugGuiError as exc:
            self._notify(str(exc), kind="negative")

    def _notify(self, message: str, *, kind: Literal["positive", "negative"]) -> None:
        """Notify this tab. Not in the handler's own slot: an action that re-renders the
        binding view (restore, remove, rebind) has deleted the element that called it, and
        ui.notify would find no client there."""
        with self.client:
            ui.notify(message, type=kind)

    # -- layout changes ----------------------------------------------------------------

    def _set_layout(self, layout: Layout) -> None:
        self.layout = layout
        self._render_binding()
        self._render_panels()

    def _add(self, panel: Panel, *, at: int | None = None) -> None:
        """Add ``panel`` at index ``at`` (default: last)."""
        registry.get(panel.kind)
        index = len(self.layout.panels) if at is None else at
        self.layout = self.layout.inserting(index, panel)
        self._render_binding()
        self._add_panel(panel, at=index)

    def _clone(self, index: int, key: str | None) -> None:
        """Panel ``index`` for robot ``key``, right after the original."""
        if key:
            panel = self.layout.panels[index]
            self._add(Panel(kind=panel.kind, robot=self._robot_of(key),
                            settings=panel.settings), at=index + 1)

    def _remove(self, index: int) -> None:
        self.layout = self.layout.without(index)
        view = self.views.pop(index)
        self._hide(view)
        view.expansion.delete()
        self._number_panels(index)
        self._render_binding()

    def _rebind(self, index: int, key: str) -> None:
        old = self.layout.panels[index]
        panel = Panel(kind=old.kind, robot=self._robot_of(key), settings=old.settings)
        self.layout = self.layout.replacing(index, panel)
        view = self.views[index]
        view.panel = panel
        view.expansion.text = self._title(panel)
        self._fill(view)
        self._render_binding()

    def _save(self) -> None:
        try:
            self.seen = self.shell.save(self.layout, self.token, seen=self.seen)
        except LayoutConflict:
            # Told once: the next save replaces the layout the user now knows about.
            self.seen = saved_text(self.shell.layout_path) if self.shell.layout_path else None
            self._keep()
            raise
        self._keep()
        self._notify(f"layout saved to {self.shell.layout_path}", kind="positive")

    def _restore(self) -> None:
        layout = self.shell.restore()
        self.seen = self.shell.seen
        self._set_layout(layout)
        self._notify("layout restored", kind="positive")

    def _remember(self, view: _PanelView, key: str, value: Setting | None) -> None:
        """A view's setting changed: into its panel, so layouts and reloads keep it."""
        index = next((i for i, v in enumerate(self.views) if v is view), None)
        if index is None:
            return  # removed meanwhile
        try:
            panel = view.panel.with_setting(key, value)
        except InvalidInput as exc:
            _log.warning("setting %s of a %s view not kept: %s", key, view.panel.kind, exc)
            return
        if panel != view.panel:
            view.panel = panel
            self.layout = self.layout.replacing(index, panel)

    # -- panels ------------------------------------------------------------------------

    def _title(self, panel: Panel) -> str:
        title = registry.get(panel.kind).title
        return f"{title} — {'team' if panel.robot is None else panel.robot.label}"

    def _render_panels(self) -> None:
        self._hide_all()
        self.views.clear()
        self.panels.clear()
        for panel in self.layout.panels:
            self._add_panel(panel)

    def _add_panel(self, panel: Panel, *, at: int | None = None) -> None:
        index = len(self.views) if at is None else at
        with self.panels:
            expansion = ui.expansion(self._title(panel), value=True).classes(
                "w-full"
            ).props(f"dense header-class=bg-grey-3 data-testid=panel-{index}")
            with expansion:
                body = ui.element("div").classes("w-full items-start").style(
                    registry.TEAM_GRID)
        if index < len(self.views):
            expansion.move(target_index=index)
        view = _PanelView(panel=panel, expansion=expansion, body=body)
        expansion.on_value_change(lambda e, v=view: self._toggle(v, bool(e.value)))
        self.views.insert(index, view)
        self._number_panels(index + 1)
        self._fill(view)

    def _number_panels(self, start: int) -> None:
        """Panels from ``start`` on moved (one inserted or removed before them): their test
        ids follow their place, as the binding view's rows do."""
        for index, view in enumerate(self.views[start:], start=start):
            view.expansion.props(f"data-testid=panel-{index}")

    def _toggle(self, view: _PanelView, shown: bool) -> None:
        # A page only counts as seen once its browser is connected: a page fetched by
        # something that never connects (a health check, curl) must not subscribe to
        # anything. The connection's on_connect shows the open panels then.
        shown = shown and self.client.has_socket_connection
        for inst in view.instances:
            if shown:
                inst.ctx.show()
            else:
                inst.ctx.hide()

    def _fill(self, view: _PanelView) -> None:
        """(Re)build the panel's instances: one, or one per robot for a team panel."""
        self._hide(view)
        view.instances.clear()
        view.body.clear()
        kind = registry.get(view.panel.kind)
        robots: list[RobotId | None]
        if view.panel.robot is not None:
            robots = [view.panel.robot]
        elif kind.team:
            robots = [None]
        else:
            robots = list(self.robots)
        view.robots = tuple(self.robots)
        with view.body:
            if not robots:
                ui.label(f"{self._no_robots()}: they appear here when found").classes(
                    "italic")
            for robot in robots:
                with ui.column().classes("min-w-0") as container:
                    if view.panel.robot is None and robot is not None:
                        ui.label(robot.label).classes("text-bold")
                    ctx = ViewContext(
                        source=self.shell.source, robot=robot, robots=list(self.robots),
                        policy=self.shell.policy, token=self.token, app=app,
                        settings=dict(view.panel.settings),
                        remember=functools.partial(self._remember, view),
                    )
                    try:
                        kind.build(ctx)
                    except Exception as exc:
                        _log.exception("building view %s for %s", kind.kind, robot)
                        ui.label(f"this view failed to build: {exc}").classes("text-negative")
                view.instances.append(_Instance(robot=robot, ctx=ctx, container=container))
        if view.expansion.value:
            self._toggle(view, True)

    def _hide(self, view: _PanelView) -> None:
        for inst in view.instances:
            inst.ctx.hide()

    def _show_open(self) -> None:
        for view in self.views:
            if view.expansion.value:
                self._toggle(view, True)

    def _hide_all(self) -> None:
        for view in self.views:
            self._hide(view)


def _kinds() -> set[str]:
    return {k.kind for k in registry.kinds()}


def install(shell: Shell) -> None:
    """Register the page (``/``, with ``?token=`` for write access) and the policy's guard."""

    @ui.page("/", title="debug_gui")
    def index(client: Client, token: str | None = None) -> None:
        if not shell.policy.loopback and not shell.policy.valid(token):
            ui.label("This debug_gui needs its token: open the URL it printed.").props(
                "data-testid=denied"
            )
            return
        _Tab(shell, client, token).build()
