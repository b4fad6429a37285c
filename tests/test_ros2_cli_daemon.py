"""The ros2 command's graph daemon, as a user meets it: started by the first graph verb,
answering as the command would without it, bypassed by ``--no-daemon``, controlled by
``ros2 daemon start|stop|status``, replaced after SIGKILL, one per discovery environment,
ending by itself when idle. Speed is bench/cli_bench.py's business, not asserted here.

Every test keeps its daemons in a folder of its own and stops them in teardown.
"""

from __future__ import annotations

import fcntl
import os
import signal
import subprocess
import sys
import threading
from collections.abc import Iterator
from pathlib import Path

import pytest

from efficient_comm.testing import isolated_domain_id, unique_topic

from ._cli import ROOT, Running, cli_env, daemons_in_tmp, ros2_path, running
from ._ros import short_lease_profile

PEER = ROOT / "tests" / "_cli_peer.py"

class Graph:
    def __init__(self, domain_id: int, topic: str, daemons: Path, peer: Running) -> None:
        self.domain_id, self.topic, self.daemons, self.peer = domain_id, topic, daemons, peer

    def env(self, **extra: str) -> dict[str, str]:
        env = cli_env(self.domain_id)
        env.update(extra)
        return env

    def ros2(self, *args: str, ok: bool = True,
             env: dict[str, str] | None = None) -> subprocess.CompletedProcess[str]:
        result = subprocess.run([ros2_path(), *args], env=env or self.env(),
                                capture_output=True, text=True, timeout=90)
        assert "Traceback" not in result.stderr, result.stderr
        if ok:
            assert result.returncode == 0, (args, result.stderr)
        return result

    def out(self, *args: str) -> str:
        return self.ros2(*args).stdout


@pytest.fixture
def graph(tmp_path: Path) -> Iterator[Graph]:
    domain_id = isolated_domain_id()
    topic = unique_topic("daemon")
    daemons = tmp_path / "d"
    daemons.mkdir()
    with daemons_in_tmp(daemons), \
            running([sys.executable, str(PEER), topic], domain_id=domain_id,
                    log=tmp_path / "peer.log") as peer:
        peer.wait_for(lambda text: "ready" in text)
        yield Graph(domain_id, topic, daemons, peer)


def _lock_files(folder: Path) -> list[Path]:
    return sorted(folder.glob("graph-*.lock"))


def _wait_unlocked(lock: Path, timeout_s: float) -> bool:
    """True once nobody holds ``lock`` (the daemon holding it has ended)."""
    fd = os.open(lock, os.O_RDONLY)
    done = threading.Event()

    def take() -> None:
        fcntl.flock(fd, fcntl.LOCK_SH)  # blocks until the daemon's exclusive lock is gone
        done.set()

    threading.Thread(target=take, daemon=True).start()
    released = done.wait(timeout_s)
    if released:
        os.close(fd)
    return released


# Twenty commands, ten of which listen for themselves (3.5 s and more each): about a minute
# on an idle machine, over the default 120 s on a loaded one.
@pytest.mark.timeout(300)
def test_answers_equal_the_answers_without_daemon(graph: Graph) -> None:
    assert graph.out("daemon", "status") == "The daemon is not running\n"
    first = graph.out("topic", "list")  # the first graph verb starts the daemon
    assert graph.topic in first.splitlines()
    assert graph.out("daemon", "status") == "The daemon is running\n"
    for args in (["topic", "list"], ["topic", "list", "-t"], ["node", "list"],
                 ["node", "list", "-a"], ["service", "list", "-t"],
                 ["topic", "info", graph.topic], ["topic", "info", "-v", graph.topic],
                 ["topic", "type", graph.topic], ["node", "info", "/cli_peer"],
                 ["service", "type", "/cli_peer/check"]):
        with_daemon = graph.out(*args)
        # A command listening for itself may miss endpoints a loaded machine announces late
        # (that is why the daemon exists): it gets a second, longer listen before it counts.
        direct = graph.out(*args, "--no-daemon")
        if direct != with_daemon and args[1] == "list":
            direct = graph.out(*args, "--no-daemon", "--spin-time", "10")
        assert with_daemon == direct, args
        assert with_daemon.strip(), args
    assert graph.out("node", "list") == "/cli_peer\n"
    assert graph.out("topic", "info", graph.topic) == (
        "Type: std_msgs/msg/String\nPublisher count: 1\nSubscription count: 0\n")


def test_unknown_names_are_reported_by_a_warm_daemon(graph: Graph) -> None:
    graph.out("daemon", "start")
    cases = {("topic", "info", "/no_such_topic"): "error: Unknown topic '/no_such_topic'\n",
             ("topic", "type", "/no_such_topic"): "error: Unknown topic '/no_such_topic'\n",
             ("node", "info", "/no_such_node"): "error: Node not found: /no_such_node\n",
             ("service", "type", "/no_such"): "error: Unknown service '/no_such'\n"}
    for args, message in cases.items():
        result = graph.ros2(*args, ok=False)
        assert (result.returncode, result.stderr) == (1, message), args


