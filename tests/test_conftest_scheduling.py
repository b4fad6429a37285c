"""conftest.py's xdist scheduler (``KindScheduling``) after a worker crashed, as one does when
the backstop (test_conftest_backstop.py) ends a stuck test: the run goes on with the tests
that were left, runs the crashed test once more when ``--reruns`` allows, and ends.

A full run once stalled after such a crash: every worker idle, the controller waiting
forever. xdist's LoadScopeScheduling put the crashed worker's whole workload back in the
queue, finished scopes included; a worker with nothing left to run that was handed one of
those was sent an empty list of tests, so it never reported again and was never given the
scopes still queued behind it.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

#: Instant tests, each a scope of its own (tests/_kinds.py: a process test, no serial group).
QUICK = "".join(f"def test_quick_{n:02}() -> None:\n    assert True\n\n\n" for n in range(12))

#: A test that crashes its worker on its first run only (the flag file says it ran), as a
#: stuck test the backstop ends would.
CRASH_ONCE = '''
import os
from pathlib import Path


def {name}() -> None:
    flag = Path(__file__).with_name("{name}.crashed")
    if not flag.exists():
        flag.touch()
        os._exit(3)
'''

#: tests/_kinds.py puts ``tests/test_*_sil.py`` in the serial "cpu" group.
SERIAL = '''
def test_serial_a() -> None:
    assert True
'''


def _run(folder: Path, *, reruns: int = 1) -> subprocess.CompletedProcess[str]:
    """``pytest -n 2 --dist loadgroup --reruns 1`` (scripts/test.sh's) on ``folder``'s tests,
    with this repository's conftest.py; a stalled run is ended after 60 s."""
    env = {key: value for key, value in os.environ.items()
           if not key.startswith("PYTEST_XDIST")}
    env["PYTHONPATH"] = f"{ROOT}{os.pathsep}{os.environ.get('PYTHONPATH', '')}"
    try:
        return subprocess.run(
            [sys.executable, "-m", "pytest", "-p", "conftest", "-p", "no:cacheprovider",
             "-n", "2", "--dist", "loadgroup", "--reruns", str(reruns), "-rR", "-v",
             "-c", os.devnull, "--rootdir", str(folder), "tests"],
            cwd=folder, env=env, capture_output=True, text=True, timeout=60, check=False)
    except subprocess.TimeoutExpired as stalled:
        out = stalled.stdout.decode(errors="replace") if isinstance(
            stalled.stdout, bytes) else str(stalled.stdout)
        raise AssertionError(f"the run stalled after the crash:\n{out[-3000:]}") from None


def _tests(folder: Path, files: dict[str, str]) -> Path:
    tests = folder / "tests"
    tests.mkdir()
    for name, text in files.items():
        (tests / name).write_text(text)
    return folder


def test_a_crash_after_finished_scopes_leaves_no_worker_idle_and_reruns_the_test(
        tmp_path: Path) -> None:
    # The crashing test comes last, so the worker running it has finished several scopes.
    folder = _tests(tmp_path, {
        "test_a_quick.py": QUICK,
        "test_b_serial_sil.py": SERIAL,
        "test_z_crash.py": CRASH_ONCE.format(name="test_crashes_once"),
    })
    run = _run(folder)
    assert "RERUN tests/test_z_crash.py::test_crashes_once" in run.stdout, run.stdout[-3000:]
    assert run.returncode == 0, run.stdout[-3000:]
    assert "14 passed, 1 rerun" in run.stdout, run.stdout[-3000:]


SERIAL_WITH_CRASH = SERIAL + CRASH_ONCE.format(name="test_serial_b_crashes_once") + (
    "\n\ndef test_serial_c() -> None:\n    assert True\n")


def test_a_crash_in_a_serial_group_reruns_the_test_and_runs_the_rest_of_the_group(
        tmp_path: Path) -> None:
    folder = _tests(tmp_path, {"test_a_quick.py": QUICK, "test_serial_sil.py": SERIAL_WITH_CRASH})
    run = _run(folder)
    assert "RERUN tests/test_serial_sil.py::test_serial_b_crashes_once" in run.stdout, (
        run.stdout[-3000:])
    assert run.returncode == 0, run.stdout[-3000:]
    assert "15 passed, 1 rerun" in run.stdout, run.stdout[-3000:]


def test_a_crashed_test_without_reruns_left_fails_and_is_not_run_again(tmp_path: Path) -> None:
    folder = _tests(tmp_path, {"test_a_quick.py": QUICK, "test_serial_sil.py": SERIAL_WITH_CRASH})
    run = _run(folder, reruns=0)
    assert "crashed while running 'tests/test_serial_sil.py::test_serial_b_crashes_once'" in (
        run.stdout), run.stdout[-3000:]
    # Failed once and not run again: its flag file would let a second run pass.
    assert "1 failed, 14 passed" in run.stdout, run.stdout[-3000:]


#: A test that fails its first run only, saying why.
FAIL_ONCE = '''
from pathlib import Path


def test_fails_once() -> None:
    flag = Path(__file__).with_name("failed.flag")
    if not flag.exists():
        flag.touch()
        assert "first" == "second", "the first attempt's own words"
'''


def test_a_rerun_tests_first_failure_is_shown_in_the_summary(tmp_path: Path) -> None:
    """A flaky test run again said only ``RERUN <id>``: why its first attempt failed was
    printed nowhere, so the flakes of full runs could not be told apart."""
    folder = _tests(tmp_path, {"test_a_quick.py": QUICK, "test_b_flaky.py": FAIL_ONCE})
    run = _run(folder)
    assert run.returncode == 0, run.stdout[-3000:]
    summary = run.stdout.partition("first attempts of the tests run again")[2]
    assert "tests/test_b_flaky.py::test_fails_once (call)" in summary, run.stdout[-3000:]
    assert "the first attempt's own words" in summary, run.stdout[-3000:]


#: A test that spends about half a second of CPU in a program it starts and waits for.
BUSY_CHILD = '''
import subprocess, sys


def test_busy_child() -> None:
    subprocess.run([sys.executable, "-c",
                    "import time\\nend = time.process_time() + 0.5\\n"
                    "while time.process_time() < end: pass"], check=True)
'''


def test_the_summary_gives_each_files_cpu_the_programs_it_waited_for_included(
        tmp_path: Path) -> None:
    """On two saturated cores a test's wall time says as much about what ran beside it as
    about its cost; the summary adds CPU seconds per file, counting the programs a test
    started and waited for."""
    folder = _tests(tmp_path, {"test_a_quick.py": QUICK, "test_b_busy.py": BUSY_CHILD})
    run = _run(folder)
    assert run.returncode == 0, run.stdout[-3000:]
    table = run.stdout.partition("most CPU by file")[2]
    cpu = {line.split()[-1]: float(line.split()[0]) for line in table.splitlines()[1:]
           if line.strip().endswith(".py")}
    assert cpu["tests/test_b_busy.py"] >= 0.5, run.stdout[-3000:]
    assert cpu["tests/test_a_quick.py"] < cpu["tests/test_b_busy.py"], run.stdout[-3000:]
