r"""The command line: ``events`` and ``sync-video`` (``ros2 run log_analysis <command>``).

``events``: find the events of a team log and write them beside it.

    ros2 run log_analysis events merged_20261126_120000/
    ros2 run log_analysis events blue1_bag/ --robot blue1 --only falls ball_lost
    ros2 run log_analysis events LOG --generators my_generators.py -o LOG.events.mcap
    ros2 run log_analysis events blue1=bags/blue1/ red1=bags/red1/ -o team.events.mcap

Several robots' own bags are read as one team log in team reference time, each moved by
the clock estimates it recorded (team_clock; ``ROBOT=LOG`` as its merge takes them), without
merging them first. Prints one line per event (seconds from the log's start, robot, what,
details), writes them to a sidecar MCAP (``<log>.events.mcap``, for several bags
``team.events.mcap`` beside the first, unless ``-o``; a partial run, with ``--only``,
``--robot``, ``--start`` or ``--end``, to ``<log>.partial.events.mcap``, leaving the full
one as it was) as Foxglove events, and shows
its progress on standard error. A generator that raises is named with what it raised and
the others finish; the exit status is then 1. A log or generator file that cannot be read
is one line and exit 1; wrong arguments exit 2.

``sync-video``: fit an external video's clock to a log's and write the fit beside the video.

    ros2 run log_analysis sync-video match/merged_20261126_120000/ match/video_20261126_120000.mp4
    ros2 run log_analysis sync-video LOG VIDEO --anchor 12.4=10.0 --anchor 95.1=92.6

From the ball's motion (log_analysis.sync explains how) or, with ``--anchor``, from moments
picked by hand (``CAMERA=LOG``: seconds since the video's first frame and since the log's
start). Prints offset, drift and residual (also in frames) and writes ``<video>.sync.json``
(``-o`` to choose), which the offline tools read to put the video on the log's time.

``augment``: the video with every robot's beliefs drawn in, event captions and a timeline.

    ros2 run log_analysis augment match/merged_20261126_120000/ match/video_20261126_120000.mp4

Reads the fit of ``sync-video`` (``VIDEO.sync.json``; fits it first when there is none)
and the events of ``events`` (``LOG.events.mcap``, when there), and writes
``VIDEO.augmented.mp4`` (``-o`` to choose).

``compare``: two variants of a component replayed on one robot's images of a log (A/B).

    ros2 run log_analysis compare LOG --robot blue1 \
        --a colour=humanoid_sim::BallDetector --b blob=humanoid_sim::BlobBallDetector \
        --set b.min_fill=0.5 -o report/

Writes ``report/report.md`` (figures, plots, the worst disagreements) and
``report/disagreements.events.mcap`` (those frames as events), and prints the table.

Every command that reads a whole log or video (``events``, the ball-track fit of
``sync-video``, ``augment``, ``compare``) shows its progress on standard error: redrawn in
place on a terminal, a line per tenth elsewhere, always ending at 100 % on a finished line;
``--quiet`` turns it off.
"""

from __future__ import annotations

import argparse
import math
import re
import sys
import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Any, TextIO

from .errors import LogAnalysisError

# Each command imports what it uses when it runs: the four share this module, and each
# importing all of them (video decoding, replaying components, rclpy) cost every command
# 0.6 s before it read its first argument.
if TYPE_CHECKING:
    from team_clock import RobotLog

    from .source import TeamLog

__all__ = ["augment_main", "compare_main", "events_main", "sync_video_main"]


def _first_sentence(doc: str) -> str:
    """A docstring's first sentence on one line (``--list``: not cut mid-sentence at the
    first line's end)."""
    paragraph = " ".join(doc.strip().split("\n\n", 1)[0].split())
    match = re.match(r"(.+?\.)(\s|$)", paragraph)
    return (match.group(1) if match else paragraph).replace("``", "")


