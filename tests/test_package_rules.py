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
import sys
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

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


def test_architecture_names_every_root_and_every_layer() -> None:
    """ARCHITECTURE.md is what a newcomer reads first: it must not lag behind the code."""
    text = (SRC.parents[1] / "ARCHITECTURE.md").read_text()
    missing = []
    for package in PACKAGES:
        errors = importlib.import_module(f"{package}.errors")
        for _, cls in inspect.getmembers(errors, inspect.isclass):
            if (cls.__module__ == errors.__name__ and cls.__bases__ == (Exception,)
                    and f"`{cls.__name__}`" not in text):
                missing.append(cls.__name__)
        if f"| `{package}` |" not in text:
            missing.append(f"the layers' row of {package}")
    assert not missing, f"ARCHITECTURE.md does not name {missing}"


@pytest.mark.parametrize("package", PACKAGES)
def test_no_error_derives_from_another_packages_errors(package: str) -> None:
    """Each package's tree stands alone, leaves included: an error that crosses a boundary
    is wrapped (``raise Own(...) from theirs``), never inherited (robot_recorder's errors
    once derived from rosbag2_layout's, so ``except Rosbag2Error`` caught the recorder's)."""
    errors = importlib.import_module(f"{package}.errors")
    foreign = [
        f"{cls.__name__} <- {base.__module__}.{base.__qualname__}"
        for _, cls in inspect.getmembers(errors, inspect.isclass)
        if issubclass(cls, BaseException) and cls.__module__ == errors.__name__
        for base in cls.__mro__
        if base.__module__.split(".")[0] not in (package, "builtins")
    ]
    assert not foreign, f"{package}.errors derives from other packages' errors: {foreign}"


def _wrapped_cases() -> list[tuple[str, str, str, str]]:
    """(what, call, the caller's error, the cause's root): calls across a boundary."""
    return [
        ("robot_recorder reads a missing bag through rosbag2_layout",
         "robot_recorder:read_messages", "robot_recorder.errors:PlaybackError",
         "rosbag2_layout.errors:Rosbag2Error"),
        ("rosbag2_layout names a type through efficient_comm",
         "rosbag2_layout:import_type", "rosbag2_layout.errors:UnknownTypeError",
         "efficient_comm.errors:EfficientCommError"),
        ("rf_bridge names a ROS 2 type through efficient_comm",
         "rf_bridge.translate:ros2_class", "rf_bridge.errors:UnknownTypeError",
         "efficient_comm.errors:EfficientCommError"),
        ("ros2_pip_cli names a type through efficient_comm",
         "ros2_pip_cli._messages:import_interface", "ros2_pip_cli.errors:CliError",
         "efficient_comm.errors:EfficientCommError"),
        ("debug_gui's topic view names a type through efficient_comm",
         "debug_gui.models.topics:message_class", "debug_gui.errors:InvalidInput",
         "efficient_comm.errors:EfficientCommError"),
    ]


def _load(ref: str) -> Any:
    module, _, name = ref.partition(":")
    return getattr(importlib.import_module(module), name)


@pytest.mark.parametrize(("what", "call", "own", "cause"), _wrapped_cases(),
                         ids=[c[0] for c in _wrapped_cases()])
def test_errors_crossing_a_boundary_are_wrapped_with_the_cause_kept(
        what: str, call: str, own: str, cause: str, tmp_path: Path) -> None:
    argument = (str(tmp_path / "missing_bag") if call.startswith("robot_recorder")
                else "no_such_pkg/msg/Thing")
    with pytest.raises(_load(own)) as info:
        result = _load(call)(argument)
        list(result) if hasattr(result, "__iter__") else None  # generators raise when read
    assert not isinstance(info.value, _load(cause)), f"{what}: inherited, not wrapped"
    assert isinstance(info.value.__cause__, _load(cause)), f"{what}: cause lost"


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


# -- The layering: which package may import which ----------------------------------------

