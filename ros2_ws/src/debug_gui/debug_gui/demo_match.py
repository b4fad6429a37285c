"""The team match as the GUI demo runs it: ``python -m humanoid_sim.match`` as a process.

debug_gui does not import humanoid_sim (ARCHITECTURE.md, "Layers"): the demo starts the
match as a user would, passes its output through, and learns from the match's first line
(``soccer match: debug_gui --domains 13,14 watches its robots ...``, printed before the
world starts) which DDS domains its robots are in. The match reserves its domains itself,
for as long as it runs, so nothing here plans them twice.

The match runs in a session of its own, so Ctrl-C in the terminal reaches the demo only,
which then stops the match as Ctrl-C would stop it (SIGINT to its process group): the
match stops its processes and prints its report, which comes through here. The match also
ends when the demo's process dies (it exits with its parent).
"""

from __future__ import annotations

import contextlib
import os
import re
import signal
import subprocess
import sys
import threading
from collections.abc import Callable, Sequence

from efficient_comm import exit_with_parent

from .robots import check_domain

#: The match's line naming its robots' domains (humanoid_sim.match's ``watch_line``).
WATCH_LINE = re.compile(r"^soccer match: debug_gui --domains (?P<domains>\d+(?:,\d+)*) ")
#: How long the match may take to stop its processes and print its report.
STOP_TIMEOUT_S = 90.0


class MatchProcess:
    """``python -m humanoid_sim.match ARGS``, its output passed through (a context manager
    that stops it on exit)."""

    def __init__(self, argv: Sequence[str]) -> None:
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "humanoid_sim.match", *argv], stdout=subprocess.PIPE,
            text=True, start_new_session=True, preexec_fn=exit_with_parent)
        self.domains: list[int] | None = None
        self._told = threading.Event()
        self._stopping = False
        self._reader = threading.Thread(target=self._read, daemon=True, name="match output")
        self._reader.start()

    def _read(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            sys.stdout.write(line)
            sys.stdout.flush()
            found = WATCH_LINE.match(line) if self.domains is None else None
            if found:
                self.domains = [check_domain(int(d)) for d in found["domains"].split(",")]
                self._told.set()
        self._told.set()  # the match ended without saying: wait_for_domains returns None

    def wait_for_domains(self, timeout_s: float) -> list[int] | None:
        """The robots' domains once the match names them; None if it ended (or said
        nothing within ``timeout_s``)."""
        self._told.wait(timeout_s)
        return self.domains

    def on_end(self, callback: Callable[[int], None]) -> None:
        """Call ``callback(returncode)`` (on a thread of its own) when the match ends by
        itself, not when :meth:`stop` ends it."""

        def wait() -> None:
            code = self.proc.wait()
            if not self._stopping:
                callback(code)

        threading.Thread(target=wait, daemon=True, name="match end").start()

    def stop(self) -> int:
        """Stop the match as Ctrl-C does and wait for its report; its exit status.

        A match that has not named its domains yet is still starting (importing, before
        it handles Ctrl-C): SIGTERM ends it quietly then, where Ctrl-C would print a
        traceback."""
        self._stopping = True
        if self.proc.poll() is None:
            how = signal.SIGINT if self.domains is not None else signal.SIGTERM
            with contextlib.suppress(ProcessLookupError):
                os.killpg(self.proc.pid, how)
            try:
                self.proc.wait(timeout=STOP_TIMEOUT_S)
            except subprocess.TimeoutExpired:
                with contextlib.suppress(ProcessLookupError):
                    os.killpg(self.proc.pid, signal.SIGKILL)
                self.proc.wait()
        self._reader.join(timeout=5.0)  # the report's last lines
        return self.proc.returncode

    def __enter__(self) -> MatchProcess:
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()