def _help_of(command: str) -> str:
    """The part of this module's help that is about ``command`` (and the closing paragraph
    every command shares): ``events --help`` shows no other command's examples."""
    text, _, shared = (__doc__ or "").partition("Every command that reads")
    parts = re.split(r"^(?=``[a-z-]+``: )", text, flags=re.MULTILINE)
    mine = "".join(p for p in parts if p.startswith(f"``{command}``: ")).strip()
    return f"{mine}\n\nEvery command that reads{shared}".rstrip() if shared else mine


def _seconds(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number of seconds: {text!r}") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"not a number of seconds: {text!r}")
    if value < 0:
        raise argparse.ArgumentTypeError(f"seconds from the log's start, >= 0: {text!r}")
    return value


def _writable(path: Path | None) -> None:
    """Refuse, before any work, an output that cannot be written: a directory, or one in
    a directory that does not exist."""
    if path is None:
        return
    if path.is_dir():
        raise LogAnalysisError(f"-o {path} is a directory: give the file to write")
    if not path.parent.is_dir():
        raise LogAnalysisError(f"-o {path}: no directory {path.parent}")


def progress_printer(total: int, start: int, *, stream: TextIO = sys.stderr,
                     label: str = "events", unit: str = "s of log", scale: float = 1e-9
                     ) -> Callable[[int], None]:
    """A progress line for ``[start, start + total]`` (log time in ns, or frames with
    ``unit="frames", scale=1``): redrawn in place on a terminal, a line per tenth elsewhere
    (a CI log)."""
    tty = stream.isatty()
    shown = [-1]
    began = time.monotonic()

    def show(reached: int) -> None:
        done = min(1.0, max(0.0, (reached - start) / total)) if total > 0 else 1.0
        step = int(done * 100 if tty else done * 10)
        if step == shown[0]:
            return
        shown[0] = step
        bar = "#" * int(done * 30)
        line = (f"{label}: [{bar:<30}] {done:4.0%} of {total * scale:.{1 if scale < 1 else 0}f} "
                f"{unit} in {time.monotonic() - began:.1f} s")
        stream.write(f"\r{line}" if tty else f"{line}\n")
        stream.flush()

    return show


@contextmanager
def progress_line(total: int, start: int, *, quiet: bool, label: str, unit: str = "s of log",
                  scale: float = 1e-9) -> Iterator[Callable[[int], None] | None]:
    """A :func:`progress_printer` for one piece of work (``None`` when ``quiet``) that
    ends cleanly: at 100 % and a finished line when the work is done, and on a terminal a
    finished line also when it failed, so that the error is a line of its own."""
    if quiet:
        yield None
        return
    printer = progress_printer(total, start, label=label, unit=unit, scale=scale)
    shown = False

    def show(reached: int) -> None:
        nonlocal shown
        shown = True
        printer(reached)

    try:
        yield show
        show(start + total)
    finally:
        if shown and sys.stderr.isatty():
            sys.stderr.write("\n")
            sys.stderr.flush()


def events_main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="events", description=_help_of("events"),
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("log", nargs="*", metavar="[ROBOT=]LOG", help="a merged team log "
                        "or one robot's bag (rosbag2 directory or .mcap file); or several "
                        "robots' own bags, put on the team's time by the clock estimates "
                        "each recorded (team_clock), each under ROBOT (default: the robot "
                        "whose estimates it holds)")
    parser.add_argument("--generators", type=Path, action="append", default=[],
                        metavar="FILE", help="a Python file whose GENERATORS list more "
                        "event generators (may repeat)")
    parser.add_argument("--only", nargs="+", metavar="NAME", help="run only these "
                        "generators: built-in, registered or of --generators files (none: "
                        "all); --list names the registered ones")
    parser.add_argument("--list", action="store_true", help="list the registered "
                        "generators and exit")
    parser.add_argument("--robot", help="only this robot's part: its topics (under "
                        "/ROBOT/) of a merged log or of its own bag recorded in its namespace; "
                        "a bag recorded without a namespace is read as ROBOT's")
    parser.add_argument("--start", type=_seconds, help="from this many seconds after the "
                        "log's start")
    parser.add_argument("--end", type=_seconds, help="up to this many seconds after the "
                        "log's start")
    parser.add_argument("-o", "--output", type=Path, help="the sidecar MCAP to write "
                        "(default: LOG.events.mcap beside the log)")
    parser.add_argument("--quiet", action="store_true", help="no progress line")
    args = parser.parse_args(argv)
    from .events import detect, generator_name
    from .registry import available_generators, load_generators
    from .sidecar import write_events
    from .source import TeamLog
    try:
        if args.list:
            for name, factory in sorted(available_generators().items()):
                print(f"{name:20} {_first_sentence(factory.__doc__ or '')}")
            return 0
        if not args.log:
            parser.error("give the LOG to analyse (or --list)")
        team = len(args.log) > 1 or (not Path(args.log[0]).exists() and "=" in args.log[0])
        if team and args.robot:
            parser.error("--robot names the robot of one bag; with several, give each as "
                         "ROBOT=LOG")
        if args.start is not None and args.end is not None and args.end <= args.start:
            parser.error(f"--end {args.end} is not after --start {args.start}")
        _writable(args.output)
        generators = load_generators(files=args.generators)
        if args.only:
            by_name = {generator_name(g): g for g in generators}
            if unknown := [n for n in args.only if n not in by_name]:
                parser.error(f"unknown event generator(s) {', '.join(unknown)}; known: "
                             f"{', '.join(sorted(by_name))}")
            generators = [by_name[n] for n in dict.fromkeys(args.only)]
        log = (TeamLog.from_robot_logs([_robot_log(text) for text in args.log]) if team
               else TeamLog(args.log[0], robot=args.robot))
        first, last = log.time_range()
        # Warned of: a generator asked for by name or from a file that reads nothing (a
        # typo); not a built-in that runs by default on a log without its topics.
        builtin = set(available_generators()) - set(args.only or ())
        unread = _unread_topics(log, generators, robot=args.robot, quiet_for=builtin)
        start_ns = None if args.start is None else first + int(args.start * 1e9)
        end_ns = None if args.end is None else first + int(args.end * 1e9)
        lo, hi = start_ns or first, min(end_ns or last, last)
        if hi <= lo and (start_ns is not None or end_ns is not None):
            unread.append(f"the window {args.start or 0:g}..{args.end or 'end'} s holds "
                          f"none of the log: the log spans 0..{(last - first) / 1e9:.1f} s")
        with progress_line(max(hi - lo, 0), lo, quiet=args.quiet,
                           label="events") as progress:
            found = detect(log, generators, start_ns=start_ns, end_ns=end_ns,
                           progress=progress)
        filters = [flag for flag, used in (("--only", args.only), ("--robot", args.robot),
                                           ("--start", args.start is not None),
                                           ("--end", args.end is not None)) if used]
        full = _default_sidecar(log.path, team=team)
        output = args.output or _default_sidecar(log.path, team=team, partial=bool(filters))
        write_events(output, found.events)
    except LogAnalysisError as exc:
        print(f"events: error: {exc}", file=sys.stderr)
        return 1
    for problem in found.problems + unread:
        print(f"events: warning: {problem}", file=sys.stderr)
    sys.stderr.flush()
    print(f"{'start':>11}  {'length':>8}  {'robot':8} {'event':20} details")
    for event in found.events:
        span = (event.end_ns - event.start_ns) / 1e9
        print(f"{(event.start_ns - first) / 1e9:9.2f} s  {span:6.2f} s  "
              f"{event.robot or 'team':8} {event.name:20} {event.description}")
    print(f"{len(found.events)} events from {len(generators)} generators over "
          f"{found.messages} messages; written to {output}"
          + (f" (partial: {' '.join(filters)}; {full} is left as it was)"
             if filters and not args.output else ""))
    for name, failure in found.failures.items():
        print(f"events: error: generator {name} failed and was left out: {failure}",
              file=sys.stderr)
    return 1 if found.failures else 0


def _default_sidecar(path: Path, *, team: bool, partial: bool = False) -> Path:
    """``LOG.events.mcap`` beside the log (beside its folder for a file of a rosbag2
    folder, so that the bag stays as the recorder made it); ``team.events.mcap`` beside the
    first of several bags."""
    from .sidecar import sidecar_path

    if team:
        return sidecar_path(path.parent / "team", partial=partial)
    if path.is_file() and (path.parent / "metadata.yaml").is_file():
        path = path.parent
    return sidecar_path(path, partial=partial)


def _unread_topics(log: TeamLog, generators: Sequence[Any], *, robot: str | None,
                   quiet_for: set[str]) -> list[str]:
    """Warnings for generators that read no topic of ``log``; a :class:`LogAnalysisError`
    when none does (an analysis over no message would say nothing happened)."""
    from .events import generator_name
    from .source import TeamLog

    missing = {generator_name(g): sorted(g.topics) for g in generators
               if not log.names(g.topics)}
    if not missing:
        return []
    # With --robot, the robots of the log as it is (not as read for that robot).
    robots = ", ".join((TeamLog(log.path) if robot else log).robots) or "none"
    whose = f"robot {robot}" if robot else "any robot"
    if len(missing) == len(generators):
        wanted = sorted({t for topics in missing.values() for t in topics})
        raise LogAnalysisError(f"no topic of {log.path} is one the generators read "
                               f"({', '.join(wanted)}) for {whose}: the log's robots are "
                               f"{robots}")
    nobody = f"robot {robot} did not log" if robot else "no robot logged"
    return [f"{name} reads {', '.join(topics)}, which {nobody} (the log's robots: "
            f"{robots}): it finds nothing" for name, topics in missing.items()
            if name not in quiet_for]


def _robot_log(text: str) -> RobotLog:
    """``ROBOT=LOG`` or ``LOG``, as team_clock's merge takes them."""
    from team_clock import RobotLog

    robot, sep, path = text.partition("=")
    return RobotLog(Path(path), namespace=robot) if sep else RobotLog(Path(text))


def _anchor(text: str) -> tuple[float, float]:
    camera, sep, log = text.partition("=")
    try:
        if not sep:
            raise ValueError
        return float(camera), float(log)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"an anchor is CAMERA=LOG in seconds (since the video's first frame and the "
            f"log's start), not {text!r}") from None


