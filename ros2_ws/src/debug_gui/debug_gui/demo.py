"""Simulated robots and the GUI watching them: ``python -m debug_gui.demo``.

By default a team match (``python -m humanoid_sim.match``: one world process, one process
per robot, each robot on a DDS domain of its own, a referee) and the GUI watching every
robot of it, starting from the world view (every robot on one field in its team's colour,
its role, the balls it believes in, the game state and score) and the robots' components.
``--robots`` says who plays, as the match takes it (``3``, ``2v1``, ``3v3``); every
argument the demo does not know goes to the match (``--seed``, ``--out-dir``, ...). The
match's live lines and its report come through; ``--duration`` (default: until Ctrl-C)
ends it, and the GUI ends with the match. See :mod:`.demo_match`.

``--solo`` is the demo of robots that each play alone, on a field of their own: ``--robots
N`` starts N soccer robots, one ``python -m humanoid_sim.demo --duration 0 --namespace
/robotK`` process each: robot 1 alone in the first domain, the others together in the
second domain under their own namespaces, so the GUI shows both ways robots are told apart.

Either way it serves the GUI (as ``debug_gui`` would) and prints its URL. Ctrl-C, SIGTERM
or ``--duration`` stop the GUI and every robot.

Robots play (walk to the ball, kick, get up) in real time. A machine that cannot simulate
them all in real time makes them late, and a late walk falls: ``--lockstep`` runs the
match's robots in step with its world (the match's ``--lockstep``), each solo robot on a
manual clock, as fast as the machine allows (slower than real time on a small machine, but
every robot plays as it would on a fast one).

Each solo robot's recorder writes its bags under ``--record-dir`` (default
``debug_gui_recordings`` in the current directory), robot K's in ``robotK/``: a folder
that outlives the demo, printed at start as an absolute path (the recorder view shows the
bags' absolute paths too). The robots' output goes to ``--log-dir``, by default a
temporary folder removed on exit. (The match keeps its logs and bags in its ``--out-dir``.)
"""

from __future__ import annotations

import argparse
import contextlib
import os
import signal
import subprocess
import sys
import tempfile
import threading
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

from efficient_comm import exit_with_parent, stop_on_sigterm

from .demo_match import MatchProcess
from .errors import DebugGuiError, InvalidInput
from .layout import Layout, Panel
from .robots import check_domain
from .server import Options, serve

#: More robots than this make a two-core machine crawl (each simulates and renders).
MAX_ROBOTS = 6
STOP_TIMEOUT_S = 10.0
#: Where the robots' bags go unless ``--record-dir`` says otherwise (under the current
#: directory, so recordings outlive the demo and are found where it was started).
DEFAULT_RECORD_DIR = "debug_gui_recordings"
#: How many solo robots without ``--robots``.
SOLO_ROBOTS = 3
#: What a tab watching a match starts from: the field with every robot, and each robot's
#: callbacks. Light on purpose (no camera views: each is a video stream; add them per
#: robot): the world view sends its drawing only when it changed, the components tables
#: changed cells every 2 s.
MATCH_LAYOUT = Layout((Panel(kind="world"), Panel(kind="components")))
#: How long the match may take to name its domains (it does so before its world starts).
MATCH_DOMAINS_TIMEOUT_S = 120.0
#: Options of the solo robots only (refused with a match).
_SOLO_ONLY = ("domains", "record_dir", "log_dir")


@dataclass(frozen=True, slots=True)
class DemoRobot:
    domain: int
    namespace: str


def plan(count: int, domains: tuple[int, int]) -> list[DemoRobot]:
    """Robot 1 in the first domain; robots 2..N share the second, apart by namespace."""
    if not 1 <= count <= MAX_ROBOTS:
        raise InvalidInput(f"--robots is 1..{MAX_ROBOTS}, not {count}")
    return [DemoRobot(domains[0] if k == 1 else domains[1], f"/robot{k}")
            for k in range(1, count + 1)]


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="debug_gui_demo", description=__doc__.split("\n\n")[0],
        allow_abbrev=False,  # an abbreviation must not take the match's arguments
        epilog="Other arguments go to the match (python -m humanoid_sim.match --help: "
               "--seed, --out-dir, --report, ...).")
    parser.add_argument("--robots", default=None,
                        help="the match's robots as the match takes them: 2 or 3 (one team) "
                             "or AvB (e.g. 1v1, 3v3); the match's default if not given. "
                             f"With --solo: how many (default {SOLO_ROBOTS})")
    parser.add_argument("--solo", action="store_true",
                        help="no match: robots that each play alone on a field of their own")
    parser.add_argument("--domains", default=None, metavar="A,B",
                        help="--solo: the two DDS domains (default: $ROS_DOMAIN_ID or 0, "
                             "and the next)")
    parser.add_argument("--port", type=int, default=8080, help="HTTP port (0: any free one)")
    parser.add_argument("--duration", type=float, default=0.0,
                        help="seconds until everything stops (0: until Ctrl-C); with "
                             "a match, the match's --duration")
    parser.add_argument("--layout", type=Path, default=None, help="layout JSON file")
    parser.add_argument("--plain-robots", action="store_true",
                        help="also show plain ROS 2 robots (as debug_gui --plain-robots)")
    parser.add_argument("--lockstep", action="store_true",
                        help="robots on simulated time, as fast as the machine allows "
                             "(slower than real time, but never late): the match's "
                             "--lockstep, or --solo robots on manual clocks")
    parser.add_argument("--record-dir", type=Path, default=None,
                        help="--solo: where the robots' recorders write bags, one folder "
                             f"per robot (default ./{DEFAULT_RECORD_DIR}; kept after the demo)")
    parser.add_argument("--log-dir", type=Path, default=None,
                        help="--solo: where the robots' output goes (default: a "
                             "temporary folder)")
    return parser


