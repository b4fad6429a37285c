"""Every console script of the workspace answers ``--help`` with a usage and exit status 0,
before it starts anything (no node, no simulator, no servo bus).

The scripts are read from each package's ``setup.py`` and run from the install tree, as
``ros2 run PACKAGE SCRIPT --help`` runs them.
"""

from __future__ import annotations

import ast
import subprocess
from pathlib import Path

import pytest
from ament_index_python.packages import get_package_prefix

from efficient_comm.testing import isolated_domain_id, ros_env

SRC = Path(__file__).resolve().parents[1] / "ros2_ws" / "src"


def console_scripts() -> list[tuple[str, str]]:
    """(package, script) for every ``console_scripts`` entry of every ``setup.py``."""
    found = []
    for setup in sorted(SRC.glob("*/setup.py")):
        for node in ast.walk(ast.parse(setup.read_text())):
            if not (isinstance(node, ast.Dict)
                    and any(isinstance(k, ast.Constant) and k.value == "console_scripts"
                            for k in node.keys)):
                continue
            for key, value in zip(node.keys, node.values, strict=True):
                if isinstance(key, ast.Constant) and key.value == "console_scripts":
                    assert isinstance(value, ast.List)
                    for entry in value.elts:
                        assert isinstance(entry, ast.Constant)
                        found.append((setup.parent.name, str(entry.value).split("=")[0].strip()))
    return found


SCRIPTS = console_scripts()


def test_the_workspace_has_console_scripts() -> None:
    assert ("humanoid_sim", "simulator") in SCRIPTS and len(SCRIPTS) >= 10, SCRIPTS


@pytest.mark.parametrize(("package", "script"), SCRIPTS, ids=[s for _, s in SCRIPTS])
def test_help_prints_a_usage_and_starts_nothing(package: str, script: str) -> None:
    path = Path(get_package_prefix(package)) / "lib" / package / script
    result = subprocess.run([str(path), "--help"], env=ros_env(isolated_domain_id()),
                            capture_output=True, text=True, timeout=60)
    assert result.returncode == 0, result.stdout + result.stderr
    assert result.stdout.startswith("usage:"), result.stdout
    # Nothing started: no node logged, nothing opened.
    assert "[INFO]" not in result.stdout + result.stderr, result.stdout + result.stderr
    assert result.stderr == "", result.stderr