def test_start_stop_status_as_ros2cli(graph: Graph) -> None:
    assert graph.out("daemon", "stop") == "The daemon is not running\n"
    assert graph.out("daemon", "start") == "The daemon has been started\n"
    assert graph.out("daemon", "start") == "The daemon is already running\n"
    assert graph.out("daemon", "status") == "The daemon is running\n"
    sockets = list(graph.daemons.glob("graph-*.sock"))
    assert len(sockets) == 1 and (sockets[0].stat().st_mode & 0o777) == 0o600
    assert (graph.daemons.stat().st_mode & 0o777) == 0o700
    assert graph.out("daemon", "stop") == "The daemon has been stopped\n"
    assert graph.out("daemon", "status") == "The daemon is not running\n"
    assert not list(graph.daemons.glob("graph-*.sock"))


def test_no_daemon_is_accepted_where_ros2cli_accepts_it(graph: Graph) -> None:
    assert graph.topic in graph.out("topic", "list", "--no-daemon").splitlines()
    assert graph.out("param", "get", "--no-daemon", "/cli_peer", "count") == (
        "Integer value is: 5\n")
    echo = graph.out("topic", "echo", "--once", "--no-daemon", graph.topic)
    assert echo.startswith("data: hello ")
    assert graph.out("daemon", "status") == "The daemon is not running\n"


def test_a_killed_daemon_and_its_stale_socket_do_not_break_the_next_call(graph: Graph) -> None:
    graph.out("daemon", "start")
    [lock] = _lock_files(graph.daemons)
    pid = int(lock.read_text())
    os.kill(pid, signal.SIGKILL)
    assert _wait_unlocked(lock, 30)
    assert list(graph.daemons.glob("graph-*.sock")), "the killed daemon left its socket"
    assert graph.topic in graph.out("topic", "list").splitlines()
    assert graph.out("daemon", "status") == "The daemon is running\n"
    assert int(lock.read_text()) != pid


def test_one_daemon_per_discovery_environment(graph: Graph) -> None:
    other_domain = isolated_domain_id()
    other = graph.env(ROS_DOMAIN_ID=str(other_domain))
    assert graph.topic in graph.out("topic", "list").splitlines()
    assert graph.topic not in graph.ros2("topic", "list", env=other).stdout.splitlines()
    assert len(_lock_files(graph.daemons)) == 2
    assert graph.ros2("daemon", "status", env=other).stdout == "The daemon is running\n"
    assert graph.ros2("daemon", "stop", env=other).stdout == "The daemon has been stopped\n"
    assert graph.out("daemon", "status") == "The daemon is running\n"


def test_the_daemon_ends_by_itself_when_idle(graph: Graph) -> None:
    graph.ros2("daemon", "start", env=graph.env(ROS2_PIP_CLI_DAEMON_IDLE_S="1"))
    [lock] = _lock_files(graph.daemons)
    assert _wait_unlocked(lock, 60)
    assert graph.out("daemon", "status") == "The daemon is not running\n"


def test_a_folder_open_to_others_is_not_used(graph: Graph, tmp_path: Path) -> None:
    shared = tmp_path / "shared"
    shared.mkdir(mode=0o777)
    shared.chmod(0o777)
    result = graph.ros2("topic", "list", env=graph.env(ROS2_PIP_CLI_DAEMON_DIR=str(shared)))
    assert graph.topic in result.stdout.splitlines()
    assert result.stderr.startswith("warning: not using the graph daemon: ")
    assert result.stderr.count("\n") == 1
    assert not list(shared.iterdir())


def test_endpoints_of_a_killed_process_go_with_its_lease(
        graph: Graph, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    profile = short_lease_profile(tmp_path)
    doomed_topic = unique_topic("doomed")
    monkeypatch.setenv("FASTRTPS_DEFAULT_PROFILES_FILE", str(profile))
    doomed = Running([sys.executable, str(PEER), doomed_topic], domain_id=graph.domain_id,
                     log=tmp_path / "doomed.log")
    monkeypatch.undo()
    try:
        doomed.wait_for(lambda text: "ready" in text)
        assert doomed_topic in graph.out("topic", "list").splitlines()
    finally:
        doomed.stop(signal.SIGKILL)
    # DDS drops the participant 2 s after its last announcement (the default lease is 20 s);
    # answers from a cache that kept it would list it on and on.
    calls = 30
    for _ in range(calls):
        if doomed_topic not in graph.out("topic", "list").splitlines():
            break
    else:
        pytest.fail(f"{doomed_topic} still listed after {calls} calls")
    assert graph.out("topic", "list") == graph.out("topic", "list", "--no-daemon")


def _daemon_processes(folder: Path) -> list[int]:
    """Pids of the processes serving a daemon socket in ``folder``."""
    pids = []
    for cmdline in Path("/proc").glob("[0-9]*/cmdline"):
        try:
            args = cmdline.read_bytes().split(b"\0")
        except OSError:  # ended meanwhile
            continue
        if b"--dir" in args and os.fsencode(folder) in args:
            pids.append(int(cmdline.parent.name))
    return pids


def test_commands_starting_a_daemon_at_once_end_up_with_one(graph: Graph) -> None:
    calls = [subprocess.Popen([ros2_path(), "topic", "list"], env=graph.env(),
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
             for _ in range(3)]
    outputs = [call.communicate(timeout=90) for call in calls]
    assert [call.returncode for call in calls] == [0, 0, 0], outputs
    assert all(graph.topic in out.splitlines() for out, _ in outputs), outputs
    assert len(_daemon_processes(graph.daemons)) == 1
    assert graph.out("daemon", "status") == "The daemon is running\n"