def sync_video_main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="sync-video", description=_help_of("sync-video"),
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    from .sync import MAX_DRIFT_PPM

    parser.add_argument("log", type=Path, help="the (merged) log the video goes with")
    parser.add_argument("video", type=Path,
                        help="the video (its sidecar VIDEO.json gives its clock and "
                        "calibration; a video without one is fitted with --anchor only)")
    parser.add_argument("--ball-topic", default="/world/ground_truth/ball",
                        help="where the log has the ball (PointStamped, PoseStamped or "
                        "PoseWithCovarianceStamped in the field frame, e.g. /ROBOT/team_ball; "
                        "default: the world's ground truth)")
    parser.add_argument("--max-offset", type=_seconds, default=30.0, metavar="S",
                        help="search the offset within ±S seconds of lining up the starts "
                        "(default: 30)")
    parser.add_argument("--anchor", type=_anchor, action="append", default=[],
                        metavar="CAMERA=LOG", help="a moment picked by hand (may repeat); "
                        "fits on these instead of the ball")
    parser.add_argument("--allow-drift", action="store_true", help="keep a drift beyond "
                        f"±{MAX_DRIFT_PPM:g} ppm (a camera's clock drifts by tens)")
    parser.add_argument("-o", "--output", type=Path, help="where to write the fit (default: "
                        "VIDEO.sync.json)")
    parser.add_argument("--quiet", action="store_true", help="no progress line")
    args = parser.parse_args(argv)
    from .source import TeamLog
    from .sync import check_fit, fit_anchors, fit_video_clock
    from .video import ExternalVideo
    try:
        _writable(args.output)
        video = ExternalVideo(args.video)
        log = TeamLog(args.log)
        if args.anchor:
            first = log.time_range()[0]
            fit = fit_anchors([(video.start_ns + round(c * 1e9), first + round(t * 1e9))
                               for c, t in args.anchor], start_ns=video.start_ns,
                              frame_period_ns=video.frame_period_ns)
        else:
            with progress_line(int(video.sidecar.get("frames") or 0), 0, quiet=args.quiet,
                               label="sync-video", unit="frames", scale=1) as show:
                fit = fit_video_clock(log, video, ball_topic=args.ball_topic,
                                      max_offset_s=args.max_offset, progress=show)
        check_fit(fit, allow_drift=args.allow_drift)
        output = fit.on_log(log).save(args.output or Path(f"{args.video}.sync.json"))
    except LogAnalysisError as exc:
        print(f"sync-video: error: {exc}", file=sys.stderr)
        return 1
    frames = f" ({fit.residual_frames:.2f} frames)" if fit.frame_period_ns else ""
    print(f"offset {fit.offset_ns / 1e9:+.3f} s  {fit.describe_drift()}  residual "
          f"{fit.residual_ns / 1e6:.1f} ms{frames}  from the {fit.method}"
          + (f" ({len(fit.stretches)} stretches, {fit.frames_used} frames, "
             f"{fit.pixel_error_px:.1f} px)" if fit.method == "ball track" else
             f" ({len(args.anchor)} anchors)"))
    print(f"written to {output}")
    return 0


