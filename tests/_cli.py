"""Running the ``ros2`` command as a user types it, for the command's and the docs' tests."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path

from efficient_comm.testing import ros_env, stop_process_group
from ros2_pip_cli import DAEMON_DIR_ENV, stop_daemons

ROOT = Path(__file__).resolve().parents[1]
VENV_BIN = Path(sys.executable).parent


def cli_env(domain_id: int) -> dict[str, str]:
    """The test's environment (scripts/env.sh sourced) on an isolated domain, venv first."""
    env = ros_env(domain_id)
    env["PATH"] = f"{VENV_BIN}{os.pathsep}{env.get('PATH', '')}"
    env["PYTHONUNBUFFERED"] = "1"
    return env


@contextmanager
def daemons_in_tmp(directory: Path) -> Iterator[Path]:
    """Point the ``ros2`` command's graph daemons (of this process's children) at
    ``directory`` (made private, as the command requires) and stop them all on exit."""
    directory.chmod(0o700)
    previous = os.environ.get(DAEMON_DIR_ENV)
    os.environ[DAEMON_DIR_ENV] = str(directory)
    try:
        yield directory
    finally:
        if previous is None:
            del os.environ[DAEMON_DIR_ENV]
        else:
            os.environ[DAEMON_DIR_ENV] = previous
        stop_daemons(directory=directory)


def ros2_path() -> str:
    found = shutil.which("ros2", path=str(VENV_BIN))
    assert found, f"no ros2 in {VENV_BIN}: run scripts/setup.sh (it writes the launcher)"
    return found


def ros2(*args: str, domain_id: int, timeout: float = 60, cwd: Path | None = None,
         stdin: str = "") -> subprocess.CompletedProcess[str]:
    """``ros2 ARGS`` to completion (``stdin`` is what it reads on standard input)."""
    return subprocess.run([ros2_path(), *args], env=cli_env(domain_id), capture_output=True,
                          text=True, timeout=timeout, cwd=cwd, input=stdin)


class Running:
    """A long-running command (echo, hz, a peer) whose output is read as it comes."""

    def __init__(self, args: Sequence[str], *, domain_id: int, log: Path,
                 cwd: Path | None = None) -> None:
        self.log = log
        self._out = open(log, "wb")  # noqa: SIM115 - closed in stop()
        self.proc = subprocess.Popen(list(args), env=cli_env(domain_id), stdout=self._out,
                                     stderr=subprocess.STDOUT, start_new_session=True,
                                     cwd=cwd)

    def text(self) -> str:
        return self.log.read_text(errors="replace")

    def wait_for(self, predicate: Callable[[str], bool], timeout: float = 30) -> str:
        """Wait until ``predicate(output so far)``; fails with the output if it never holds."""
        end = time.monotonic() + timeout
        while True:
            text = self.text()
            if predicate(text):
                return text
            if self.proc.poll() is not None:
                raise AssertionError(f"{self.proc.args!r} exited {self.proc.returncode}:\n{text}")
            if time.monotonic() > end:
                raise AssertionError(f"{self.proc.args!r}: timed out; output:\n{text}")
            time.sleep(0.05)

    def stop(self, sig: int = signal.SIGINT, timeout: float = 15) -> int:
        returncode = stop_process_group(self.proc, sig=sig, timeout_s=timeout)
        self._out.close()
        return returncode


@contextmanager
def running(args: Sequence[str], *, domain_id: int, log: Path,
            cwd: Path | None = None) -> Iterator[Running]:
    r = Running(args, domain_id=domain_id, log=log, cwd=cwd)
    try:
        yield r
    finally:
        r.stop()
