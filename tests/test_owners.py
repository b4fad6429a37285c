"""One owner per concept at the bottom layer (ARCHITECTURE.md, "Owners"), checked on the source.

A review found the same concept written by hand in several packages, each copy drifting
(``bus.py`` spelled types ``pkg/Name``). Each test here finds the hand-written form of one
concept anywhere outside its owner, so a new copy fails CI instead of waiting for a review.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

SRC = Path(__file__).resolve().parents[1] / "ros2_ws" / "src"
PACKAGES = sorted(p.parent.name for p in SRC.glob("*/setup.py"))


def _modules() -> list[tuple[Path, ast.Module]]:
    return [(path, ast.parse(path.read_text()))
            for package in PACKAGES for path in sorted((SRC / package / package).rglob("*.py"))]


def _where(path: Path, node: ast.AST) -> str:
    return f"{path.relative_to(SRC)}:{getattr(node, 'lineno', 0)}"


def _names_an_interface_module(text: ast.expr) -> bool:
    """``f"{package}.msg"``, ``f"{parts[0]}.{parts[1]}"`` from a split type name, or
    ``".".join(namespaces)`` of a rosidl type."""
    if isinstance(text, ast.Call) and isinstance(text.func, ast.Attribute):
        return text.func.attr == "join" and getattr(text.func.value, "value", None) == "."
    if (isinstance(text, ast.JoinedStr) and text.values and isinstance(text.values[0], ast.Constant)
            and str(text.values[0].value).startswith(".")):
        return False  # a relative import: a module of the package itself, never a rosidl one
    return isinstance(text, ast.JoinedStr) and any(
        (isinstance(v, ast.Constant) and re.search(r"\.(msg|srv|action)$", str(v.value)))
        or (isinstance(v, ast.FormattedValue) and isinstance(v.value, ast.Subscript))
        for v in text.values)


def test_type_names_are_spelled_by_efficient_comm_typenames_only() -> None:
    """class -> name reads ``__module__``; name -> class imports ``pkg.msg``/``pkg.srv``."""
    owner = SRC / "efficient_comm" / "efficient_comm" / "typenames.py"
    found = []
    for path, tree in _modules():
        if path == owner:
            continue
        for node in ast.walk(tree):
            if isinstance(node, ast.Attribute) and node.attr == "__module__":
                found.append(f"{_where(path, node)} reads __module__")
            elif (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)
                  and node.func.attr == "import_module" and node.args
                  and _names_an_interface_module(node.args[0])):
                found.append(f"{_where(path, node)} imports an interface module by name")
    assert not found, "use efficient_comm.type_name / import_type:\n" + "\n".join(found)


def _is_transient_local(node: ast.AST) -> bool:
    return isinstance(node, ast.Attribute) and node.attr == "TRANSIENT_LOCAL"


def test_latched_profiles_come_from_latched_qos() -> None:
    """A QoSProfile built with a literal TRANSIENT_LOCAL durability is a hand-made latched
    profile (KEEP_ALL readers, which keep everything, are another profile)."""
    owner = SRC / "efficient_comm" / "efficient_comm" / "_qos.py"
    found = []
    for path, tree in _modules():
        if path == owner:
            continue
        for node in ast.walk(tree):
            if (isinstance(node, ast.Call) and getattr(node.func, "id", None) == "QoSProfile"):
                kw = {k.arg: k.value for k in node.keywords}
                keep_all = getattr(kw.get("history"), "attr", "") == "KEEP_ALL"
                if _is_transient_local(kw.get("durability", ast.Constant(None))) and not keep_all:
                    found.append(_where(path, node))
    assert not found, "use efficient_comm.latched_qos():\n" + "\n".join(found)


#: ``x.sec * 1_000_000_000 + x.nanosec`` (and the sum the other way round) written by hand.
_STAMP_ARITHMETIC = re.compile(
    r"\.sec\)?\s*\*\s*(1_000_000_000|10\s*\*\*\s*9|1e9)|Time\(\s*sec\s*=[^,]*//|\.nanosec\)?\s*\+")


def test_stamp_nanoseconds_conversions_go_through_from_msg_and_to_msg() -> None:
    owner = SRC / "efficient_comm" / "efficient_comm" / "_clock.py"
    found = [
        f"{path.relative_to(SRC)}:{n}: {line.strip()}"
        for package in PACKAGES for path in sorted((SRC / package / package).rglob("*.py"))
        if path != owner
        for n, line in enumerate(path.read_text().splitlines(), 1)
        if _STAMP_ARITHMETIC.search(line)
    ]
    assert not found, "use efficient_comm.from_msg / to_msg:\n" + "\n".join(found)


#: The modules that use the field's dimensions; each must read them from soccer_field.
FIELD_READERS = ("humanoid_sim/humanoid_sim/soccer/referee.py",
                 "humanoid_sim/humanoid_sim/soccer/laws.py",
                 "humanoid_sim/humanoid_sim/soccer/game_control.py",
                 "humanoid_sim/humanoid_sim/soccer/striker.py",
                 "debug_gui/debug_gui/models/world.py")


def test_the_fields_dimensions_come_from_soccer_field() -> None:
    for reader in FIELD_READERS:
        tree = ast.parse((SRC / reader).read_text())
        imported = {node.module for node in ast.walk(tree) if isinstance(node, ast.ImportFrom)}
        assert "soccer_field" in imported, f"{reader} does not read the field from soccer_field"
    from debug_gui.models.world import FIELD
    from humanoid_sim.soccer import referee, striker
    from soccer_field import KIDSIZE

    assert (KIDSIZE.half_length, KIDSIZE.half_width) == (referee.HALF_LENGTH, referee.HALF_WIDTH)
    assert KIDSIZE.goal_width == referee.GOAL_HALF_WIDTH * 2
    assert KIDSIZE.goal_height == referee.CROSSBAR
    assert striker.PARAMETERS["goal"] == list(KIDSIZE.opponent_goal)
    assert (FIELD["length"], FIELD["width"], FIELD["goal_width"]) == (
        KIDSIZE.length, KIDSIZE.width, KIDSIZE.goal_width)
