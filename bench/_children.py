"""Benchmark trials in child processes: one JSON task in, one JSON result out.

A trial that shares a process with the ones before it inherits their heap, their threads
and MuJoCo's caches; a fresh process per trial keeps trials independent (and lets them run
in parallel). The bench script is its own child: ``SCRIPT --child TASK`` must print the
result as its last line of output.
"""

from __future__ import annotations

import json
import subprocess
import sys
from typing import Any


def run_child(script: str, task: dict[str, Any], *, name: str) -> dict[str, Any]:
    """Run ``task`` (a dict with a ``kind``) in ``python SCRIPT --child``; its result.

    A failing child ends the benchmark with its error output: a figure measured on a
    trial that crashed would be a wrong figure.
    """
    out = subprocess.run([sys.executable, script, "--child", json.dumps(task)],
                         capture_output=True, text=True, check=False)
    if out.returncode != 0:
        raise SystemExit(f"{name}: a {task['kind']} run failed:\n{out.stderr[-2000:]}")
    result: dict[str, Any] = json.loads(out.stdout.strip().splitlines()[-1])
    return result
