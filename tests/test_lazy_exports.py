"""Packages whose public names load on first use (efficient_comm, debug_gui, log_analysis):
the table each loads them by and the imports type checkers read name the same objects, and
a command that needs little imports little: type names without the container, a bad option
of the GUI's commands without the data side, one log_analysis command without the others'
modules."""

from __future__ import annotations

import ast
import importlib
import subprocess
import sys
from pathlib import Path
from types import ModuleType

import pytest

import debug_gui
import efficient_comm
import log_analysis

PACKAGES = [efficient_comm, debug_gui, log_analysis]


def _static_imports(package: ModuleType) -> dict[str, str]:
    """name -> module of the ``from .module import name as name`` lines type checkers read."""
    found = {}
    assert package.__file__ is not None
    branches = [n.orelse for n in ast.parse(Path(package.__file__).read_text()).body
                if isinstance(n, ast.If)]  # ``if not TYPE_CHECKING: ... else: <imports>``
    for node in (n for branch in branches for n in branch):
        if isinstance(node, ast.ImportFrom) and node.level == 1 and node.module:
            for alias in node.names:
                assert alias.asname == alias.name, alias.name  # a re-export, not a rename
                found[alias.name] = f".{node.module}"
    return found


@pytest.mark.parametrize("package", PACKAGES, ids=lambda p: p.__name__)
def test_the_lazy_table_and_the_type_checkers_imports_agree(package: ModuleType) -> None:
    table = package._EXPORTS
    assert table and _static_imports(package) == table
    for name, module in table.items():
        defined = getattr(importlib.import_module(module, package.__name__), name)
        assert getattr(package, name) is defined, name
    assert set(package.__all__) <= set(dir(package))


@pytest.mark.parametrize("package", PACKAGES, ids=lambda p: p.__name__)
def test_an_unknown_name_is_an_attribute_error(package: ModuleType) -> None:
    with pytest.raises(AttributeError, match="NoSuchThing"):
        package.NoSuchThing  # noqa: B018


def _loaded(code: str, *watched: str) -> str:
    probe = f"import sys\n{code}\nprint(sorted(m for m in {watched!r} if m in sys.modules))"
    return subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True,
                          timeout=60, check=True).stdout.strip()


def test_type_names_alone_leave_the_container_unimported() -> None:
    code = "import efficient_comm\nefficient_comm.import_type('std_msgs/msg/String')"
    assert _loaded(code, "efficient_comm.container", "efficient_comm.shm", "numpy") == "[]"


def test_the_guis_commands_parse_before_the_data_side_is_imported() -> None:
    code = "import debug_gui.server, debug_gui.demo"
    assert _loaded(code, "nicegui", "debug_gui.hub", "debug_gui.playback", "log_analysis",
                   "mcap") == "[]"


def test_a_log_analysis_command_imports_only_what_it_runs() -> None:
    """Each of the four commands imported all four's modules (video decoding, component
    replays, rclpy): 0.6 s before it read an argument, on every call."""
    code = ("import contextlib, io\nfrom log_analysis.cli import compare_main\n"
            "with contextlib.suppress(SystemExit), contextlib.redirect_stdout(io.StringIO()):\n"
            "    compare_main(['--help'])")
    assert _loaded(code, "log_analysis.compare", "log_analysis.video", "log_analysis.sync",
                   "log_analysis.augment", "log_analysis.source", "rclpy", "av") == "[]"
    code = "from log_analysis.cli import sync_video_main"
    assert _loaded(code, "log_analysis.compare", "log_analysis.augment",
                   "efficient_comm.testing") == "[]"
