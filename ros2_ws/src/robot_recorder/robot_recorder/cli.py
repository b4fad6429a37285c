"""Console scripts: ``recorder`` (the component standalone) and ``player``."""

from __future__ import annotations

import argparse
import sys

from rclpy.utilities import remove_ros_args

from efficient_comm import NodeHandle
from efficient_comm import run_standalone as run

from .recorder import Recorder

RECORD_HELP = """\
Record topics into MCAP bags (rosbag2 layout) as a standalone node; everything is set
with ROS parameters after --ros-args:

  recorder --ros-args -p topics:="['/chatter', '/image max_rate_hz=5']" -p output_dir:=/data

It records from the start unless -p autostart:=false (then ~/start begins); ~/stop,
~/split, ~/snapshot and ~/set_topics control it, ~/status reports. A topic entry is
"NAME [TYPE] [max_rate_hz=R] [every_nth=N]". Other parameters: docs/RECORDER.md.
"""


def record_main(argv: list[str] | None = None) -> int:
    """``recorder --ros-args -p topics:='[/a, /b]' -p output_dir:=/data``."""
    argv = list(sys.argv if argv is None else argv)
    parser = argparse.ArgumentParser(prog="recorder", description=RECORD_HELP,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.parse_args(remove_ros_args(argv)[1:])  # --help, or refuse what is not a ROS arg
    return run(recorder, name="recorder", args=argv)


def recorder(node: NodeHandle) -> Recorder:
    """The command's recorder: it records at once unless ``-p autostart:=false``."""
    return Recorder(node, autostart=node.declare_parameter("autostart", True))


def play_main() -> int:
    """``player BAG [options] [--ros-args ...]``: see :func:`robot_recorder.player.main`."""
    from .player import main

    return main(sys.argv[1:])
