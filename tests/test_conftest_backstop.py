"""The suite's backstop behind pytest-timeout (conftest.py's ``pytest_runtest_protocol``): a
test stuck where SIGALRM cannot reach it dumps its stacks and ends its process, instead of
idling until CI's hard limit (two full runs hung so on an xdist worker)."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
BACKSTOP_DIR = "EFFICIENT_COMM_TEST_BACKSTOP_DIR"  # conftest.py's

STUCK = '''
import signal
import time

import pytest


@pytest.mark.timeout(1)
def test_stuck_where_no_alarm_reaches() -> None:
    # As a thread waiting in native code: pytest-timeout's SIGALRM never gets handled.
    signal.pthread_sigmask(signal.SIG_BLOCK, [signal.SIGALRM])
    time.sleep(120)
'''


def test_a_test_that_outlives_its_timeout_unreachably_is_dumped_and_ended(
        tmp_path: Path) -> None:
    (tmp_path / "test_stuck.py").write_text(STUCK)
    # Not an xdist worker, as the outer run's may be (PYTEST_XDIST_WORKER).
    env = {key: value for key, value in os.environ.items()
           if not key.startswith("PYTEST_XDIST")}
    env["PYTHONPATH"] = f"{ROOT}{os.pathsep}{os.environ.get('PYTHONPATH', '')}"
    start = time.monotonic()
    run = subprocess.run(
        [sys.executable, "-m", "pytest", "-p", "conftest", "-p", "no:cacheprovider",
         "-p", "no:rerunfailures", "-n", "1", "-c", os.devnull, "--rootdir", str(tmp_path),
         str(tmp_path / "test_stuck.py")],
        cwd=tmp_path, env=env,
        capture_output=True, text=True, timeout=90, check=False)
    took = time.monotonic() - start
    # 2 x 1 s + 10 s of grace, then the dump; the test itself would sleep 120 s.
    assert took < 60, f"the stuck test ran {took:.0f} s: the backstop never fired"
    assert run.returncode != 0
    # xdist reports the crash and the summary shows where the test was stuck.
    assert "crashed while running" in run.stdout, run.stdout[-3000:]
    summary = run.stdout[run.stdout.index("stuck test (conftest.py's backstop)"):]
    assert "test_stuck.py::test_stuck_where_no_alarm_reaches still ran 12 s" in summary
    assert 'test_stuck.py", line 12 in test_stuck_where_no_alarm_reaches' in summary, summary
    if shutil.which("gdb"):
        # Where the main thread waits natively, which faulthandler's Python frames never say.
        native = summary[summary.index("native stacks (gdb):"):]
        assert "clock_nanosleep" in native, summary


def test_a_nested_run_leaves_the_outer_runs_live_files_alone(tmp_path: Path) -> None:
    """A test that starts pytest (test_test_kinds.py's --collect-only) inherits the outer
    run's folder, where every test in progress keeps its file: the nested run once printed
    them as stuck tests (failing that test in CI) and deleted them."""
    outer = tmp_path / "outer"
    outer.mkdir()
    live = outer / "4242.txt"
    live.write_text("tests/test_x.py::test_in_progress still ran 250 s after it began\n")
    (tmp_path / "test_quick.py").write_text("def test_quick() -> None:\n    assert True\n")
    env = {key: value for key, value in os.environ.items()
           if not key.startswith("PYTEST_XDIST")}
    env[BACKSTOP_DIR] = str(outer)
    env["PYTHONPATH"] = f"{ROOT}{os.pathsep}{os.environ.get('PYTHONPATH', '')}"
    run = subprocess.run(
        [sys.executable, "-m", "pytest", "-p", "conftest", "-p", "no:cacheprovider",
         "-c", os.devnull, "--rootdir", str(tmp_path), str(tmp_path / "test_quick.py")],
        cwd=tmp_path, env=env, capture_output=True, text=True, timeout=90, check=False)
    assert run.returncode == 0, run.stdout[-3000:]
    assert "1 passed" in run.stdout
    assert "test_in_progress" not in run.stdout
    assert live.exists()
