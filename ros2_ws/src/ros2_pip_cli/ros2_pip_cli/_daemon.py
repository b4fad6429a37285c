"""The graph daemon: one background node per user and ROS environment that has been
listening all along, so graph verbs answer at once (ros2cli's daemon, without TCP ports).

Where it lives: a Unix socket ``graph-KEY.sock`` in a private folder
(``$ROS2_PIP_CLI_DAEMON_DIR``, else ``$XDG_RUNTIME_DIR/ros2_pip_cli``, else
``/tmp/ros2_pip_cli-UID``; mode 0700, owned by the user, or it is not used). KEY hashes the
variables that decide what discovery sees (:data:`KEY_VARIABLES`), so a shell on another
domain or discovery range gets its own daemon, as ros2cli's does (it keys on the domain).

Who runs: the daemon holds an exclusive ``flock`` on ``graph-KEY.lock`` for its whole life.
The kernel drops the lock when the process ends, however it ends (SIGKILL included), so
"lock taken" means "a daemon is alive", a stale socket file left by a killed daemon is
simply replaced by the next one, and two commands starting one at the same moment end up
with one daemon (the second exits at once, and its command connects to the first).

When it answers: a request for a whole-graph answer waits until the daemon's own discovery
has settled (as a command without daemon would); after that it answers from what the node
knows, which DDS keeps current (an endpoint of a killed process goes when its lease
expires, as for any participant). A name not in the graph is reported as soon as the
graph has been quiet for ``QUIET_S``. It ends after ``ROS2_PIP_CLI_DAEMON_IDLE_S`` seconds
(default two hours, as ros2cli's) without a request, on ``ros2 daemon stop``, or SIGTERM.
"""

from __future__ import annotations

import argparse
import contextlib
import fcntl
import hashlib
import json
import os
import select
import signal
import socket
import socketserver
import stat
import subprocess
import sys
import threading
import time
import uuid
from collections.abc import Mapping
from pathlib import Path
from types import FrameType
from typing import Any

from ._timing import ANNOUNCE_S, QUIET_S, SETTLE_MAX_S, WAIT_S
from ._view import DAEMON_NODE_PREFIX, Query, View, build_view, present
from .errors import CliError, DaemonUnavailableError

#: Bumped whenever requests or answers change: a daemon of another version gets another key.
PROTOCOL = 1
DAEMON_DIR_ENV = "ROS2_PIP_CLI_DAEMON_DIR"
IDLE_ENV = "ROS2_PIP_CLI_DAEMON_IDLE_S"
IDLE_S = 2 * 60 * 60
#: What decides which participants discovery finds, and so which daemon may answer.
KEY_VARIABLES = (
    "ROS_DOMAIN_ID", "ROS_AUTOMATIC_DISCOVERY_RANGE", "ROS_STATIC_PEERS", "ROS_LOCALHOST_ONLY",
    "RMW_IMPLEMENTATION", "ROS_DISCOVERY_SERVER", "ROS_SUPER_CLIENT",
    "FASTRTPS_DEFAULT_PROFILES_FILE", "FASTDDS_DEFAULT_PROFILES_FILE",
    "FASTDDS_BUILTIN_TRANSPORTS", "CYCLONEDDS_URI", "ROS_SECURITY_ENABLE",
    "ROS_SECURITY_STRATEGY", "ROS_SECURITY_KEYSTORE", "ROS_SECURITY_ENCLAVE_OVERRIDE",
)
#: How long a command waits for a daemon it started to listen (Python and rclpy start-up).
START_S = 20.0
#: How often the daemon looks whether the graph changed (for "quiet"); cheap at this rate.
WATCH_S = 0.1
_POLL_S = 0.02


# -- where ---------------------------------------------------------------------------------

def daemon_dir() -> Path:
    configured = os.environ.get(DAEMON_DIR_ENV)
    if configured:
        return Path(configured)
    runtime = os.environ.get("XDG_RUNTIME_DIR")
    if runtime and Path(runtime).is_dir():
        return Path(runtime) / "ros2_pip_cli"
    return Path("/tmp") / f"ros2_pip_cli-{os.getuid()}"


