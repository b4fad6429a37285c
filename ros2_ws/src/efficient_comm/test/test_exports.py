"""efficient_comm's public names are loaded on first use: the table the package loads them
by and the imports type checkers read name the same objects, and a tool that needs only the
type names does not import the container."""

from __future__ import annotations

import ast
import importlib
import subprocess
import sys
from pathlib import Path

import efficient_comm

INIT = Path(efficient_comm.__file__)


def _static_imports() -> dict[str, str]:
    """name -> module of the ``from .module import name as name`` lines type checkers read."""
    found = {}
    for node in ast.walk(ast.parse(INIT.read_text())):
        if isinstance(node, ast.ImportFrom) and node.level == 1 and node.module:
            for alias in node.names:
                assert alias.asname == alias.name, alias.name  # a re-export, not a rename
                found[alias.name] = f".{node.module}"
    return found


def test_the_lazy_table_and_the_type_checkers_imports_agree() -> None:
    assert _static_imports() == efficient_comm._EXPORTS
    for name, module in efficient_comm._EXPORTS.items():
        defined = getattr(importlib.import_module(module, "efficient_comm"), name)
        assert getattr(efficient_comm, name) is defined, name
    assert set(efficient_comm.__all__) <= set(dir(efficient_comm))


def test_an_unknown_name_is_an_attribute_error() -> None:
    try:
        efficient_comm.NoSuchThing  # type: ignore[attr-defined]  # noqa: B018
    except AttributeError as exc:
        assert "NoSuchThing" in str(exc)
    else:
        raise AssertionError("efficient_comm.NoSuchThing did not raise")


def test_type_names_alone_leave_the_container_unimported() -> None:
    probe = ("import sys\nimport efficient_comm\n"
             "efficient_comm.import_type('std_msgs/msg/String')\n"
             "print(sorted(m for m in ('efficient_comm.container', 'efficient_comm.shm', "
             "'numpy') if m in sys.modules))")
    loaded = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True,
                            timeout=60, check=True).stdout.strip()
    assert loaded == "[]"