def _domains(text: str | None) -> tuple[int, int]:
    if text is None:
        first = check_domain(int(os.environ.get("ROS_DOMAIN_ID") or 0))
        return first, check_domain(first + 1)
    parts = [p.strip() for p in text.split(",")]
    if len(parts) != 2 or not all(p.isdigit() for p in parts) or parts[0] == parts[1]:
        raise InvalidInput(f"--domains is two different domain ids A,B, not {text!r}")
    return check_domain(int(parts[0])), check_domain(int(parts[1]))


@contextlib.contextmanager
def robots(planned: Sequence[DemoRobot], log_dir: Path, *, record_dir: Path,
           lockstep: bool = False) -> Iterator[list[subprocess.Popen[bytes]]]:
    """The robots as processes in sessions of their own; stopped (Ctrl-C, then kill) on exit.

    Robot ``/robotK`` records under ``record_dir/robotK`` (absolute: the robot runs in a
    folder of its own under ``log_dir``)."""
    procs: list[subprocess.Popen[bytes]] = []
    try:
        for robot in planned:
            name = robot.namespace.strip("/")
            env = dict(os.environ, ROS_DOMAIN_ID=str(robot.domain))
            env.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
            workdir = log_dir / name
            workdir.mkdir(parents=True, exist_ok=True)
            with open(log_dir / f"{name}.log", "wb") as log:
                procs.append(subprocess.Popen(
                    [sys.executable, "-m", "humanoid_sim.demo", "--duration", "0",
                     "--namespace", robot.namespace,
                     "--bag-dir", str(record_dir.absolute() / name),
                     *(["--lockstep"] if lockstep else [])],
                    env=env, stdout=log, stderr=subprocess.STDOUT, cwd=workdir,
                    start_new_session=True, preexec_fn=exit_with_parent,
                ))
        yield procs
    finally:
        if procs:  # each writes its report first: say why nothing happens for a while
            print(f"debug_gui demo: stopping {len(procs)} robot(s)", file=sys.stderr, flush=True)
        for proc in procs:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(proc.pid, signal.SIGINT)
        for proc in procs:
            try:
                proc.wait(timeout=STOP_TIMEOUT_S)
            except subprocess.TimeoutExpired:
                with contextlib.suppress(ProcessLookupError):
                    os.killpg(proc.pid, signal.SIGKILL)
                proc.wait()


def _watch(procs: Sequence[subprocess.Popen[bytes]], planned: Sequence[DemoRobot],
           log_dir: Path, stop: threading.Event) -> None:
    """Say so when a robot ends before the demo does (its log's last line tells why)."""
    reported: set[int] = set()
    while not stop.wait(1.0):
        for i, proc in enumerate(procs):
            if i not in reported and proc.poll() is not None:
                reported.add(i)
                name = planned[i].namespace.strip("/")
                lines = (log_dir / f"{name}.log").read_text(errors="replace").splitlines()
                print(f"debug_gui demo: {planned[i].namespace} exited ({proc.returncode}): "
                      f"{lines[-1] if lines else 'no output'}", file=sys.stderr, flush=True)


def main(argv: Sequence[str] | None = None) -> int:
    args, rest = _parser().parse_known_args(argv)
    given = [f"--{name.replace('_', '-')}" for name in _SOLO_ONLY
             if getattr(args, name) not in (None, False)]
    refused = (f"unrecognized arguments with --solo: {' '.join(rest)}" if args.solo and rest
               else f"{', '.join(given)}: for --solo robots only, not for a match"
               if given and not args.solo else None)
    if refused:
        print(f"debug_gui demo: error: {refused}", file=sys.stderr)
        return 2
    return _solo(args) if args.solo else _match(args, rest)


