"""Test-session set-up shared by every suite: DDS on loopback, composition-ready process,
and each test's kind (tier) from its file name.

Fast DDS reads its profile once per process, when the first participant is created, so
the profile that keeps in-process and DDS delivery apart must be in place before any test
calls ``rclpy.init`` (see efficient_comm.dds).

Kinds (``sil``, ``browser``, ``bench``, ``docs``, ``process``, ``root``, ``fast``) are
markers given by tests/_kinds.py's table, so ``pytest -m fast`` selects the tier to run
after an edit and new test files get a tier without a marker of their own. Tests of kind
``root`` are counted at the end ("root-only tests: N ran, M skipped"); under CI (``CI=true``)
as root, a skipped one fails the run, since CI is where they are meant to run.
"""

import faulthandler
import importlib.util
import os
import resource
import shutil
import signal
import subprocess
import sys
import tempfile
from collections.abc import Generator, Iterator
from pathlib import Path
from typing import Any

import pytest

from efficient_comm.dds import prepare_process

os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
prepare_process()

ROOT = Path(__file__).resolve().parent


def _load_kinds() -> Any:
    # By path: the repository root is not on sys.path under --import-mode=importlib.
    spec = importlib.util.spec_from_file_location("_test_kinds", ROOT / "tests" / "_kinds.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


_kinds = _load_kinds()


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Mark each test with its kinds; a file no row of the table covers is an error."""
    missing = set()
    for item in items:
        path = Path(str(item.path)).resolve()
        try:
            rel = path.relative_to(ROOT).as_posix()
        except ValueError:  # a test outside the repository (pytester's): no tier
            continue
        kinds = _kinds.kinds_of(rel, item.name, fixtures=getattr(item, "fixturenames", ()))
        if not kinds:
            missing.add(rel)
        for kind in sorted(kinds):
            item.add_marker(kind)
    if missing:
        raise pytest.UsageError(
            f"no test kind for {', '.join(sorted(missing))}: add a row to "
            "tests/_kinds.py's KIND_PATTERNS"
        )


@pytest.hookimpl(optionalhook=True)
def pytest_xdist_make_scheduler(config: pytest.Config, log: Any) -> Any:
    """Under ``-n N --dist loadgroup`` (scripts/test.sh), tests of a kind with a serial group
    (tests/_kinds.py's ``serial_group``: simulations and benchmarks, docs commands) run one
    after another in one worker, every other test wherever a worker is free.

    The group comes from the node id's file and name, as the kinds do, and not from an
    ``xdist_group`` marker: pytest-xdist 3.8 groups marked tests by renaming their node ids,
    which pytest 9 no longer lets a plugin do (the marker is silently ignored).
    """
    if config.getvalue("dist") != "loadgroup":
        return None
    from xdist.scheduler import LoadScopeScheduling

    class KindScheduling(LoadScopeScheduling):  # type: ignore[misc]
        """After a worker crash (the backstop's exit), only the crashed worker's unfinished
        tests go back in the queue, and the crashed test itself only through
        ``mark_test_pending``, which pytest-rerunfailures calls while ``--reruns`` allows.

        xdist's LoadScopeScheduling requeued the whole workload, finished scopes included: a
        worker with nothing left that was handed one got an empty list of tests, never
        reported again, and so was never given the scopes queued behind it; once every
        worker was in that state the run stalled. It also ran the crashed test again
        whatever ``--reruns`` said, and could not requeue it for pytest-rerunfailures.
        """

        def _split_scope(self, nodeid: str) -> str:
            path, _, name = nodeid.partition("::")
            return _kinds.serial_group(_kinds.kinds_of(path, name)) or nodeid

        def remove_node(self, node: Any) -> str | None:
            workload = self.assigned_work.pop(node)
            unfinished = [(scope, nodeid) for scope, unit in workload.items()
                          for nodeid, done in unit.items() if not done]
            if not unfinished:
                return None
            # A worker runs its tests in the order they were sent: the first unfinished one
            # is the one it crashed in.
            crashitem: str = unfinished[0][1]
            for scope, nodeid in unfinished[1:]:
                self.workqueue.setdefault(scope, {})[nodeid] = False
            if len(unfinished) > 1:
                for other in self.nodes:
                    self._reschedule(other)
            return crashitem

        def mark_test_pending(self, item: str) -> None:
            scope = self._split_scope(item)
            # A scope still in the queue, or a serial group a live worker holds, takes the
            # test back; else it is a scope of its own again, first in the queue.
            if scope in self.workqueue:
                self.workqueue[scope][item] = False
            else:
                for node, work in self.assigned_work.items():
                    if scope in work and not node.shutting_down:
                        work[scope][item] = False
                        node.send_runtest_some([self.registered_collections[node].index(item)])
                        return
                self.workqueue[scope] = {item: False}
            self.workqueue.move_to_end(scope, last=False)
            for node in self.nodes:
                self._reschedule(node)

    return KindScheduling(config, log)


#: Where a stuck test's stacks go: a directory the controlling process makes and its xdist
#: workers inherit through the environment; the controller prints what is in it at the end.
BACKSTOP_DIR = "EFFICIENT_COMM_TEST_BACKSTOP_DIR"


def pytest_configure(config: pytest.Config) -> None:
    # A run started in the background by a non-interactive shell (``scripts/test.sh ... &``)
    # has SIGINT ignored, and every program a test starts inherits that across exec: the
    # tests that stop a program with Ctrl-C then waited for it in vain (20 of them, every
    # run). Tests stand in for a user at a terminal, where Ctrl-C works.
    if signal.getsignal(signal.SIGINT) == signal.SIG_IGN:
        signal.signal(signal.SIGINT, signal.default_int_handler)
    # Every controlling run makes its own directory, even when it inherited one: a pytest
    # that a test starts (a nested --collect-only) would otherwise print, and delete, the
    # outer run's dumps of tests still in progress.
    if not hasattr(config, "workerinput"):
        os.environ[BACKSTOP_DIR] = tempfile.mkdtemp(prefix="pytest-backstop-")


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item: pytest.Item) -> Iterator[None]:
    """A backstop behind pytest-timeout: a test still running long after its timeout (every
    phase and every rerun spent) dumps every thread's stack and ends its process.

    pytest-timeout interrupts a test with SIGALRM, whose Python handler runs only once the
    main thread returns to the interpreter; a thread stuck in native code (a DDS or rclpy
    call waiting on a lock) never does, and the xdist worker would then idle until CI's
    hard limit. faulthandler's watchdog is a native thread: it still dumps the stacks, and
    the exit makes xdist report the test as crashed and go on with a new worker. The stacks
    go to a file (the worker's stderr is pytest's capture, lost with the process), which the
    controller prints in its summary.

    faulthandler shows Python frames only, and a test stuck in ``_rclpy.Node(...)`` says
    nothing about the lock it waits on; so, where gdb exists, a watcher process (below) adds
    every thread's native stack to the same file shortly before the exit.
    """
    global _cpu_mark
    _cpu_mark = _cpu_now()
    marker = item.get_closest_marker("timeout")
    timeout = float(marker.args[0]) if marker and marker.args else float(
        item.config.getini("timeout") or 0)
    if timeout <= 0:
        yield
        return
    limit = 2 * timeout * (int(item.config.getoption("reruns", 0) or 0) + 1) + 10
    dump = Path(os.environ[BACKSTOP_DIR]) / f"{os.getpid()}.txt"
    # Appending, as the native-stack watcher does: neither overwrites the other's lines.
    with dump.open("a") as out:
        out.write(f"{item.nodeid} still ran {limit:.0f} s after it began; its threads:\n")
        out.flush()
        faulthandler.dump_traceback_later(limit, exit=True, file=out)
        _native_stacks_at(limit - min(30.0, limit / 2), dump)
        try:
            yield
        finally:
            _native_stacks_at(None, dump)
            faulthandler.cancel_dump_traceback_later()
    dump.unlink(missing_ok=True)


def _cpu_now() -> float:
    """CPU seconds of this process and of the programs it started and waited for."""
    own, children = (resource.getrusage(who) for who in
                     (resource.RUSAGE_SELF, resource.RUSAGE_CHILDREN))
    return own.ru_utime + own.ru_stime + children.ru_utime + children.ru_stime


_cpu_mark = 0.0


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo[None]
                              ) -> Generator[None, Any, None]:
    """Each phase's report carries the CPU seconds it took (``cpu_s`` in its user
    properties, which xdist hands to the controller): on two saturated cores a test's wall
    time says how long it waited as much as what it cost, and only less CPU makes the
    suite shorter (issue 18). Counted: the worker (every thread) and the programs the
    phase started and waited for; not programs left running (a session's browser)."""
    global _cpu_mark
    outcome = yield
    now = _cpu_now()
    outcome.get_result().user_properties.append(("cpu_s", round(now - _cpu_mark, 3)))
    _cpu_mark = now


#: The watcher: told "<seconds> <file>" it appends gdb's stacks of every thread of its parent
#: (this worker) to the file when the seconds pass first; "off" disarms it; it ends with its
#: parent (end of input).
_WATCHER = '''
import os, select, subprocess, sys, time
pid = os.getppid()
deadline, dump = None, ""
while True:
    wait = None if deadline is None else max(0.0, deadline - time.monotonic())
    if select.select([sys.stdin], [], [], wait)[0]:
        line = sys.stdin.readline()
        if not line:
            break
        seconds, _, dump = line.strip().partition(" ")
        deadline = None if seconds == "off" else time.monotonic() + float(seconds)
    elif deadline is not None:
        deadline = None
        with open(dump, "a") as out:
            out.write("native stacks (gdb):\\n")
            out.flush()
            subprocess.run(["gdb", "-batch", "-nx", "-iex", "set auto-load python-scripts off",
                            "-p", str(pid), "-ex", "thread apply all bt"],
                           stdin=subprocess.DEVNULL, stdout=out, stderr=subprocess.DEVNULL,
                           timeout=120, check=False)
'''
_watcher: subprocess.Popen[str] | None = None


def _native_stacks_at(seconds: float | None, dump: Path) -> None:
    """Arm (``seconds``) or disarm (None) this process's native-stack watcher."""
    global _watcher
    if shutil.which("gdb") is None:
        return
    if _watcher is None or _watcher.poll() is not None:
        if seconds is None:
            return
        _watcher = subprocess.Popen([sys.executable, "-c", _WATCHER], stdin=subprocess.PIPE,
                                    text=True)
    assert _watcher.stdin is not None
    _watcher.stdin.write(f"{'off' if seconds is None else seconds} {dump}\n")
    _watcher.stdin.flush()


def _print_stuck_tests(terminalreporter: Any) -> None:
    if hasattr(terminalreporter.config, "workerinput"):  # an xdist worker: the controller's
        return
    folder = Path(os.environ.get(BACKSTOP_DIR, "/nonexistent"))
    for dump in sorted(folder.glob("*.txt")):
        terminalreporter.write_sep("=", "stuck test (conftest.py's backstop)", red=True)
        terminalreporter.write_line(dump.read_text(errors="replace"))
        dump.unlink()


_root_outcomes: dict[str, str] = {}
#: Seconds and node ids per lane (a serial group, or "parallel" for the tests that run
#: wherever a worker is free), summed from every phase of every report the run received.
_lane_seconds: dict[str, float] = {}
_lane_tests: dict[str, set[str]] = {}
#: Seconds per "<lane> <node id>": the serial lanes' sums are a floor under the wall time,
#: the parallel lane's is shared among the workers.
_test_seconds: dict[str, float] = {}
#: CPU seconds per test file (every phase and rerun; see pytest_runtest_makereport).
_file_cpu: dict[str, float] = {}
#: What each first attempt of a test run again said (node id, the end of its report): with
#: ``--reruns`` a flaky test's failure was otherwise shown nowhere, only ``RERUN <id>``.
_rerun_reports: list[tuple[str, str]] = []
#: Lines of each such report kept for the summary (the assertion and what led to it).
RERUN_LINES = 40


def pytest_runtest_logreport(report: pytest.TestReport) -> None:
    lane = _kinds.serial_group(k for k in _kinds.KINDS if k in report.keywords) or "parallel"
    _lane_seconds[lane] = _lane_seconds.get(lane, 0.0) + report.duration
    _lane_tests.setdefault(lane, set()).add(report.nodeid)
    key = f"{lane} {report.nodeid}"
    _test_seconds[key] = _test_seconds.get(key, 0.0) + report.duration
    cpu = dict(report.user_properties).get("cpu_s")
    if isinstance(cpu, (int, float)):
        name = f"{lane} {report.nodeid.partition('::')[0]}"
        _file_cpu[name] = _file_cpu.get(name, 0.0) + cpu
    if str(report.outcome) == "rerun":  # pytest-rerunfailures' mark on a failed first attempt
        text = report.longreprtext.rstrip().splitlines()[-RERUN_LINES:]
        _rerun_reports.append((f"{report.nodeid} ({report.when})", "\n".join(text)))
    if "root" not in report.keywords:
        return
    if report.skipped:
        _root_outcomes[report.nodeid] = "skipped"
    elif report.when == "call" and report.nodeid not in _root_outcomes:
        _root_outcomes[report.nodeid] = "ran"


def _root_counts() -> tuple[int, int]:
    outcomes = list(_root_outcomes.values())
    return outcomes.count("ran"), outcomes.count("skipped")


def _root_required() -> bool:
    return os.environ.get("CI", "").lower() == "true" and os.geteuid() == 0


def _lane_line() -> str:
    """Where a run's time went: a serial lane's sum is a floor under the wall time however
    many workers there are, the rest is shared among them (the suite's budget, issue 18)."""
    lanes = sorted(_lane_seconds, key=lambda lane: (lane == "parallel", lane))
    return "time by lane: " + ", ".join(
        f"{lane} {_lane_seconds[lane]:.0f} s ({len(_lane_tests[lane])} tests)"
        for lane in lanes)


def _slowest_lines(count: int = 20) -> list[str]:
    """Where cutting time shortens a run (every phase and rerun summed): the serial lanes'
    slowest tests, and the parallel lane's slowest files (its time is that of many short
    tests; ``--durations`` shows single tests of every lane mixed)."""
    serial: dict[str, float] = {}
    files: dict[str, float] = {}
    for key, seconds in _test_seconds.items():
        lane, _, nodeid = key.partition(" ")
        if lane == "parallel":
            name = f"parallel {nodeid.partition('::')[0]}"
            files[name] = files.get(name, 0.0) + seconds
        else:
            serial[key] = seconds
    lines = []
    tables = [("slowest tests of the serial lanes:", serial),
              ("slowest files of the parallel lane:", files)]
    if _file_cpu:
        tables.append((f"most CPU by file ({sum(_file_cpu.values()):.0f} s in all; the "
                       "worker and the programs it waited for):", _file_cpu))
    for title, table in tables:
        lines.append(title)
        lines += [f"{seconds:7.1f} s  {key}"
                  for key, seconds in sorted(table.items(), key=lambda item: -item[1])[:count]]
    return lines


def pytest_terminal_summary(terminalreporter: Any) -> None:
    _print_stuck_tests(terminalreporter)
    if _rerun_reports and not hasattr(terminalreporter.config, "workerinput"):
        terminalreporter.write_sep("=", "first attempts of the tests run again", yellow=True)
        for nodeid, text in _rerun_reports:
            terminalreporter.write_sep("-", nodeid)
            terminalreporter.write_line(text)
    if _lane_seconds and not hasattr(terminalreporter.config, "workerinput"):
        terminalreporter.write_line(_lane_line())
        for line in _slowest_lines():
            terminalreporter.write_line(line)
    ran, skipped = _root_counts()
    if ran or skipped:
        terminalreporter.write_line(f"root-only tests: {ran} ran, {skipped} skipped")
        if skipped and _root_required():
            terminalreporter.write_line(
                "root-only tests were skipped under CI as root: failing the run", red=True)


def pytest_sessionfinish(session: pytest.Session, exitstatus: int) -> None:
    if _root_counts()[1] and _root_required() and exitstatus == 0:
        session.exitstatus = pytest.ExitCode.TESTS_FAILED
