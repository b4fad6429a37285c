"""The team match as the tests start it: the command as a user types it
(``python -m humanoid_sim.match ...``) on domains of its own, its output read as it comes.

:class:`MatchProcess` is what every match test shares: it starts the match in a process
group of its own, reads its stdout (stderr joined) in a thread so that the match never
blocks on a full pipe (several matches side by side once stopped printing their live lines
while the test waited on another), waits for a line with a timeout that says what was seen
instead, and stops the whole group on the way out. :func:`report_rows` reads the report's
table of robots.
"""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Sequence
from pathlib import Path
from types import TracebackType

from efficient_comm.testing import isolated_domain_id, ros_env, stop_process_group

#: How many of the last lines an error shows.
SHOWN_LINES = 60


class MatchProcess:
    """``python -m humanoid_sim.match *args`` in ``cwd``, on a domain reserved for it.

    Use it as a context manager: leaving the block stops the match's process group
    (SIGINT, then SIGKILL), whatever happened in it. :meth:`until` waits for the next line
    that matches, in the order the lines came (each call goes on after the line the previous
    one matched); :meth:`output` is everything read so far.
    """

    def __init__(self, args: Sequence[str], *, cwd: Path) -> None:
        self.args = list(args)
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "humanoid_sim.match", *self.args],
            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
            env=ros_env(isolated_domain_id()), start_new_session=True, cwd=cwd)
        self.lines: list[str] = []
        self._read = 0  # lines :meth:`until` has looked at
        self._changed = threading.Condition()
        self._eof = False
        self._reader = threading.Thread(target=self._read_lines, daemon=True,
                                        name="match stdout")
        self._reader.start()

    def __enter__(self) -> MatchProcess:
        return self

    def __exit__(self, kind: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.stop()

    def _read_lines(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            with self._changed:
                self.lines.append(line)
                self._changed.notify_all()
        self.proc.stdout.close()  # read to its end (left open, the pipe warns when collected)
        with self._changed:
            self._eof = True
            self._changed.notify_all()

    def until(self, pattern: str, timeout_s: float) -> re.Match[str]:
        """The next line (after the one the last call matched) that ``pattern`` matches
        (``re.search``), waiting up to ``timeout_s``; AssertionError with the last lines
        seen if it does not come, or the match ends first."""
        compiled = re.compile(pattern)
        deadline = time.monotonic() + timeout_s
        with self._changed:
            while True:
                while self._read < len(self.lines):
                    self._read += 1
                    if m := compiled.search(self.lines[self._read - 1]):
                        return m
                left = deadline - time.monotonic()
                if self._eof or left <= 0:
                    why = "the match ended" if self._eof else f"{timeout_s:g} s passed"
                    raise AssertionError(f"no {pattern!r} ({why}) in:\n" + self.tail())
                self._changed.wait(left)

    def output(self) -> str:
        """Every line read so far."""
        with self._changed:
            return "".join(self.lines)

    def tail(self, lines: int = SHOWN_LINES) -> str:
        """The last ``lines`` lines read, for an assertion's message."""
        return "".join(self.lines[-lines:])

    def interrupt(self) -> None:
        """Ctrl-C, as a user stops the match: SIGINT to its process group."""
        os.killpg(self.proc.pid, signal.SIGINT)

    def wait(self, timeout_s: float) -> int:
        """The match's exit status once it ended and its output is read to the end."""
        code = self.proc.wait(timeout=timeout_s)
        self._reader.join(timeout=timeout_s)
        return code

    def stop(self) -> int:
        """End the match and every process it started (see :func:`stop_process_group`)."""
        code = stop_process_group(self.proc, timeout_s=30)
        self._reader.join(timeout=30)
        return code


def report_rows(text: str, robots: str = r"(blue|red)\d") -> dict[str, list[str]]:
    """The report's table, a row per robot whose name matches ``robots``: its cells after
    the name (process, role, game state seen, frames / IMU, falls, walked, link bytes, B/s,
    CPU)."""
    return {row.split("|")[1].strip(): [cell.strip() for cell in row.split("|")[2:-1]]
            for row in text.splitlines() if re.match(rf"^\| {robots} ", row)}
