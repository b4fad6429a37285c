"""Test helpers: a real ROS 1 system (Debian's rosmaster and rospy) for bridge tests, a
test handle on a real rclpy node, and the log lines rclpy's loggers wrote.

ROS 1 runs on the system Python (``/usr/bin/python3``) with a clean environment, never in
the ROS 2 virtual environment; its master listens on 127.0.0.1 on a free ephemeral port.
Every process gets its own session and is killed with its group on close.
"""

from __future__ import annotations

import contextlib
import os
import queue
import shutil
import signal
import socket
import subprocess
import tempfile
import threading
import time
import uuid
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from types import TracebackType
from typing import Any, Protocol

from efficient_comm import Container
from efficient_comm.testing import ManualClock, TestHandle, isolated_domain_id

from .adapters.ros1.xmlrpc import call
from .errors import LinkError

SYSTEM_PYTHON = "/usr/bin/python3"


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port: int = s.getsockname()[1]
        return port


def wait_for(predicate: Callable[[], bool], timeout_s: float, *, poll_s: float = 0.01) -> bool:
    """Poll ``predicate`` until true or ``timeout_s`` passes; returns its last value."""
    deadline = time.monotonic() + timeout_s
    while not predicate():
        if time.monotonic() > deadline:
            return predicate()
        time.sleep(poll_s)
    return True


@contextlib.contextmanager
def rclpy_test_handle(name: str = "rf_bridge") -> Iterator[TestHandle]:
    """A :class:`TestHandle` whose node is a real rclpy node (DDS in an isolated domain,
    manual clock): what the bridge logs goes through rclpy's real logger, as in production.
    """
    with Container(
        f"rf_test_{uuid.uuid4().hex[:8]}",
        dds=True,
        domain_id=isolated_domain_id(),
        clock=ManualClock(),
        serve=False,
    ) as container:
        yield TestHandle(name, container=container)


class _Capture(Protocol):
    def readouterr(self) -> Any: ...


class CapturedLogs:
    """What rclpy's real loggers of this process wrote, read from pytest's ``capfd``.

    rcutils writes every record to the process's stderr; tests of the bridge assert on
    those lines instead of logging into a recording double, so they see what rclpy's
    logger does (it refuses, for example, one call site logging at two severities).
    """

    def __init__(self, capfd: _Capture) -> None:
        self._capfd = capfd
        self._text = ""

    def text(self) -> str:
        """Everything logged so far (stderr of the process since the capture began)."""
        self._text += self._capfd.readouterr().err
        return self._text

    def wait(self, needle: str, timeout_s: float = 10.0) -> bool:
        """True once a logged line contains ``needle``; False after ``timeout_s``."""
        return wait_for(lambda: needle in self.text(), timeout_s, poll_s=0.05)


class LineReader:
    """Lines of a child's stdout, read by a thread so waiting never blocks on a buffer."""

    def __init__(self, proc: subprocess.Popen[bytes]) -> None:
        assert proc.stdout is not None
        self._proc = proc
        self._lines: queue.Queue[str | None] = queue.Queue()
        stream = proc.stdout

        def pump() -> None:
            for raw in iter(stream.readline, b""):
                self._lines.put(raw.decode(errors="replace").rstrip("\n"))
            self._lines.put(None)

        threading.Thread(target=pump, daemon=True).start()

    def next(self, timeout_s: float = 20.0) -> str:
        """The next line; AssertionError if none comes in time or the program ended."""
        try:
            line = self._lines.get(timeout=timeout_s)
        except queue.Empty:
            raise AssertionError(f"no output from {self._proc.args!r} in {timeout_s} s") from None
        if line is None:
            raise AssertionError(f"{self._proc.args!r} exited ({self._proc.poll()})")
        return line

    def drain(self) -> list[str]:
        out: list[str] = []
        while True:
            try:
                line = self._lines.get_nowait()
            except queue.Empty:
                return out
            if line is not None:
                out.append(line)


class Ros1System:
    """A rosmaster of its own plus helpers to start ROS 1 programs against it."""

    def __init__(self) -> None:
        if shutil.which("rosmaster") is None:
            raise RuntimeError("rosmaster not installed: run scripts/setup_ros1.sh")
        self.port = free_port()
        self.master_uri = f"http://127.0.0.1:{self.port}/"
        self.workdir = Path(tempfile.mkdtemp(prefix="rf_ros1_"))
        self._procs: list[subprocess.Popen[bytes]] = []
        self.master: subprocess.Popen[bytes] | None = None
        self.start_master()

    @property
    def env(self) -> dict[str, str]:
        return {
            "PATH": "/usr/bin:/bin",
            "HOME": str(self.workdir),
            "ROS_MASTER_URI": self.master_uri,
            "ROS_HOSTNAME": "127.0.0.1",
            "ROS_LOG_DIR": str(self.workdir / "log"),
            "ROS_HOME": str(self.workdir),
            "PYTHONUNBUFFERED": "1",
            "LANG": "C.UTF-8",
        }

    def start_master(self, timeout_s: float = 20.0) -> None:
        self.master = self.spawn(["rosmaster", "--core", "-p", str(self.port)], log="master")

        def up() -> bool:
            try:
                call(self.master_uri, "getPid", "/test", timeout_s=0.5)
                return True
            except LinkError:
                return False

        if not wait_for(up, timeout_s, poll_s=0.05):
            raise RuntimeError(f"rosmaster did not come up on {self.master_uri}")

    def stop_master(self) -> None:
        if self.master is not None:
            self.kill(self.master)
            self.master = None

    def spawn(
        self, args: Sequence[str], *, log: str, stdout_pipe: bool = False
    ) -> subprocess.Popen[bytes]:
        """Start a ROS 1 program in its own session (stderr to ``workdir/<log>.log``)."""
        err = open(self.workdir / f"{log}.log", "ab")  # noqa: SIM115 (closed with the process)
        proc = subprocess.Popen(
            list(args),
            env=self.env,
            cwd=self.workdir,
            start_new_session=True,
            stdout=subprocess.PIPE if stdout_pipe else err,
            stderr=err,
        )
        err.close()
        self._procs.append(proc)
        return proc

    def python(self, script: str, *args: str, log: str) -> subprocess.Popen[bytes]:
        """Run ``script`` with the system Python (rospy); stdout is a pipe to read lines from."""
        return self.spawn([SYSTEM_PYTHON, "-c", script, *args], log=log, stdout_pipe=True)

    def log_text(self, log: str) -> str:
        path = self.workdir / f"{log}.log"
        return path.read_text(errors="replace") if path.exists() else ""

    @staticmethod
    def kill(proc: subprocess.Popen[bytes], sig: int = signal.SIGKILL) -> None:
        if proc.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(proc.pid, sig)
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait(timeout=10)
        if proc.stdout is not None:
            proc.stdout.close()

    def close(self) -> None:
        for proc in reversed(self._procs):
            self.kill(proc)
        shutil.rmtree(self.workdir, ignore_errors=True)

    def __enter__(self) -> Ros1System:
        return self

    def __exit__(
        self, t: type[BaseException] | None, e: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()
