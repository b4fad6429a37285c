"""The match's merged log: every robot's on-board bag and the world's ground truth, in one time.

Each robot records on its own clock with its clock estimates (team_clock's ``ClockSync``
and the recorder, docs/TEAM_CLOCK.md); the world records the ground truth on the world's
(simulated) clock. team_clock's :func:`~team_clock.merge` already aligns logs by their
recorded estimates; what a match adds is the world's log, which usually holds none: the
world's clock is the team's reference (the robots synchronise to it, as to ``/clock`` in
ROS), and a reference measures nothing. So the world's log is merged on the identity with
the world named as the reference, and a robot aligned to another reference is refused
rather than merged by a wrong offset. A world that ran a ``ClockSync`` of its own (as a
client of a robot, say) has recorded estimates, and those are used instead.

    match_log -o merged/ --world logs/world blue1=logs/blue1 red1=logs/red1

Everything lands under its namespace (``/blue1/...``, ``/world/ground_truth/ball``), and
header stamps are moved to the reference time as well (``--no-stamps`` leaves them).
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Collection, Mapping, Sequence
from pathlib import Path

from team_clock import MergeReport, NoEstimateError, OffsetModel, RobotLog, TeamClockError, merge

__all__ = ["WORLD", "main", "merge_match"]

#: The world's name as the team's clock reference and its namespace in the merged log.
WORLD = "world"


def merge_match(
    robots: Mapping[str, str | os.PathLike[str]],
    world: str | os.PathLike[str],
    output: str | os.PathLike[str],
    *,
    world_name: str = WORLD,
    stamps: bool = True,
    on_world_time: Collection[str] = (),
) -> MergeReport:
    """Merge ``robots`` (name -> bag) and the ``world``'s ground-truth bag into ``output``.

    ``on_world_time``: robots whose clock is the world's (a lockstep match: every process
    on the world's simulated time), merged as they are, estimates or not.

    Raises team_clock's errors (a :class:`~team_clock.TeamClockError`): a robot's bag
    without estimates, robots aligned to another reference than the world, an existing
    output.
    """
    try:
        world_model = OffsetModel.from_mcap(world, robot=world_name)
    except NoEstimateError:
        world_model = OffsetModel.identity(robot=world_name, reference=world_name)
    logs = [RobotLog(Path(world), namespace=world_name, model=world_model)]
    logs += [RobotLog(Path(path), namespace=name,
                      model=OffsetModel.identity(robot=name, reference=world_name)
                      if name in on_world_time else None)
             for name, path in robots.items()]
    return merge(logs, output, stamps=stamps)


def _robot_arg(text: str) -> tuple[str, Path]:
    name, sep, path = text.partition("=")
    if not sep or not name or not path:
        raise argparse.ArgumentTypeError(f"{text!r}: a robot's bag is ROBOT=BAG")
    return name, Path(path)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="match_log", description="Merge a match's robot bags and the world's ground "
        "truth into one MCAP in the world's time.")
    parser.add_argument("robots", nargs="+", type=_robot_arg, metavar="ROBOT=BAG",
                        help="a robot's bag (directory or .mcap) with its clock estimates")
    parser.add_argument("--world", required=True, type=Path,
                        help="the world's ground-truth bag")
    parser.add_argument("--world-name", default=WORLD,
                        help="the world's name as the robots' clock reference (default: world)")
    parser.add_argument("-o", "--output", required=True, type=Path,
                        help="bag directory to create (or a file ending in .mcap)")
    parser.add_argument("--no-stamps", action="store_true",
                        help="leave header stamps on each robot's own clock")
    args = parser.parse_args(argv)
    robots = dict(args.robots)
    if len(robots) != len(args.robots):
        parser.error("a robot is named twice")
    try:
        report = merge_match(robots, args.world, args.output, world_name=args.world_name,
                             stamps=not args.no_stamps)
    except (TeamClockError, OSError) as exc:
        print(f"match_log: error: {exc}", file=sys.stderr)
        return 1
    print(f"merged {report.messages} messages into {report.output}")
    for r in report.robots:
        print(f"  /{r.namespace}: {r.messages} messages from {r.path}, offset ±"
              f"{r.max_uncertainty_ns / 1e6:.3f} ms")
    return 0


if __name__ == "__main__":
    sys.exit(main())