def _private_dir() -> Path:
    """The daemon folder, created 0700; refused unless it is a real folder of ours that
    nobody else can write into (a socket there is only as safe as its folder)."""
    folder = daemon_dir()
    with contextlib.suppress(FileExistsError):
        folder.mkdir(mode=0o700, parents=True)
    info = folder.lstat()
    if not stat.S_ISDIR(info.st_mode) or info.st_uid != os.getuid():
        raise DaemonUnavailableError(f"{folder} is not a folder of this user")
    if info.st_mode & 0o077:
        raise DaemonUnavailableError(f"{folder} is open to others (mode {info.st_mode & 0o777:o})")
    return folder


def environment_key(environ: Mapping[str, str] | None = None) -> str:
    """The daemon a command with ``environ`` (default: this process's) may ask."""
    env = os.environ if environ is None else environ
    described = json.dumps([PROTOCOL, [env.get(v) for v in KEY_VARIABLES]])
    return hashlib.sha256(described.encode()).hexdigest()[:16]


class _Paths:
    def __init__(self, folder: Path, key: str) -> None:
        self.socket = folder / f"graph-{key}.sock"
        self.lock = folder / f"graph-{key}.lock"
        self.log = folder / f"graph-{key}.log"
        if len(os.fsencode(self.socket)) >= 104:
            raise DaemonUnavailableError(f"socket path too long: {self.socket}")


def _paths() -> _Paths:
    return _Paths(_private_dir(), environment_key())


# -- the command's side ----------------------------------------------------------------------

def _exchange(path: Path, request: dict[str, Any], *, timeout_s: float) -> dict[str, Any]:
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as sock:
        sock.settimeout(timeout_s)
        sock.connect(str(path))
        sock.sendall(json.dumps(request).encode() + b"\n")
        data = b""
        while not data.endswith(b"\n"):
            chunk = sock.recv(1 << 16)
            if not chunk:
                raise ConnectionResetError("the daemon closed the connection")
            data += chunk
    answer: dict[str, Any] = json.loads(data)
    return answer


def _request(paths: _Paths, request: dict[str, Any], *, timeout_s: float = 5.0,
             start: bool = False) -> dict[str, Any] | None:
    """Send ``request``; None if no daemon runs (after starting one, if ``start``)."""
    try:
        return _exchange(paths.socket, request, timeout_s=timeout_s)
    except (FileNotFoundError, ConnectionRefusedError):
        if not start or not _start(paths):
            return None
    return _exchange(paths.socket, request, timeout_s=timeout_s)


#: How a command starts the daemon (not ``-m``: the package imports this module itself).
_DAEMON_MAIN = "import sys; from ros2_pip_cli._daemon import main; sys.exit(main(sys.argv[1:]))"


def _start(paths: _Paths) -> bool:
    """Start a daemon and wait until it listens. False if it could not be started."""
    log = open(paths.log, "ab")  # noqa: SIM115 - handed to the child, closed below
    try:
        process = subprocess.Popen(
            [sys.executable, "-c", _DAEMON_MAIN, "--dir", str(paths.socket.parent),
             "--key", paths.socket.name[len("graph-"):-len(".sock")]],
            stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=log, cwd="/",
            start_new_session=True)
    finally:
        log.close()
    assert process.stdout is not None
    ready, _, _ = select.select([process.stdout], [], [], START_S)
    line = process.stdout.readline().strip() if ready else b""
    process.stdout.close()
    if line == b"ready":
        return True
    if line == b"running":  # another command started one a moment ago: it listens soon
        deadline = time.monotonic() + START_S
        while time.monotonic() < deadline:
            with contextlib.suppress(FileNotFoundError, ConnectionRefusedError), \
                    socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as probe:
                probe.connect(str(paths.socket))
                return True
            time.sleep(_POLL_S)
    return False


def ask_view(query: Query) -> View | None:
    """The daemon's answer to ``query``, starting the daemon if none runs; None when no
    daemon can answer (the command then listens for itself, as ros2cli falls back)."""
    try:
        paths = _paths()
        answer = _request(paths, {"op": "view", "query": query.to_json()},
                          timeout_s=SETTLE_MAX_S + WAIT_S + START_S, start=True)
    except DaemonUnavailableError as exc:
        print(f"warning: not using the graph daemon: {exc}", file=sys.stderr)
        return None
    except (OSError, ValueError):  # a daemon that died or answered garbage: go without
        return None
    if answer is None or not answer.get("ok"):
        return None
    return View.from_json(answer["view"])


