"""Layouts: which view kinds are shown, bound to which robot, saved as JSON.

A layout is a list of panels. A panel shows one view kind either for one robot, or, as a
team panel, for every robot side by side (robots that appear later join it live). Cloning
a view for another robot adds a panel of the same kind bound to that robot.

File format (version 1)::

    {"version": 1, "panels": [
        {"kind": "components", "robot": {"domain": 5, "namespace": "/robot2", "via": "dds"}},
        {"kind": "image", "team": true}
    ]}

Everything read is validated (a layout file may come from anyone): unknown keys, wrong
types and malformed robots raise InvalidInput naming the entry.
"""

from __future__ import annotations

import contextlib
import json
import os
import tempfile
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from .errors import InvalidInput
from .robots import RobotId

VERSION = 1
#: More panels than anyone can look at; a guard against a hostile or broken file.
MAX_PANELS = 64
MAX_FILE_BYTES = 1_000_000


@dataclass(frozen=True, slots=True)
class Panel:
    """One view kind bound to one robot, or (``robot`` None) to the whole team."""

    kind: str
    robot: RobotId | None = None

    @property
    def team(self) -> bool:
        return self.robot is None

    def to_dict(self) -> dict[str, Any]:
        if self.robot is None:
            return {"kind": self.kind, "team": True}
        return {"kind": self.kind, "robot": self.robot.to_dict()}

    @classmethod
    def from_dict(cls, data: object, *, where: str = "panel") -> Panel:
        if not isinstance(data, dict):
            raise InvalidInput(f"{where}: a panel is an object, not {data!r}")
        unknown = set(data) - {"kind", "robot", "team"}
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
        if team:
            return cls(kind=kind)
        try:
            return cls(kind=kind, robot=RobotId.from_dict(data["robot"]))
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
        if len(self.panels) >= MAX_PANELS:
            raise InvalidInput(f"at most {MAX_PANELS} panels")
        return Layout((*self.panels, panel))

    def without(self, index: int) -> Layout:
        return Layout(tuple(p for i, p in enumerate(self.panels) if i != index))

    def replacing(self, index: int, panel: Panel) -> Layout:
        return Layout(tuple(panel if i == index else p for i, p in enumerate(self.panels)))
