"""The demo: the example pipeline composed in one container, with live statistics.

    python -m efficient_comm.examples.demo --duration 10

Loads ``demo.yaml`` (or ``--config``), runs the components on the consecutive executor and
prints every ``--stats-period`` seconds what each callback costs and how often it runs,
then a summary. With DDS on (the default) the pipeline's topics are visible to other
processes (``ros2 topic echo /demo/track``) and the container takes load/unload requests.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from collections.abc import Sequence
from pathlib import Path

from efficient_comm import Container, format_stats, stop_on_sigterm
from efficient_comm.examples.pipeline import Monitor


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="demo", description=__doc__.split("\n\n")[0])
    parser.add_argument("--duration", type=float, default=10.0, help="seconds; 0 = until Ctrl-C")
    parser.add_argument("--config", type=Path, default=Path(__file__).with_name("demo.yaml"))
    parser.add_argument("--strategy", choices=["depth_first", "breadth_first"],
                        default="depth_first")
    parser.add_argument("--no-dds", action="store_true", help="no DDS: nothing leaves the process")
    parser.add_argument("--stats-period", type=float, default=2.0)
    args = parser.parse_args(argv)
    stop_on_sigterm()

    with Container("demo", dds=not args.no_dds, strategy=args.strategy) as container:
        report = container.load_file(args.config)
        for error in report.errors:
            print(f"error: {error}", file=sys.stderr)
        if not report.loaded:
            return 1
        print(f"loaded {', '.join(c.full_node_name for c in report.loaded)} "
              f"({args.strategy}, {'no DDS' if args.no_dds else 'DDS for remote peers'})")
        monitors = [c.instance for c in report.loaded if isinstance(c.instance, Monitor)]
        end = time.monotonic() + args.duration if args.duration > 0 else float("inf")
        try:
            while (left := end - time.monotonic()) > 0:
                container.spin_for(min(args.stats_period, left))
                print(format_stats(container.stats()), flush=True)
        except KeyboardInterrupt:
            pass
        print("\nsummary")
        for monitor in monitors:
            lat = sorted(monitor.latencies_ns) or [0]
            print(f"  tracks received: {monitor.count}; camera->track latency "
                  f"median {statistics.median(lat) / 1e3:.1f} µs, "
                  f"p99 {lat[int(0.99 * (len(lat) - 1))] / 1e3:.1f} µs")
        failures = sum(s.exceptions for s in container.stats())
        print(f"  callback exceptions: {failures}")
        return 0 if all(m.count > 0 for m in monitors) and not failures else 1


if __name__ == "__main__":
    sys.exit(main())