def _gui_options(args: argparse.Namespace, domains: Sequence[int]) -> Options:
    """The GUI's command line from the demo's (validated: a busy port fails here)."""
    gui_args = ["--port", str(args.port), "--domains", ",".join(map(str, domains))]
    if args.layout is not None:
        gui_args += ["--layout", str(args.layout)]
    if args.plain_robots:
        gui_args.append("--plain-robots")
    if args.duration < 0:
        raise InvalidInput(f"--duration is >= 0, not {args.duration}")
    return Options(gui_args)


def _match(args: argparse.Namespace, rest: Sequence[str]) -> int:
    """The team match and the GUI watching its robots; the GUI ends with the match."""
    robots = (args.robots or "").strip()
    try:
        if robots == "1":
            raise InvalidInput("--robots 1 is one robot alone, no match: --solo --robots 1")
        options = _gui_options(args, [0])  # the match's domains replace 0 once it names them
    except DebugGuiError as exc:
        print(f"debug_gui demo: error: {exc}", file=sys.stderr)
        return 2
    match_args = [*(["--robots", robots] if robots else []),
                  *(["--lockstep"] if args.lockstep else []),
                  "--duration", f"{args.duration:g}", *rest]
    stop_on_sigterm()  # until the server takes over SIGTERM: the match is stopped either way
    with MatchProcess(match_args) as match:
        try:
            domains = match.wait_for_domains(MATCH_DOMAINS_TIMEOUT_S)
            if domains is None:
                code = match.stop()
                if code != 2:  # 2: the match refused an argument, and said why
                    print("debug_gui demo: error: the match ended before naming its robots' "
                          f"domains (exit status {code})", file=sys.stderr)
                return code or 2
            options.domains = domains

            def ended(code: int) -> None:
                print(f"debug_gui demo: the match ended (exit status {code}); the GUI stops",
                      file=sys.stderr, flush=True)
                os.kill(os.getpid(), signal.SIGINT)

            match.on_end(ended)
            serve(options, default_layout=MATCH_LAYOUT)
        except DebugGuiError as exc:
            print(f"debug_gui demo: error: {exc}", file=sys.stderr)
            match.stop()
            return 2
        except KeyboardInterrupt:
            pass
        if match.proc.poll() is None:  # it prints its report while it stops
            print("debug_gui demo: stopping the match", file=sys.stderr, flush=True)
        return match.stop()


def _solo(args: argparse.Namespace) -> int:
    """Robots that each play alone (the demo before the team match), and the GUI."""
    try:
        if args.robots is not None and not args.robots.strip().isdigit():
            raise InvalidInput(f"--robots is 1..{MAX_ROBOTS} with --solo, not {args.robots!r}")
        planned = plan(SOLO_ROBOTS if args.robots is None else int(args.robots),
                       _domains(args.domains))
        options = _gui_options(args, sorted({r.domain for r in planned}))
    except DebugGuiError as exc:
        print(f"debug_gui demo: error: {exc}", file=sys.stderr)
        return 2
    stop_on_sigterm()  # until the server takes over SIGTERM: robots are stopped either way
    with contextlib.ExitStack() as stack:
        log_dir = args.log_dir or Path(stack.enter_context(
            tempfile.TemporaryDirectory(prefix="debug_gui_demo_")))
        log_dir.mkdir(parents=True, exist_ok=True)
        record_dir = (args.record_dir or Path(DEFAULT_RECORD_DIR)).absolute()
        try:
            record_dir.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            print(f"debug_gui demo: error: --record-dir {record_dir}: {exc.strerror or exc}",
                  file=sys.stderr)
            return 2
        print(f"debug_gui demo: recordings go to {record_dir} (kept after the demo)",
              flush=True)
        procs = stack.enter_context(robots(planned, log_dir, record_dir=record_dir,
                                           lockstep=args.lockstep))
        for robot, proc in zip(planned, procs, strict=True):
            print(f"debug_gui demo: {robot.namespace} in domain {robot.domain} "
                  f"(pid {proc.pid}, log: {log_dir / robot.namespace.strip('/')}.log)",
                  flush=True)
        stop = threading.Event()
        stack.callback(stop.set)
        threading.Thread(target=_watch, args=(procs, planned, log_dir, stop),
                         daemon=True).start()
        if args.duration > 0:
            timer = threading.Timer(args.duration, os.kill, (os.getpid(), signal.SIGINT))
            timer.daemon = True
            timer.start()
            stack.callback(timer.cancel)
        try:
            return serve(options)
        except DebugGuiError as exc:
            print(f"debug_gui demo: error: {exc}", file=sys.stderr)
            return 2
        except KeyboardInterrupt:
            return 0


if __name__ == "__main__":
    sys.exit(main())
