"""Console scripts: ``recorder`` (the component standalone, recording from the start)."""

from __future__ import annotations

import sys

from efficient_comm import run_standalone as run

from .recorder import Recorder


def record_main() -> int:
    """``recorder --ros-args -p topics:='[/a, /b]' -p output_dir:=/data``: records at once."""
    return run(lambda node: Recorder(node, autostart=True), name="recorder",
               args=sys.argv)


def play_main() -> int:
    """``player BAG [options] [--ros-args ...]``: see :func:`robot_recorder.player.main`."""
    from .player import main

    return main(sys.argv[1:])
