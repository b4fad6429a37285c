"""Rules every package follows (ARCHITECTURE.md, "Errors" and "Seams"), checked on the source.

These are the seams a review found drifting: a root error under another package's root, a
private exception outside the tree, components asking which backend they run on, and
imports of another package's private modules or examples.
"""

from __future__ import annotations

import ast
import builtins
import importlib
import inspect
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "ros2_ws" / "src"
#: Python packages (ament_python): every one has its own errors.py.
PACKAGES = sorted(p.parent.name for p in SRC.glob("*/setup.py"))


def _sources(package: str) -> list[Path]:
    """The package's own modules (its tests are not its public behaviour)."""
    return sorted((SRC / package / package).rglob("*.py"))


def test_there_are_packages_to_check() -> None:
    assert {"efficient_comm", "throttle_publisher", "rf_bridge", "humanoid_sim",
            "robot_recorder", "team_clock"} <= set(PACKAGES)


@pytest.mark.parametrize("package", PACKAGES)
def test_one_exception_root_per_package_deriving_from_exception_only(package: str) -> None:
    errors = importlib.import_module(f"{package}.errors")
    defined = [
        cls for _, cls in inspect.getmembers(errors, inspect.isclass)
        if issubclass(cls, BaseException) and cls.__module__ == errors.__name__
    ]
    roots = [cls for cls in defined if not any(c in defined for c in cls.__mro__[1:])]
    assert len(roots) == 1, f"{package}.errors has roots {roots}"
    (root,) = roots
    assert root.__bases__ == (Exception,), (
        f"{root.__qualname__} must derive from Exception only, not {root.__bases__}"
    )
    doc = errors.__doc__ or ""
    missing = [cls.__name__ for cls in defined if cls.__name__ not in doc]
    assert not missing, f"{package}.errors' docstring tree lacks {missing}"


@pytest.mark.parametrize("package", PACKAGES)
def test_exceptions_outside_errors_py_derive_from_the_packages_tree(package: str) -> None:
    """A class that derives from a built-in exception belongs in errors.py, under the root."""
    builtin = {name for name, obj in vars(builtins).items()
               if inspect.isclass(obj) and issubclass(obj, BaseException)}
    strays = []
    for path in _sources(package):
        if path.name == "errors.py":
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ClassDef):
                bases = {b.id for b in node.bases if isinstance(b, ast.Name)}
                if bases & builtin:
                    strays.append(f"{path.relative_to(SRC)}:{node.lineno} {node.name}")
    assert not strays, f"exceptions outside {package}'s tree: {strays}"


#: What a component would use to find out which backend it runs on, instead of asking the
#: handle's capabilities (resolve_topic_name, graph, clock_kind, timer_schedule).
BACKEND_PEEKING = ("ComposedHandle", "rclpy_node", "is_manual")


@pytest.mark.parametrize("package", [p for p in PACKAGES if p != "efficient_comm"])
def test_packages_use_public_api_and_handle_capabilities_only(package: str) -> None:
    problems = []
    for path in _sources(package):
        tree = ast.parse(path.read_text())
        where = path.relative_to(SRC)
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                parts = node.module.split(".")
                if parts[0] in PACKAGES and parts[0] != package and (
                    any(p.startswith("_") or p == "examples" for p in parts[1:])
                    or any(a.name.startswith("_") for a in node.names)
                ):
                    problems.append(f"{where}:{node.lineno} imports from {node.module}")
            elif isinstance(node, ast.Import):
                for alias in node.names:
                    parts = alias.name.split(".")
                    if parts[0] in PACKAGES and parts[0] != package and any(
                        p.startswith("_") or p == "examples" for p in parts[1:]
                    ):
                        problems.append(f"{where}:{node.lineno} imports {alias.name}")
            elif isinstance(node, ast.Name) and node.id in BACKEND_PEEKING:
                problems.append(f"{where}:{node.lineno} uses {node.id}")
            elif isinstance(node, ast.Attribute) and node.attr in BACKEND_PEEKING:
                problems.append(f"{where}:{node.lineno} uses .{node.attr}")
            elif isinstance(node, ast.Constant) and node.value in BACKEND_PEEKING:
                problems.append(f"{where}:{node.lineno} asks for {node.value!r}")
    assert not problems, "\n".join(problems)