#: Every arrow allowed between the project's own packages (Python and interface packages).
#: A package imports only what its row names; ARCHITECTURE.md, "Layers", draws the same
#: table and says why. Adding an arrow is a design decision: change it here and there.
LAYERS: dict[str, frozenset[str]] = {
    "efficient_comm": frozenset({"efficient_comm_interfaces"}),
    "soccer_field": frozenset(),
    "throttle_publisher": frozenset({"efficient_comm", "efficient_comm_interfaces"}),
    "rosbag2_layout": frozenset({"efficient_comm"}),
    "team_clock": frozenset({"efficient_comm", "rosbag2_layout", "team_clock_interfaces"}),
    "robot_recorder": frozenset({"efficient_comm", "throttle_publisher", "rosbag2_layout",
                                 "team_clock", "robot_recorder_interfaces"}),
    "rf_bridge": frozenset({"efficient_comm", "throttle_publisher"}),
    "debug_probes": frozenset({"efficient_comm", "efficient_comm_interfaces",
                               "throttle_publisher"}),
    "humanoid_sim": frozenset({"efficient_comm", "throttle_publisher", "debug_probes",
                               "robot_recorder", "team_clock", "team_clock_interfaces",
                               "log_analysis",
                               "soccer_field", "soccer_interfaces"}),
    "ros2_pip_cli": frozenset({"efficient_comm", "efficient_comm_interfaces",
                               "robot_recorder"}),
    "log_analysis": frozenset({"efficient_comm", "rosbag2_layout", "team_clock",
                               "team_clock_interfaces"}),
    "debug_gui": frozenset({"efficient_comm", "efficient_comm_interfaces",
                            "throttle_publisher", "debug_probes", "rosbag2_layout",
                            "log_analysis",
                            "robot_recorder", "robot_recorder_interfaces", "soccer_field",
                            "soccer_interfaces"}),
}
#: Every package of the workspace, interface packages included (their package.xml).
OURS = frozenset(p.parent.name for p in SRC.glob("*/package.xml"))

#: Python modules whose rosdep key is not their import name.
ROSDEP_KEYS = {"yaml": "python3-yaml", "numpy": "python3-numpy", "cv2": "python3-opencv",
               "serial": "python3-serial", "av": "python3-av",
               "matplotlib": "python3-matplotlib"}
#: Python modules from PyPI with no rosdep key (tools/requirements.txt installs them); a
#: package.xml cannot name them, so they are the only imports it may leave out.
PIP_ONLY = frozenset({"mujoco", "nicegui", "fastapi", "foxglove", "websockets", "zenoh",
                      "mcap", "mcap_ros2", "rosbags", "zstandard", "iceoryx2"})


def _imports(package: str) -> dict[str, list[str]]:
    """Top-level module -> where the package's own modules import it (not stdlib)."""
    found: dict[str, list[str]] = {}
    for path in _sources(package):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                names = [node.module]
            elif isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            else:
                continue
            for name in names:
                top = name.split(".")[0]
                if top != package and top not in sys.stdlib_module_names:
                    found.setdefault(top, []).append(f"{path.relative_to(SRC)}:{node.lineno}")
    return found


def _declared(package: str) -> set[str]:
    root = ET.parse(SRC / package / "package.xml").getroot()
    return {e.text.strip() for e in root if e.tag in ("depend", "exec_depend") and e.text}


def test_every_package_has_a_row_and_the_layers_have_no_cycle() -> None:
    assert set(LAYERS) == set(PACKAGES)
    assert all(deps <= OURS for deps in LAYERS.values())
    done: set[str] = set()
    while len(done) < len(LAYERS):
        ready = {p for p, deps in LAYERS.items()
                 if p not in done and deps & set(LAYERS) <= done}
        assert ready, f"the layers have a cycle among {set(LAYERS) - done}"
        done |= ready


@pytest.mark.parametrize("package", PACKAGES)
def test_packages_import_only_what_the_layers_allow(package: str) -> None:
    wrong = {dep: where for dep, where in _imports(package).items()
             if dep in OURS and dep not in LAYERS[package]}
    assert not wrong, f"{package} may not import {sorted(wrong)}: {wrong}"


@pytest.mark.parametrize("package", PACKAGES)
def test_package_xml_declares_what_the_package_imports(package: str) -> None:
    declared = _declared(package)
    imported = _imports(package)
    missing = {ROSDEP_KEYS.get(dep, dep): where[0] for dep, where in imported.items()
               if dep not in PIP_ONLY and ROSDEP_KEYS.get(dep, dep) not in declared}
    assert not missing, f"{package}/package.xml lacks exec_depend {missing}"
    extra = {dep for dep in declared & OURS if dep not in imported}
    assert not extra, f"{package}/package.xml declares {sorted(extra)}, which it never imports"
