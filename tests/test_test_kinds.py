"""Every test has a kind (tier) from its file name: tests/_kinds.py's table, conftest's hook.

A new test file that no row covers would fall out of every tier (``-m fast`` and the slow
kinds alike), so the table must cover every test file of the repository; and the hook must
really mark what the table says, which ``pytest --collect-only -m KIND`` shows.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from ._kinds import KINDS, SLOW_KINDS, kinds_of, serial_group

ROOT = Path(__file__).resolve().parents[1]


def _test_files() -> list[str]:
    files = [*ROOT.glob("tests/test_*.py"), *ROOT.glob("ros2_ws/src/*/test/test_*.py")]
    return sorted(p.relative_to(ROOT).as_posix() for p in files)


def test_every_test_file_has_a_kind() -> None:
    files = _test_files()
    assert len(files) > 50
    without = [f for f in files if not kinds_of(f, "test_x")]
    assert without == []
    for f in files:
        assert kinds_of(f, "test_x") <= set(KINDS), f


@pytest.mark.parametrize(("path", "name", "fixtures", "expected"), [
    ("ros2_ws/src/efficient_comm/test/test_bus.py", "test_a", (), {"fast"}),
    ("ros2_ws/src/humanoid_sim/test/test_render.py", "test_a", (), {"process"}),
    ("tests/test_kick_sil.py", "test_a", (), {"sil"}),
    # The demo's argument checks start no simulation; the tests of that file that play do.
    ("tests/test_demo_args.py", "test_a_bad_argument_is_one_line_and_exit_status_2[args0-x]",
     (), {"process"}),
    ("tests/test_demo_args.py", "test_the_seed_draws_the_start", (), {"process", "sil"}),
    ("tests/test_demo.py", "test_a", (), {"sil"}),
    ("tests/test_demo_watchable.py", "test_a_bad_namespace_is_refused_in_one_line", (),
     {"process"}),
    ("tests/test_match_localization_sil.py", "test_a_localization_for_a_robot_not_in_x", (),
     {"process"}),
    ("tests/test_match_localization_sil.py", "test_each_robot_runs_the_localization_x", (),
     {"process", "sil"}),
    ("tests/test_gui_shell_browser.py", "test_a", ("browser",), {"browser"}),
    # A browser test in a data-side file is a browser test all the same.
    ("tests/test_gui_world_views.py", "test_b", ("tmp_path", "browser"), {"process", "browser"}),
    ("tests/test_gui_world_views.py", "test_a", ("tmp_path",), {"process"}),
    ("tests/test_walk_bench_smoke.py", "test_a", (), {"bench"}),
    ("tests/test_docs_commands.py", "test_a[README.md:12]", (), {"docs"}),
    ("tests/test_throttle_bench_smoke.py", "test_a", (), {"bench", "root"}),
    ("tests/test_cli_bench_smoke.py", "test_a", (), {"bench", "process"}),
    ("tests/test_recorder_robustness.py", "test_real_small_file_system[0]", (),
     {"process", "root"}),
    ("tests/test_recorder_robustness.py", "test_snapshot_when_off_is_an_error", (),
     {"process"}),
    # A new top-level file nobody listed: a process test until a row says otherwise.
    ("tests/test_something_new.py", "test_a", (), {"process"}),
    ("tests/test_something_new_sil.py", "test_a", (), {"sil"}),
    ("ros2_ws/src/new_package/test/test_new.py", "test_a", (), {"fast"}),
    ("bench/not_a_test.py", "test_a", (), set()),
])
def test_kinds_follow_file_names(
    path: str, name: str, fixtures: tuple[str, ...], expected: set[str]
) -> None:
    assert kinds_of(path, name, fixtures=fixtures) == expected


def test_fast_excludes_every_slow_kind() -> None:
    for f in _test_files():
        kinds = kinds_of(f, "test_x")
        assert ("fast" in kinds) != bool(kinds & set(SLOW_KINDS)), (f, kinds)


def _collected(marker: str, *paths: str) -> list[str]:
    out = subprocess.run(
        [sys.executable, "-m", "pytest", "--collect-only", "-q", "-m", marker, *paths],
        cwd=ROOT, capture_output=True, text=True, timeout=120,
    )
    assert out.returncode in (0, 5), out.stdout + out.stderr
    return [line for line in out.stdout.splitlines() if "::" in line]


def test_the_hook_marks_collected_tests() -> None:
    files = ("tests/test_test_kinds.py", "tests/test_gui_world_views.py")
    fast = _collected("fast", *files)
    assert fast and all(n.startswith("tests/test_test_kinds.py::") for n in fast)
    browser = _collected("browser", *files)
    assert browser and all(n.startswith("tests/test_gui_world_views.py::") for n in browser)
    process = _collected("process", *files)
    assert set(process) > set(browser)


def test_busy_kinds_take_turns_in_one_worker() -> None:
    """Simulations and benchmarks share one xdist group, docs commands another; a waiting
    test has none (it runs beside anything)."""
    group = {f: serial_group(kinds_of(f, "test_a")) for f in (
        "tests/test_kick_sil.py", "tests/test_demo_args.py", "tests/test_walk_bench_smoke.py",
        "tests/test_throttle_bench_smoke.py", "tests/test_docs_commands.py",
        "tests/test_gui_world_views.py", "ros2_ws/src/efficient_comm/test/test_bus.py")}
    assert group == {
        "tests/test_kick_sil.py": "cpu", "tests/test_demo_args.py": None,
        "tests/test_walk_bench_smoke.py": "cpu", "tests/test_throttle_bench_smoke.py": "cpu",
        "tests/test_docs_commands.py": "docs", "tests/test_gui_world_views.py": None,
        "ros2_ws/src/efficient_comm/test/test_bus.py": None}
    # A benchmark that mostly waits (a row makes it a process test too) waits beside the
    # others; a simulation that starts programs still takes its turn.
    assert serial_group(kinds_of("tests/test_cli_bench_smoke.py", "test_a")) is None
    assert serial_group(kinds_of("tests/test_bridge_bench_smoke.py", "test_a")) is None
    assert serial_group({"bench", "process"}) is None
    assert serial_group({"sil", "process"}) == "cpu"
    assert serial_group({"bench", "root"}) == "cpu"
    # The demo's argument checks wait beside anything; its runs take their turn.
    demo_args = "tests/test_demo_args.py"
    assert serial_group(kinds_of(demo_args, "test_the_demo_films_the_match_and_x")) == "cpu"
    assert serial_group(kinds_of(demo_args, "test_negative_coordinates_as_x")) == "cpu"
