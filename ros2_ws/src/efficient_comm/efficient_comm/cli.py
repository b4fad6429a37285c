"""Console scripts: ``container`` (a component container) and ``standalone`` (one node)."""

from __future__ import annotations

import argparse
import contextlib
import sys
from collections.abc import Sequence

from rclpy.utilities import remove_ros_args

from ._signals import stop_on_sigterm
from .container import Container
from .dds import prepare_process
from .errors import ConfigError
from .standalone import cli as standalone


def container(argv: Sequence[str] | None = None) -> int:
    """``container [--config FILE ...] [--name NAME] [--strategy S] [--no-dds]
    [--stats-period S] [--stats-namespace NS] [--sim-time | --lockstep NAME]
    [--clock-offset S]``."""
    argv = list(sys.argv if argv is None else argv)
    parser = argparse.ArgumentParser(
        prog="container", description="Run components from container files in one process."
    )
    parser.add_argument("--config", action="append", default=[], help="container YAML file")
    parser.add_argument("--name", default="container", help="the container's node name")
    parser.add_argument("--namespace", default="/")
    parser.add_argument("--strategy", choices=["depth_first", "breadth_first"],
                        default="depth_first")
    parser.add_argument("--no-dds", action="store_true")
    parser.add_argument("--stats-period", type=float, default=1.0, metavar="S",
                        help="seconds between callback statistics on "
                        "<stats namespace>/efficient_comm/stats (0: none; default 1)")
    parser.add_argument("--stats-namespace", default="/", metavar="NS",
                        help="namespace of the statistics topic, i.e. the robot (default /)")
    time = parser.add_mutually_exclusive_group()
    time.add_argument("--sim-time", action="store_true",
                      help="follow /clock from another process (a simulator)")
    time.add_argument("--lockstep", metavar="NAME",
                      help="run in lockstep with the simulator as participant NAME")
    time.add_argument("--clock-offset", type=float, default=0.0, metavar="S",
                      help="run on the system clock shifted by S seconds (a computer of its own)")
    args = parser.parse_args(remove_ros_args(argv)[1:])
    prepare_process(prompt_acks=args.sim_time or args.lockstep is not None)
    stop_on_sigterm()
    # Ctrl-C or SIGTERM at any point (even while loading) unloads what was loaded.
    try:
        c = Container(
            args.name, namespace=args.namespace, dds=not args.no_dds, strategy=args.strategy,
            args=argv, stats_period_s=args.stats_period, stats_namespace=args.stats_namespace,
            sim_time=args.sim_time, lockstep=args.lockstep, clock_offset_s=args.clock_offset,
        )
    except ConfigError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    with contextlib.suppress(KeyboardInterrupt), c:
        for path in args.config:
            report = c.load_file(path)
            for loaded in report.loaded:
                c.logger.info(f"loaded {loaded.class_path} as {loaded.full_node_name}")
        c.spin()
    return 0


__all__ = ["container", "standalone"]
