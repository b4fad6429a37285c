"""Layouts: which view kinds are shown, bound to which robot, saved as JSON.

A layout is a list of panels. A panel shows one view kind either for one robot, or, as a
team panel, for every robot side by side (robots that appear later join it live). Cloning
a view for another robot adds a panel of the same kind bound to that robot.

File format (version 1)::

    {"version": 1, "panels": [
        {"kind": "components", "robot": {"domain": 5, "namespace": "/robot2", "via": "dds"}},
        {"kind": "image", "team": true, "settings": {"rate_hz": 5}}
    ]}

A panel's optional ``settings`` are what its view was set to (the parameters view's node
and filter, the image view's rate, the topics view's echoed topic and plotted field, the
log view's filters): flat, scalar values a view reads back when it is built, names relative
to the robot so they suit every robot of a team panel and a clone.

Everything read is validated (a layout file may come from anyone): unknown keys, wrong
types and malformed robots raise InvalidInput naming the entry.

Saving never replaces a saved layout the tab did not see: :meth:`Layout.save_over` takes
the file's text as the tab last read or wrote it and raises LayoutConflict when the file
now holds something else (another tab saved meanwhile).
"""

from __future__ import annotations

import contextlib
import json
import os
import tempfile
from collections.abc import Iterable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from .errors import InvalidInput, LayoutConflict
from .robots import RobotId

VERSION = 1
#: More panels than anyone can look at; a guard against a hostile or broken file.
MAX_PANELS = 64
MAX_FILE_BYTES = 1_000_000
#: A view has a handful of settings; these bound what a file may hold.
MAX_SETTINGS = 16
MAX_SETTING_CHARS = 512

#: One setting's value: what a view's widgets hold.
Setting = str | int | float | bool


def _check_setting(key: object, value: object, *, where: str) -> tuple[str, Setting]:
    if not isinstance(key, str) or not key.isidentifier() or len(key) > 64:
        raise InvalidInput(f"{where}: a setting's name is an identifier, not {key!r}")
    if isinstance(value, str):
        if len(value) > MAX_SETTING_CHARS:
            raise InvalidInput(f"{where}: setting {key} is at most {MAX_SETTING_CHARS} "
                               "characters")
    elif isinstance(value, float):
        if value != value or value in (float("inf"), float("-inf")):
            raise InvalidInput(f"{where}: setting {key} must be a finite number")
    elif not isinstance(value, int):  # bool is an int
        raise InvalidInput(f"{where}: setting {key} is text, a number or true/false, "
                           f"not {value!r}")
    return key, value


@dataclass(frozen=True, slots=True)
class Panel:
    """One view kind bound to one robot, or (``robot`` None) to the whole team, with what
    its view was set to (``settings``, sorted by name)."""

    kind: str
    robot: RobotId | None = None
    settings: tuple[tuple[str, Setting], ...] = ()

    @property
    def team(self) -> bool:
        return self.robot is None

    def setting(self, key: str) -> Setting | None:
        return dict(self.settings).get(key)

    def with_setting(self, key: str, value: Setting | None) -> Panel:
        """This panel with ``key`` set to ``value`` (None: removed); checked as a file's."""
        settings = dict(self.settings)
        if value is None or value == "":
            settings.pop(key, None)
        else:
            settings[key] = _check_setting(key, value, where="setting")[1]
        if len(settings) > MAX_SETTINGS:
            raise InvalidInput(f"a panel has at most {MAX_SETTINGS} settings")
        return replace(self, settings=tuple(sorted(settings.items())))

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = ({"kind": self.kind, "team": True} if self.robot is None
                               else {"kind": self.kind, "robot": self.robot.to_dict()})
        if self.settings:
            out["settings"] = dict(self.settings)
        return out

    @classmethod
    def from_dict(cls, data: object, *, where: str = "panel") -> Panel:
        if not isinstance(data, dict):
            raise InvalidInput(f"{where}: a panel is an object, not {data!r}")
        unknown = set(data) - {"kind", "robot", "team", "settings"}
        if unknown:
            raise InvalidInput(f"{where}: unknown keys {sorted(unknown)}")
        kind = data.get("kind")
        if not isinstance(kind, str) or not kind.isidentifier():
            raise InvalidInput(f"{where}: kind must be a view kind's name, not {kind!r}")
        team = data.get("team", False)
        if not isinstance(team, bool):
            raise InvalidInput(f"{where}: team must be true or false, not {team!r}")
        if team == ("robot" in data):
            raise InvalidInput(f"{where}: give either a robot or team: true")
        raw = data.get("settings", {})
        if not isinstance(raw, dict) or len(raw) > MAX_SETTINGS:
            raise InvalidInput(f"{where}: settings are an object of at most {MAX_SETTINGS}")
        settings = tuple(sorted(_check_setting(k, v, where=where) for k, v in raw.items()))
        if team:
            return cls(kind=kind, settings=settings)
        try:
            return cls(kind=kind, robot=RobotId.from_dict(data["robot"]), settings=settings)
        except InvalidInput as exc:
            raise InvalidInput(f"{where}: {exc}") from None


