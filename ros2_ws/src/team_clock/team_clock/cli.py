"""``team_clock``: merge robots' logs in reference time, or show a log's clock estimates.

    team_clock merge -o merged/ robotA=logs/a/ robotB=logs/b.mcap [--stamps]
    team_clock offsets logs/a/
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

from .errors import MergeError, TeamClockError
from .merge import RobotLog, merge
from .model import OffsetModel


def _log_arg(text: str) -> RobotLog:
    namespace, sep, path = text.partition("=")
    if not sep:
        return RobotLog(Path(text))
    return RobotLog(Path(path), namespace=namespace)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="team_clock", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="command", required=True)
    m = sub.add_parser("merge", help="merge logs into one MCAP in team reference time")
    m.add_argument("logs", nargs="+", metavar="[ROBOT=]LOG",
                   help="an .mcap file or rosbag2 directory, aligned with ROBOT's recorded "
                        "clock estimates and merged under /ROBOT (default: the robot whose "
                        "estimates it holds)")
    m.add_argument("-o", "--output", required=True, type=Path,
                   help="bag directory to create (or a file ending in .mcap)")
    m.add_argument("--stamps", action="store_true",
                   help="also move header stamps to reference time")
    m.add_argument("--assume-synced", action="append", default=[], metavar="NAMESPACE",
                   help="take this log's clock as the reference (no estimates needed)")
    m.add_argument("--compression", choices=["zstd", "lz4", "none"], default="zstd")
    o = sub.add_parser("offsets", help="print the clock estimates recorded in a log")
    o.add_argument("log", type=Path)
    o.add_argument("--robot", help="whose estimates, when the log holds several robots'")
    args = parser.parse_args(argv)
    try:
        if args.command == "offsets":
            model = OffsetModel.from_mcap(args.log, robot=args.robot)
            print(f"robot {model.robot} reference {model.reference}: {len(model.knots)} estimates")
            for k in model.knots:
                print(f"  local {k.stamp_ns}  offset {k.offset_ns:+d} ns  drift "
                      f"{k.drift_ppm:+.3f} ppm  ±{k.uncertainty_ns} ns  hops {k.hops} "
                      f"via {k.source}")
            return 0
        logs = [_log_arg(text) for text in args.logs]
        named = {log.namespace for log in logs}
        if unknown := sorted(set(args.assume_synced) - named):
            raise MergeError(f"--assume-synced {', '.join(unknown)}: no log given as "
                             "NAMESPACE=LOG under that name")
        logs = [RobotLog(log.path, namespace=log.namespace,
                         model=OffsetModel.identity(robot=log.namespace or ""))
                if log.namespace in args.assume_synced else log for log in logs]
        report = merge(logs, args.output, stamps=args.stamps, compression=args.compression)
    except (TeamClockError, OSError) as exc:
        print(f"team_clock: error: {exc}", file=sys.stderr)
        return 1
    print(f"merged {report.messages} messages into {report.output}")
    for r in report.robots:
        skipped = f", skipped {dict(r.skipped)}" if r.skipped else ""
        truncated = f", truncated files {[str(p) for p in r.truncated_files]}" \
            if r.truncated_files else ""
        stamps = f", stamps moved {r.stamps_moved} left {r.stamps_left}" if args.stamps else ""
        print(f"  /{r.namespace}: {r.messages} messages from {r.path}, offset ±"
              f"{r.max_uncertainty_ns / 1e6:.3f} ms{stamps}{skipped}{truncated}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
