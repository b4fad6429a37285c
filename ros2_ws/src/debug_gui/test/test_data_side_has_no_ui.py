"""The data side (Hub, models, layouts, security) imports no UI toolkit: it is tested, and
served to Foxglove, without one."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "debug_gui"
#: Where NiceGUI may be imported (server.py only inside serve()).
UI_MODULES = {"ui", "server.py"}


def test_no_module_outside_ui_imports_nicegui() -> None:
    offenders = []
    for path in PACKAGE.rglob("*.py"):
        relative = path.relative_to(PACKAGE)
        if relative.parts[0] in UI_MODULES:
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            names = (
                [a.name for a in node.names] if isinstance(node, ast.Import)
                else [node.module or ""] if isinstance(node, ast.ImportFrom) else []
            )
            if any(n.split(".")[0] == "nicegui" for n in names):
                offenders.append(str(relative))
    assert not offenders


def test_importing_the_data_side_loads_no_nicegui() -> None:
    code = (
        "import sys, debug_gui, debug_gui.hub, debug_gui.layout, debug_gui.security, "
        "debug_gui.models.components, debug_gui.demo, debug_gui.server; "
        "assert 'nicegui' not in sys.modules, 'nicegui imported'"
    )
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                            timeout=60)
    assert result.returncode == 0, result.stderr