def _lock_held(paths: _Paths) -> bool:
    try:
        fd = os.open(paths.lock, os.O_RDONLY)
    except FileNotFoundError:
        return False
    try:
        fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
    except BlockingIOError:
        return True
    finally:
        os.close(fd)
    return False


def is_running() -> bool:
    try:
        return _request(_paths(), {"op": "status"}) is not None
    except OSError:
        return False


def start() -> bool:
    """Start the daemon of this environment; False if one was running already."""
    paths = _paths()
    if _request(paths, {"op": "status"}) is not None:
        return False
    if not _start(paths):
        raise CliError(f"the daemon did not start (see {paths.log})")
    return True


def _stop_at(paths: _Paths, *, timeout_s: float = 10.0) -> bool:
    try:
        if _request(paths, {"op": "stop"}) is None:
            return False
    except OSError:
        return False
    deadline = time.monotonic() + timeout_s
    while _lock_held(paths):  # released by the kernel when the process has ended
        if time.monotonic() > deadline:
            raise CliError(f"the daemon did not stop within {timeout_s:g} s")
        time.sleep(_POLL_S)
    return True


def stop() -> bool:
    """Stop the daemon of this environment; False if none was running."""
    return _stop_at(_paths())


def stop_daemons(*, directory: Path) -> int:
    """Stop every daemon whose socket is in ``directory`` (tests point ``DAEMON_DIR_ENV`` at a
    folder of their own and call this in teardown); returns how many were stopped."""
    stopped = 0
    for sock in sorted(Path(directory).glob("graph-*.sock")):
        key = sock.name[len("graph-"):-len(".sock")]
        stopped += _stop_at(_Paths(Path(directory), key))
    return stopped


# -- ros2 daemon start|stop|status ------------------------------------------------------------

def register(commands: Any) -> None:
    from ._main import add_verbs, verb

    verbs = add_verbs(commands, "daemon", "Various daemon related sub-commands")
    verb(verbs, "start", "Start the daemon if it isn't running", _start_verb)
    verb(verbs, "stop", "Stop the daemon if it is running", _stop_verb)
    verb(verbs, "status", "Output the status of the daemon", _status_verb)


def _start_verb(_args: argparse.Namespace) -> int:
    print("The daemon has been started" if start() else "The daemon is already running")
    return 0


def _stop_verb(_args: argparse.Namespace) -> int:
    print("The daemon has been stopped" if stop() else "The daemon is not running")
    return 0


def _status_verb(_args: argparse.Namespace) -> int:
    print("The daemon is running" if is_running() else "The daemon is not running")
    return 0


# -- the daemon's side -----------------------------------------------------------------------

class GraphDaemon:
    """A hidden node that watches the graph; answers queries from request threads."""

    def __init__(self) -> None:
        from ._graph import CliNode

        domain = os.environ.get("ROS_DOMAIN_ID", "0")
        self.cli = CliNode(name=f"{DAEMON_NODE_PREFIX}{domain}_{uuid.uuid4().hex}")
        self.settled = threading.Event()
        self.stopping = threading.Event()
        self.last_change = time.monotonic()
        self._watcher = threading.Thread(target=self._watch, daemon=True, name="graph-watch")
        self._watcher.start()

    def _watch(self) -> None:
        self.cli.settle(min_s=ANNOUNCE_S)
        self.settled.set()
        last = self.cli._signature()
        while not self.stopping.wait(WATCH_S):
            current = self.cli._signature()
            if current != last:
                last, self.last_change = current, time.monotonic()

    def quiet(self) -> bool:
        return self.settled.is_set() and time.monotonic() - self.last_change >= QUIET_S

    def answer(self, query: Query) -> View:
        """As a command without daemon would answer, but from a graph known all along:
        whole-graph answers once discovery has settled and the graph is quiet (at once,
        normally); a name that appears, at once (once quiet, for counts); an absent name
        once the graph is quiet, because then discovery has nothing more to tell."""
        node = self.cli.node
        deadline = time.monotonic() + (WAIT_S if query.wait_kind else SETTLE_MAX_S)
        while time.monotonic() < deadline:
            if query.wait_kind and present(node, query):
                if not query.settle_after_wait:
                    break
                query = Query(settle_after_wait=True, topic=query.topic, node=query.node)
            if self.quiet():
                break
            time.sleep(_POLL_S)
        return build_view(node, query)

    def close(self) -> None:
        self.stopping.set()
        self._watcher.join(timeout=SETTLE_MAX_S + ANNOUNCE_S)
        self.cli.close()


