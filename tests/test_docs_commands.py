"""Every shell line of README.md and docs/*.md runs as written after ``source scripts/env.sh``.

Each ```bash block is one test: its commands (``\\``-continued lines joined, comments
dropped) run one after another in a temporary copy-by-symlink of the repository, on an
isolated DDS domain, each within 60 s, and must exit 0 without a traceback. ```yaml blocks
(or any block) marked ``file=NAME`` are written there first; ``export``, ``cd`` and
``source`` lines apply to the block's later commands, as in one shell. An HTML comment on
the line before a block changes that (the docs then say in words what else it needs):

* ``<!-- doc-test: skip reason="..." -->``: not run (root, a regular ROS 2 install, minutes
  of running time);
* ``<!-- doc-test: runs-until-stopped -->``: each command passes if it is still running,
  without a traceback or ``error:``, after 5 s;
* ``<!-- doc-test: background -->``: the first command runs in the background (a peer the
  others talk to) for the rest of the block;
* ``<!-- doc-test: file=NAME -->`` before a yaml (or python ...) block: write it as NAME.
"""

from __future__ import annotations

import contextlib
import re
import subprocess
import time
from dataclasses import dataclass, field
from pathlib import Path

import pytest

from efficient_comm.testing import isolated_domain_id, stop_process_group

from ._cli import ROOT, cli_env

DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
_DIRECTIVE = re.compile(r"<!--\s*doc-test:\s*(.*?)\s*-->")
RUN_S = 60.0
STOPPED_AFTER_S = 5.0


@dataclass
class Block:
    doc: Path
    line: int
    commands: list[str]
    directive: str = ""
    files: dict[str, str] = field(default_factory=dict)

    @property
    def id(self) -> str:
        return f"{self.doc.name}:{self.line}"


def _commands(lines: list[str]) -> list[str]:
    out: list[str] = []
    pending = ""
    for raw in lines:
        line = raw.rstrip()
        if not pending and (not line.strip() or line.lstrip().startswith("#")):
            continue
        if line.endswith("\\"):
            pending += line[:-1] + " "
            continue
        out.append((pending + line).strip())
        pending = ""
    return out


def blocks() -> list[Block]:
    found: list[Block] = []
    for doc in DOCS:
        lines = doc.read_text().splitlines()
        files: dict[str, str] = {}
        i = 0
        while i < len(lines):
            fence = re.match(r"^```(\w+)", lines[i])
            if not fence:
                i += 1
                continue
            start = i
            end = next(j for j in range(i + 1, len(lines)) if lines[j].startswith("```"))
            body = lines[start + 1:end]
            match = _DIRECTIVE.search(lines[start - 1]) if start else None
            directive = match.group(1) if match else ""
            if directive.startswith("file="):
                files[directive[len("file="):]] = "\n".join(body) + "\n"
            elif fence.group(1) == "bash":
                found.append(Block(doc, start + 1, _commands(body), directive, dict(files)))
            i = end + 1
    return found


def _sandbox(tmp: Path, files: dict[str, str]) -> Path:
    for entry in ROOT.iterdir():
        if entry.name not in (".git",):
            (tmp / entry.name).symlink_to(entry)
    for name, text in files.items():
        (tmp / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp / name).write_text(text)
    return tmp


def _start(command: str, cwd: Path, env: dict[str, str], log: Path) -> subprocess.Popen[bytes]:
    script = f"source scripts/env.sh >/dev/null && {command}"
    with open(log, "wb") as out:
        return subprocess.Popen(["bash", "-c", script], cwd=cwd, env=env, stdout=out,
                                stderr=subprocess.STDOUT, start_new_session=True)



def _group_states(pgid: int) -> list[str]:
    """The scheduler states (R, S, D, ...) of the processes in process group ``pgid``."""
    states = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        with contextlib.suppress(OSError):
            # pid (comm) state ppid pgrp ...: comm may hold spaces and parentheses.
            fields = stat.read_text().rpartition(")")[2].split()
            if int(fields[2]) == pgid:
                states.append(fields[0])
    return states


#: An rclpy node's log line (``[INFO] [1700000000.123] [name]: ...``).
_NODE_LOGGED = re.compile(r"^\[(INFO|WARN)\] \[[\d.]+\] \[", re.MULTILINE)


def _wait_until_idle(proc: subprocess.Popen[bytes], log: Path) -> None:
    """Wait :data:`STOPPED_AFTER_S`, then until every process the command started has been
    waiting (sleeping, as a started node spins) in most samples for a second, at most
    :data:`RUN_S`: Ctrl-C while Python still imports is a KeyboardInterrupt traceback for any
    program, and a loaded machine imports rclpy for longer than the 5 s an idle one needs.
    A node that has logged is past its imports too: a simulation in real time is never idle
    (the world's command waited the whole minute).
    """
    with contextlib.suppress(subprocess.TimeoutExpired):
        proc.wait(timeout=STOPPED_AFTER_S)
    deadline = time.monotonic() + RUN_S
    while proc.poll() is None and time.monotonic() < deadline:
        if _NODE_LOGGED.search(log.read_text(errors="replace")):
            return
        samples = []
        for _ in range(20):
            samples.append(all(s == "S" for s in _group_states(proc.pid)))
            time.sleep(0.05)  # sampling the scheduler's state: nothing to await
        if sum(samples) >= 16:
            return


def _bad(text: str) -> bool:
    return "Traceback" in text or re.search(r"^error:", text, re.MULTILINE) is not None


@pytest.mark.parametrize("block", blocks(), ids=lambda b: b.id)
def test_doc_block_runs_as_written(block: Block, tmp_path: Path) -> None:
    if block.directive.startswith("skip"):
        pytest.skip(block.directive)
    (tmp_path / "repo").mkdir()
    cwd = _sandbox(tmp_path / "repo", block.files)
    env = cli_env(isolated_domain_id())
    setup = [c for c in block.commands if c.split()[0] in ("export", "cd", "source")]
    commands = [" && ".join([*setup, c]) for c in block.commands if c not in setup]
    background: subprocess.Popen[bytes] | None = None
    try:
        if block.directive == "background":
            background = _start(commands.pop(0), cwd, env, tmp_path / "background.log")
        for n, command in enumerate(commands):
            log = tmp_path / f"cmd{n}.log"
            proc = _start(command, cwd, env, log)
            if block.directive == "runs-until-stopped":
                _wait_until_idle(proc, log)
                still_running = proc.poll() is None
                stop_process_group(proc)
                text = log.read_text(errors="replace")
                assert still_running or proc.returncode == 0, f"{command}\n{text}"
                assert not _bad(text), f"{command}\n{text}"
                continue
            try:
                proc.wait(timeout=RUN_S)
            except subprocess.TimeoutExpired:
                stop_process_group(proc)
                pytest.fail(f"{block.id}: {command} still running after {RUN_S} s:\n"
                            f"{log.read_text(errors='replace')}")
            text = log.read_text(errors="replace")
            assert proc.returncode == 0 and not _bad(text), \
                f"{block.id}: {command} exited {proc.returncode}:\n{text}"
        if background is not None:
            text = (tmp_path / "background.log").read_text(errors="replace")
            assert background.poll() is None, f"background {commands[0]} ended:\n{text}"
    finally:
        if background is not None:
            stop_process_group(background)