def check_layout_path(path: Path) -> Path:
    """``path`` if a layout can be written there, else InvalidInput saying why.

    Checked when the server starts, so a typo in ``--layout`` is found at once rather than
    at the first "save layout".
    """
    path = Path(path)
    parent = path.parent
    if path.is_dir():
        raise InvalidInput(f"--layout {path} is a directory, not a file")
    if not parent.is_dir():
        raise InvalidInput(f"--layout {path}: directory {parent} does not exist")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise InvalidInput(f"--layout {path}: directory {parent} is not writable")
    if path.exists() and not os.access(path, os.W_OK):
        raise InvalidInput(f"--layout {path} is not writable")
    return path


@dataclass(frozen=True, slots=True)
class Layout:
    panels: tuple[Panel, ...] = ()

    def to_json(self) -> str:
        return json.dumps(
            {"version": VERSION, "panels": [p.to_dict() for p in self.panels]}, indent=2
        )

    @classmethod
    def from_json(cls, text: str, *, known_kinds: Iterable[str] | None = None) -> Layout:
        """Parse and validate; ``known_kinds`` rejects kinds this server does not have."""
        if len(text) > MAX_FILE_BYTES:
            raise InvalidInput(f"a layout is at most {MAX_FILE_BYTES} bytes")
        try:
            data = json.loads(text)
        except json.JSONDecodeError as exc:
            raise InvalidInput(f"layout is not JSON: {exc}") from None
        if not isinstance(data, dict) or set(data) != {"version", "panels"}:
            raise InvalidInput('a layout is {"version": 1, "panels": [...]}')
        if data["version"] != VERSION:
            raise InvalidInput(f"layout version {data['version']!r}; this reads {VERSION}")
        panels = data["panels"]
        if not isinstance(panels, list) or len(panels) > MAX_PANELS:
            raise InvalidInput(f"panels must be a list of at most {MAX_PANELS}")
        out = tuple(Panel.from_dict(p, where=f"panel {i + 1}") for i, p in enumerate(panels))
        if known_kinds is not None:
            known = set(known_kinds)
            for i, p in enumerate(out):
                if p.kind not in known:
                    raise InvalidInput(
                        f"panel {i + 1}: no view kind {p.kind!r} here "
                        f"(known: {', '.join(sorted(known))})"
                    )
        return cls(out)

    @classmethod
    def load(cls, path: Path, *, known_kinds: Iterable[str] | None = None) -> Layout:
        try:
            text = path.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as exc:
            raise InvalidInput(f"cannot read layout {path}: {exc}") from None
        try:
            return cls.from_json(text, known_kinds=known_kinds)
        except InvalidInput as exc:
            raise InvalidInput(f"{path}: {exc}") from None

    def save_over(self, path: Path, *, seen: str | None) -> str:
        """Save unless the file changed since it was ``seen`` (its text then; None: there
        was no file); the text written, to pass as ``seen`` next time.

        Raises LayoutConflict, leaving the file alone, when the file holds a layout other
        than the one seen and other than this one: someone else saved meanwhile.
        """
        text = self.to_json() + "\n"
        now = saved_text(path)
        if now != seen and now != text:
            raise LayoutConflict(
                f"not saved: {path} holds a layout saved elsewhere since this tab loaded "
                "it; restore it to see it, or save again to replace it")
        self.save(path)
        return text

    def save(self, path: Path) -> None:
        """Write atomically: a crash mid-save leaves the old layout, not half a file."""
        path = check_layout_path(Path(path))
        tmp: str | None = None
        try:
            fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.")
            with os.fdopen(fd, "w", encoding="utf-8") as out:
                out.write(self.to_json() + "\n")
            os.replace(tmp, path)
        except OSError as exc:
            if tmp is not None:
                with contextlib.suppress(OSError):
                    os.unlink(tmp)
            # The message names the layout, not the temporary file the error was about.
            raise InvalidInput(
                f"cannot write layout {path}: {exc.strerror or exc}"
            ) from None

    def adding(self, panel: Panel) -> Layout:
        return self.inserting(len(self.panels), panel)

    def inserting(self, index: int, panel: Panel) -> Layout:
        """This layout with ``panel`` at ``index``, the later panels one down (a clone goes
        right after its original, where the eye compares them)."""
        if len(self.panels) >= MAX_PANELS:
            raise InvalidInput(f"at most {MAX_PANELS} panels")
        return Layout((*self.panels[:index], panel, *self.panels[index:]))

    def without(self, index: int) -> Layout:
        return Layout(tuple(p for i, p in enumerate(self.panels) if i != index))

    def replacing(self, index: int, panel: Panel) -> Layout:
        """This layout with panel ``index`` replaced (an index out of range changes
        nothing)."""
        return Layout(tuple(panel if i == index else p for i, p in enumerate(self.panels)))


def saved_text(path: Path) -> str | None:
    """The layout file's text now (None: no file, or none readable), for
    :meth:`Layout.save_over`."""
    try:
        return Path(path).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError):
        return None