class _Server(socketserver.ThreadingUnixStreamServer):
    daemon_threads = True

    def __init__(self, path: str) -> None:
        super().__init__(path, _Handler)
        self.graph: GraphDaemon | None = None
        self.stop_requested = False
        self.last_request = time.monotonic()
        self.ready = threading.Event()


class _Handler(socketserver.StreamRequestHandler):
    server: _Server

    def handle(self) -> None:
        server = self.server
        server.last_request = time.monotonic()
        try:
            request = json.loads(self.rfile.readline())
            op = request.get("op")
            if op == "status":
                reply: dict[str, Any] = {"ok": True, "pid": os.getpid()}
            elif op == "stop":
                server.stop_requested = True
                reply = {"ok": True}
            elif op == "view":
                server.ready.wait(START_S)
                if server.graph is None:
                    raise RuntimeError("the daemon's node did not start")
                view = server.graph.answer(Query.from_json(request["query"]))
                reply = {"ok": True, "view": view.to_json()}
            else:
                reply = {"ok": False, "error": f"unknown request {op!r}"}
        except Exception as exc:  # one bad request must not end the daemon
            reply = {"ok": False, "error": repr(exc)}
        with contextlib.suppress(OSError):
            self.wfile.write(json.dumps(reply).encode() + b"\n")
        server.last_request = time.monotonic()


def serve(folder: Path, key: str) -> int:
    """The daemon's main: take the lock, listen, say ``ready`` on stdout, answer."""
    paths = _Paths(folder, key)
    lock = os.open(paths.lock, os.O_RDWR | os.O_CREAT, 0o600)
    try:
        fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        print("running", flush=True)
        return 0
    os.ftruncate(lock, 0)
    os.write(lock, f"{os.getpid()}\n".encode())
    with contextlib.suppress(FileNotFoundError):
        paths.socket.unlink()  # left by a daemon that was killed: we hold the lock now
    old_umask = os.umask(0o177)
    try:
        server = _Server(str(paths.socket))
    finally:
        os.umask(old_umask)
    stop = threading.Event()

    def request_stop(_signum: int, _frame: FrameType | None) -> None:
        stop.set()

    signal.signal(signal.SIGTERM, request_stop)
    signal.signal(signal.SIGINT, request_stop)
    idle_s = float(os.environ.get(IDLE_ENV, IDLE_S))
    server.timeout = 0.2
    threading.Thread(target=_serve_requests, args=(server, stop), daemon=True).start()
    print("ready", flush=True)
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, sys.stdout.fileno())
    try:
        server.graph = GraphDaemon()
        server.ready.set()
        while not stop.wait(0.2):
            if server.stop_requested:
                print("stop requested", file=sys.stderr, flush=True)
                break
            if time.monotonic() - server.last_request > idle_s:
                print(f"idle for {idle_s:g} s: stopping", file=sys.stderr, flush=True)
                break
    finally:
        stop.set()
        server.server_close()
        with contextlib.suppress(FileNotFoundError):
            paths.socket.unlink()
        if server.graph is not None:
            server.graph.close()
        os.close(lock)  # releases the lock last: a new daemon may start from here on
    return 0


def _serve_requests(server: _Server, stop: threading.Event) -> None:
    while not stop.is_set():
        with contextlib.suppress(OSError, ValueError):
            server.handle_request()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="ros2_pip_cli graph daemon")
    parser.add_argument("--dir", required=True, type=Path)
    parser.add_argument("--key", required=True)
    args = parser.parse_args(argv)
    return serve(args.dir, args.key)