def augment_main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="augment", description=_help_of("augment"),
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("log", type=Path, help="the (merged) log the video goes with")
    parser.add_argument("video", type=Path,
                        help="the video with its sidecar VIDEO.json (the calibration to draw with)")
    parser.add_argument("--fit", type=Path, help="the video's clock (default: "
                        "VIDEO.sync.json; fitted from the ball when there is none)")
    parser.add_argument("--events", type=Path, help="events to caption (default: "
                        "LOG.events.mcap when it exists)")
    parser.add_argument("-o", "--output", type=Path,
                        help="the MP4 to write (default: VIDEO.augmented.mp4)")
    parser.add_argument("--quiet", action="store_true", help="no progress line")
    args = parser.parse_args(argv)
    from .augment import augment_video
    from .sidecar import read_events, sidecar_path
    from .source import TeamLog
    from .sync import VideoFit, check_fit, fit_video_clock
    from .video import ExternalVideo
    if args.output is not None and args.output.suffix.lower() != ".mp4":
        parser.error(f"augment writes an MP4 (H.264): -o must end in .mp4, not {args.output}")
    try:
        _writable(args.output)
        video = ExternalVideo(args.video)
        log = TeamLog(args.log)
        fit_path = args.fit or Path(f"{args.video}.sync.json")
        if args.fit is None and not fit_path.exists():
            print(f"augment: no {fit_path}: fitting the video's clock first", file=sys.stderr)
            fit = fit_video_clock(log, video)
            check_fit(fit)
            fit = fit.on_log(log)
            fit.save(fit_path)
        else:
            fit = VideoFit.load(fit_path)
            fit.check_log(log)
        events_path = args.events or sidecar_path(args.log)
        events = read_events(events_path) if args.events or events_path.exists() else []
        uses = (f"the video's clock from {fit_path}; "
                + (f"events from {events_path}" if args.events or events_path.exists()
                   else f"no events (no {events_path})"))
        output = args.output or args.video.with_name(
            f"{args.video.name.removesuffix('.mp4')}.augmented.mp4")
        total = int(video.sidecar.get("frames") or 0)
        with progress_line(total, 0, quiet=args.quiet, label="augment", unit="frames",
                           scale=1) as show:
            report = augment_video(log, video, fit, output, events=events, progress=show)
    except LogAnalysisError as exc:
        print(f"augment: error: {exc}", file=sys.stderr)
        return 1
    print(f"using {uses}")
    print(f"{report.frames} frames of {report.width}x{report.height} with "
          f"{', '.join(report.robots) or 'no robot'} and {len(events)} events in "
          f"{report.seconds:.1f} s ({report.frames_per_s / report.video_fps:.1f}x real time); "
          f"written to {report.path}")
    return 0


