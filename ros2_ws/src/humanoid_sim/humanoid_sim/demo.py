"""The soccer demo: a simulated kid-size humanoid plays: it finds the ball, walks to it and
kicks it towards the opponent goal, again and again, and gets up when it falls.

    python -m humanoid_sim.demo --duration 30

One container holds the simulator (MuJoCo behind emulated Dynamixel servos on a pty), the
servo driver (dynamixel-sdk, unchanged) and the soccer software (camera -> ball detection ->
ball model -> head behaviour and striker -> walk, kick, get-up -> motion arbiter), passing
messages by reference on one thread; a referee (ground truth) counts goals and puts the
ball back on the centre mark. The robot starts at ``--robot-pose``, the ball at
``--ball``; without them ``--seed`` draws the start (:func:`start_positions`); nothing but
the robot moves the ball. Every ``--stats-period`` seconds it prints
rates, tracking error, distance walked, kicks, goals and falls; at the end (after
``--duration`` or on Ctrl-C/SIGTERM) it writes a short Markdown report.

``--namespace`` names the robot (default ``/robot``): its topics, its recorder
(``<ns>/recorder``, idle until its ``~/start`` service is called; bags under ``--bag-dir``)
and its callback statistics (``<ns>/efficient_comm/stats``) live there, so several demo
processes (one robot each, in separate DDS domains and/or namespaces) can be told apart by
a debugging tool such as debug_gui.

``--lockstep`` runs on a manual clock as fast as the machine allows, the same run for the
same ``--seed``; by default the simulation runs in real time. ``--push-at`` pushes the robot
along the field's +x (towards the opponent goal) at that simulated second
(``--push-newtons`` for 0.1 s; 40 N fells it).

``--split`` runs the robot as two processes on this machine: the body (simulator, servo
driver, motions, decisions) here, perception (the ball detector and the JPEG compressor) in
a container process of its own, the camera image crossing through shared memory
(``--split dds``: over DDS, for comparison); see :mod:`humanoid_sim.split`.

``--video match.mp4`` also films the field from above into an MP4 on a camera clock of its
own (:mod:`humanoid_sim.match_video`: ``match.mp4.json`` beside it), for offline analysis.

A bad argument is refused with one line and exit status 2 (:class:`DemoArguments`).

Exit status: 0 the robot played (falls it got up from included); 1 a bug (the ball was
never detected, a callback raised, or the servo bus emulator raised); 3 the robot fell and
was still down at the end, with no bug.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from pathlib import Path

from .arguments import (
    EXIT_BUG,
    EXIT_FELL,
    EXIT_OK,
    EXIT_USAGE,
    KICK_OFF_BALL,
    KICK_OFF_POSE,
    TRANSPORTS,
    DemoArguments,
    field_position,
    finite_number,
    namespace_arg,
    start_positions,
)
from .soccer.pose_sources import SOURCES

__all__ = ["EXIT_BUG", "EXIT_FELL", "EXIT_OK", "EXIT_USAGE", "KICK_OFF_BALL", "KICK_OFF_POSE",
           "main", "start_positions"]


def main(argv: Sequence[str] | None = None) -> int:
    parser = DemoArguments(prog="soccer_demo", description=__doc__.split("\n\n")[0],
                           epilog="A team match instead: scripts/demo.sh --robots 3 (or 2, "
                           "AvB such as 3v3); python -m humanoid_sim.match --help.")
    parser.add_argument("--duration", type=finite_number(low=0, what="seconds >= 0"), default=30.0,
                        help="simulated seconds in lockstep, wall seconds otherwise; "
                        "0 = until Ctrl-C (default 30)")
    parser.add_argument("--lockstep", action="store_true",
                        help="manual clock, as fast as possible, deterministic")
    parser.add_argument("--seed", type=int, default=0,
                        help="the start (unless --robot-pose and --ball are given; 0 is the "
                        "kick-off) and the line noise's pattern (default 0)")
    parser.add_argument("--robot-pose", type=field_position(3, "X,Y,HEADING"), default=None,
                        metavar="X,Y,HEADING",
                        help="where the robot starts on the field (m, m, rad; x towards the "
                        "opponent goal, origin the centre mark, e.g. -1,0.5,0); "
                        "default: from --seed")
    parser.add_argument("--ball", type=field_position(2, "X,Y"), default=None, metavar="X,Y",
                        help="where the ball starts (m; 0,0 is the centre mark); "
                        "default: from --seed")
    parser.add_argument("--line-noise", type=finite_number(low=0, high=1, high_open=True,
                                                     what="a share 0 <= p < 1"),
                        default=0.0, help="share of servo bus packets (either way) with a "
                        "flipped bit, 0 <= p < 1 (default 0)")
    parser.add_argument("--no-dds", action="store_true", help="no DDS: nothing leaves the process")
    parser.add_argument("--stats-period", type=finite_number(low=0, what="seconds >= 0"),
                        default=2.0, help="seconds between the printed live lines; 0 = none "
                        "(default 2)")
    parser.add_argument("--namespace", type=namespace_arg, default="/robot",
                        help="the robot's namespace (default /robot)")
    parser.add_argument("--bag-dir", type=Path, default=None,
                        help="where the robot's recorder writes bags "
                        "(default recordings/<namespace>)")
    parser.add_argument("--record", action="store_true",
                        help="record from the start (into --bag-dir), not only when a viewer "
                        "starts the recorder; log_analysis reads the bag afterwards")
    parser.add_argument("--report", type=Path, default=Path("soccer_report.md"))
    parser.add_argument("--video", type=Path, default=None, metavar="MP4",
                        help="also film the field from above into this MP4 (a sidecar "
                        "MP4.json beside it), on a camera clock 2.5 s off the world's")
    parser.add_argument("--push-at", type=finite_number(low=0, what="simulated seconds >= 0"),
                        default=0.0, metavar="SECONDS",
                        help="push the robot along +x of the field (towards the opponent "
                        "goal) at this simulated time (0: never)")
    parser.add_argument("--localization", choices=(*SOURCES, "none"), default="none",
                        help="the robot's localization/pose: the particle filter, noisy "
                        "ground truth standing in, or none (default); the report gives its "
                        "error against ground truth")
    parser.add_argument("--split", nargs="?", const="shm", choices=TRANSPORTS, default=None,
                        help="run perception (ball detector, JPEG compressor) in a process of "
                        "its own, the camera image crossing through shared memory (shm, the "
                        "default) or DDS (dds); real time with DDS only")
    parser.add_argument("--push-newtons", type=finite_number(low=0, what="newtons >= 0"),
                        default=40.0, help="force of that push, for 0.1 s (default 40)")
    args = parser.parse_args(argv)
    if args.split and (args.lockstep or args.no_dds):
        parser.error(f"--split runs two processes in real time: not with "
                     f"{'--lockstep' if args.lockstep else '--no-dds'} (the demo's "
                     f"lockstep is one process on a manual clock; without DDS the "
                     f"processes cannot meet)")
    # The simulation is imported once the arguments are known good (see .arguments).
    from ._demo_run import run

    return run(args, parser)


if __name__ == "__main__":
    sys.exit(main())
