"""View kinds and what a view instance gets to build itself with.

A view module registers its builder::

    @register(kind="components", title="Components")
    def build(ctx: ViewContext) -> None:
        model = ComponentsModel(ctx.source, ctx.robot)
        ctx.on_show(model.activate)
        ctx.on_hide(model.deactivate)
        ...  # NiceGUI elements, a ui.timer polling the model

The shell calls the builder inside the view instance's container, then ``on_show``
callbacks while the instance is visible and ``on_hide`` ones when it is collapsed,
removed, rebound or its browser tab goes away.
"""

from __future__ import annotations

import importlib
import logging
import pkgutil
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from ..errors import InvalidInput
from ..layout import Setting
from ..robots import RobotId
from ..security import AccessPolicy
from ..source import Source

_log = logging.getLogger(__name__)

#: How a team's robots stand side by side (the shell's team panels, the recorder's robots):
#: as many equal columns of at least 28rem as the window has room for (three at 1600 px),
#: the others on the next line, so no robot is cut off behind a scroll bar (two at 1280 px).
TEAM_GRID = ("display: grid; gap: 0.5rem; "
             "grid-template-columns: repeat(auto-fit, minmax(min(100%, 28rem), 1fr))")


@dataclass(slots=True)
class ViewContext:
    """What a view instance is bound to and may use."""

    source: Source
    #: The robot this instance shows (None only for a kind registered with team=True).
    robot: RobotId | None
    #: Every robot known when the view was built (team views, robot pickers).
    robots: list[RobotId]
    policy: AccessPolicy
    #: The token this browser session presented (None: read-only); pass it to
    #: ``policy.check_write`` before any change to a robot.
    token: str | None
    #: The FastAPI app, for routes of a view's own (e.g. a binary image endpoint).
    app: Any = None
    #: What this panel's view was set to (its layout's settings): read when building.
    settings: dict[str, Setting] = field(default_factory=dict)
    #: Keeps a setting in the panel's layout (None: drop it); see :meth:`keep`.
    remember: Callable[[str, Setting | None], None] | None = None
    _show: list[Callable[[], None]] = field(default_factory=list)
    _hide: list[Callable[[], None]] = field(default_factory=list)
    shown: bool = False

    def keep(self, key: str, value: Setting | None) -> None:
        """Remember that the user set ``key`` to ``value`` (a node, a rate, a filter): the
        panel's layout keeps it, so it survives a reload, a save and a clone. Names of a
        robot's nodes and topics are kept relative to its namespace (see
        :meth:`RobotId.relative`), so they suit every robot of a team panel."""
        self.settings[key] = value if value is not None else ""
        if self.remember is not None:
            self.remember(key, value)

    def text(self, key: str, default: str = "") -> str:
        """Setting ``key`` as text (``default`` when absent or not text)."""
        value = self.settings.get(key)
        return value if isinstance(value, str) and value else default

    def on_show(self, callback: Callable[[], None]) -> None:
        """Run ``callback`` whenever the view becomes visible (at once if it is)."""
        self._show.append(callback)
        if self.shown:
            callback()

    def on_hide(self, callback: Callable[[], None]) -> None:
        """Run ``callback`` whenever the view stops being visible."""
        self._hide.append(callback)

    def follow(self, model: Any, *timers: Any) -> None:
        """Activate ``model`` and its polling ``timers`` while the view is shown, and stop
        both when it is hidden: a hidden view costs the robot nothing."""

        def show() -> None:
            model.activate()
            for timer in timers:
                timer.activate()

        def hide() -> None:
            for timer in timers:
                timer.deactivate()
            model.deactivate()

        self.on_show(show)
        self.on_hide(hide)

    @property
    def can_write(self) -> bool:
        return self.policy.valid(self.token)

    def show(self) -> None:
        """Called by the shell."""
        if not self.shown:
            self.shown = True
            _run_all(self._show)

    def hide(self) -> None:
        """Called by the shell."""
        if self.shown:
            self.shown = False
            _run_all(self._hide)


def _run_all(callbacks: list[Callable[[], None]]) -> None:
    for cb in callbacks:
        try:
            cb()
        except Exception:
            _log.exception("view callback %r raised", cb)


@dataclass(frozen=True, slots=True)
class ViewKind:
    """A kind of view: its key in layouts, its title and its builder."""

    kind: str
    title: str
    build: Callable[[ViewContext], None]
    #: The kind shows several robots in one instance (the world view); it still works bound
    #: to one robot.
    team: bool = False
    #: Position in the "add view" menu.
    order: int = 100


_KINDS: dict[str, ViewKind] = {}


def register(
    *, kind: str, title: str, team: bool = False, order: int = 100
) -> Callable[[Callable[[ViewContext], None]], Callable[[ViewContext], None]]:
    """Register a view kind's builder (a decorator). Re-registering a kind replaces it."""
    if not kind.isidentifier():
        raise InvalidInput(f"a view kind is an identifier, not {kind!r}")

    def deco(build: Callable[[ViewContext], None]) -> Callable[[ViewContext], None]:
        _KINDS[kind] = ViewKind(kind=kind, title=title, build=build, team=team, order=order)
        return build

    return deco


def kinds() -> list[ViewKind]:
    return sorted(_KINDS.values(), key=lambda k: (k.order, k.title))


def get(kind: str) -> ViewKind:
    try:
        return _KINDS[kind]
    except KeyError:
        raise InvalidInput(
            f"no view kind {kind!r} (known: {', '.join(sorted(_KINDS)) or 'none'})"
        ) from None


def load_views() -> list[ViewKind]:
    """Import every module of ``debug_gui.ui`` so their kinds register themselves."""
    from .. import ui

    for info in pkgutil.iter_modules(ui.__path__):
        if info.name not in {"registry", "app"} and not info.name.startswith("_"):
            importlib.import_module(f"{ui.__name__}.{info.name}")
    return kinds()