def _variant(text: str) -> tuple[str, str]:
    label, sep, component = text.partition("=")
    if not sep or not label or not component:
        raise argparse.ArgumentTypeError(
            f"a variant is LABEL=COMPONENT (an entry point such as humanoid_sim::BallDetector, "
            f"or module:Class), not {text!r}")
    return label, component


def _setting(text: str) -> tuple[str, str, Any]:
    key, sep, value = text.partition("=")
    side, dot, name = key.partition(".")
    if not sep or not dot or side not in ("a", "b") or not name:
        raise argparse.ArgumentTypeError(f"a setting is a.NAME=VALUE or b.NAME=VALUE, not "
                                         f"{text!r}")
    import yaml

    return side, name, yaml.safe_load(value)


def compare_main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="compare", description=_help_of("compare"),
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("log", type=Path, help="the (merged) log with the robot's images")
    parser.add_argument("--robot", required=True, help="whose images (its namespace)")
    parser.add_argument("--a", type=_variant, required=True, metavar="LABEL=COMPONENT",
                        help="variant a: a label and an entry point such as "
                        "humanoid_sim::BallDetector, or module:Class")
    parser.add_argument("--b", type=_variant, required=True, metavar="LABEL=COMPONENT",
                        help="variant b, as --a")
    parser.add_argument("--set", type=_setting, action="append", default=[],
                        metavar="a.NAME=VALUE", help="a parameter of variant a or b "
                        "(YAML value; may repeat)")
    parser.add_argument("--images", default="camera/image_raw/compressed",
                        help="the robot's logged image topic (Image or CompressedImage; "
                        "default: camera/image_raw/compressed)")
    parser.add_argument("--agree-deg", type=float, default=2.0,
                        help="two detections within this many degrees agree, and a "
                        "detection this near the truth is a hit (default: 2)")
    parser.add_argument("-o", "--output", type=Path, default=Path("comparison"),
                        help="the folder for report.md and its plots")
    parser.add_argument("--quiet", action="store_true", help="no progress line")
    args = parser.parse_args(argv)
    from .compare import Variant, compare_components, write_report
    from .sidecar import write_events
    from .source import TeamLog
    params: dict[str, dict[str, Any]] = {"a": {}, "b": {}}
    for side, name, value in args.set:
        params[side][name] = value
    try:
        variants = [Variant(label, component, params[side])
                    for side, (label, component) in (("a", args.a), ("b", args.b))]
        log = TeamLog(args.log)
        first, last = log.time_range()
        with progress_line(last - first, first, quiet=args.quiet, label="compare") as show:
            comparison = compare_components(log, *variants, robot=args.robot,
                                            image_topic=args.images,
                                            agree_deg=args.agree_deg, progress=show)
        report = write_report(comparison, args.output)
        write_events(args.output / "disagreements.events.mcap", comparison.disagreements())
    except LogAnalysisError as exc:
        print(f"compare: error: {exc}", file=sys.stderr)
        return 1
    for problem in log.problems:
        print(f"compare: warning: {problem}", file=sys.stderr)
    sys.stderr.flush()
    print(report.read_text().split("![", 1)[0].rstrip())
    print(f"\nwritten to {report}")
    return 0
