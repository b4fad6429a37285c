"""The team match: robots in one world, each robot's software in a process of its own.

    python -m humanoid_sim.match --robots 3v3 --duration 60 --seed 4

``--robots``: ``1`` is the one-robot demo (:mod:`.demo`, every other argument goes to it);
``2`` or ``3`` is one team of that many (blue) against nobody; ``AvB`` is A blue against
B red (``1v1`` .. ``3v3``). A match starts:

* one world process (:mod:`.match_world`): the world with every robot's servo bus, the
  team referee, and each robot's camera, IMU, ``game_state`` and ground truth delivered on
  that robot's own DDS domain;
* one process per robot (:mod:`.match_robot`): driver, perception, behaviour, motion, team
  layer, its rf_bridge team link (Zenoh on localhost: each robot listens on a free port
  and connects to its teammates'; one key space per team and match) and its recorder.

Domains: the world's and each robot's are reserved for the match's life through
``efficient_comm.testing.isolated_domain_id`` (domain_coordinator's port per id, what the
tests use), so two matches, or a match and a test, never share a domain. The first line
printed names them (:func:`watch_line`, what ``python -m debug_gui.demo`` reads to watch
the match).

Every ``--stats-period`` seconds it prints a line for the game (wall and simulated time,
the world's real-time factor, game state, score) and one per robot (role, the behaviour's
state, game state as the robot got it, falls, the distance to the ball it believes in, the
team link's bytes a second). A robot whose process ends is reported by name and the match
goes on (its body stands where it is); the world ending ends the match. At the end (after
``--duration`` wall seconds, or Ctrl-C/SIGTERM) every process is stopped (each is the
leader of its own process group, which is stopped whole; a child also dies with this
process) and a report is printed and written (``--report``): goals per team, and per robot
falls, distance walked (ground truth), role switches, team-link bytes and CPU, and which
localization ran (``--localization``) with its error against ground truth. What is
recorded (:mod:`.match_recording`): each robot runs on a clock of its own, off the world's
by a seeded offset and drift that its ``ClockSync`` measures; the robots' bags and the
world's are merged into one log in the world's time, and the external video is filmed on a
camera clock of its own.

``--lockstep``: the world steps every robot's process as one barrier on simulated time
(one ``StepCoordinator`` per robot domain, :func:`.match_world.play_in_lockstep`): slower
than real time, never late; ``--duration`` then counts simulated seconds, and a seed plays
the same game on every run, team messages included (the team link delivers at a step fixed
by the sender's, :data:`TEAM_LINK_LATENCY_S` later; docs/HUMANOID_SIM.md, "What repeats").
``--team-link off``: no robot connects to a
teammate, as a cut link. ``--team-link-cut-at SECONDS``: the link fails mid-game, once the
world's (simulated) time reaches SECONDS: every robot is told to close its end
(:func:`cut_team_link`) and plays on alone; in lockstep each robot closes it itself at
that simulated time, so a cut match repeats too.

A bad argument is refused with one line and exit status 2. Exit status 0: every process
ran to the end; 1: one ended early (named in the report).
"""

from __future__ import annotations

import argparse
import contextlib
import ctypes
import json
import math
import os
import random
import re
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

import yaml

from efficient_comm import stop_on_sigterm
from efficient_comm.testing import isolated_domain_id, ros_env, stop_process_group
from soccer_field import KIDSIZE

from .arguments import EXIT_OK, TRANSPORTS, DemoArguments, finite_number
from .match_recording import (
    ClockSkew,
    RecordingPaths,
    clock_skews,
    merge_recordings,
    recording_paths,
    recording_report,
)
from .match_world import GroundTruthLog
from .soccer.pose_sources import GROUND_TRUTH, NOISY_GROUND_TRUTH, PARTICLE_FILTER, SOURCES
from .world import DEFAULT_START

EXIT_ENDED = 1
STATE_SETTLE_S = GroundTruthLog.SETTLE_S
#: The team link's budget per robot (bytes a second, and the burst), as in the team docs.
BUDGET_BYTES_PER_S = 2048
TEAM_NUMBERS = {"blue": 1, "red": 2}
_ROBOTS = re.compile(r"^(?:(?P<one>[1-3])|(?P<blue>[1-3])v(?P<red>[0-3]))$")
#: ``--localization``'s short names for the sources of ``localization/pose``.
LOCALIZATION_NAMES = {"pf": PARTICLE_FILTER, "noisy": NOISY_GROUND_TRUTH,
                      "truth": GROUND_TRUTH} | {s: s for s in SOURCES}
#: Every robot's source unless ``--localization`` says otherwise (docs/HUMANOID_SIM.md,
#: "Localization in the match", has the figures it was chosen by).
DEFAULT_LOCALIZATION = NOISY_GROUND_TRUTH


def robot_names(text: str) -> list[str]:
    """``--robots``: ``2``, ``3`` (one blue team) or ``AvB``; ``1`` is the demo's (``1v0``:
    one robot in the match's processes, what the match bench measures)."""
    m = _ROBOTS.match(text.strip())
    if m is None:
        raise argparse.ArgumentTypeError(
            f"{text!r}: need 1, 2, 3 (one team) or AvB with A, B in 1..3 (e.g. 3v3)")
    blue, red = (int(m["one"]), 0) if m["one"] else (int(m["blue"]), int(m["red"]))
    return [f"blue{i}" for i in range(1, blue + 1)] + [f"red{i}" for i in range(1, red + 1)]


def localization_choice(text: str) -> tuple[str | None, dict[str, str]]:
    """``--localization``: a source for every robot (``pf``, ``noisy``, ``truth``), robots'
    own (``blue1=pf,red1=noisy``), or both (``noisy,blue1=pf``): (the default or None, the
    robots' own). Whether the robots exist is checked against ``--robots`` later."""
    default: str | None = None
    own: dict[str, str] = {}
    names = ", ".join(LOCALIZATION_NAMES)
    for item in filter(None, (part.strip() for part in text.split(","))):
        robot, _, name = item.rpartition("=")
        source = LOCALIZATION_NAMES.get(name.strip())
        if source is None:
            raise argparse.ArgumentTypeError(f"{name.strip()!r} is not a localization: "
                                             f"one of {names}")
        if not robot:
            default = source
        elif not re.fullmatch(r"(blue|red)[1-3]", robot.strip()):
            raise argparse.ArgumentTypeError(f"{robot.strip()!r} is not a robot (blue1 .. red3)")
        else:
            own[robot.strip()] = source
    if default is None and not own:
        raise argparse.ArgumentTypeError(f"need a localization ({names}) or ROBOT=NAME pairs")
    return default, own


def robot_seed(seed: int, robot: str) -> int:
    """A seed of ``robot``'s own, stable for (``seed``, ``robot``): teammates given the
    match's one seed drew the same noise sample for sample, so their localization errors
    were perfectly correlated (and a shared world model averaged nothing out)."""
    return random.Random(f"localization {seed} {robot}").getrandbits(31)


def localization_plan(robot: str, source: str, *, start: tuple[float, float, float],
                      seed: int) -> dict[str, Any]:
    """The robot's localization: its source and that component's parameters (the
    particle filter starts where the robot was placed, knows its own half and its name, so
    it follows the referee's placements; the truth-based ones read the world's truth).
    ``seed`` is the match's: each robot's noise is seeded by :func:`robot_seed`."""
    seed = robot_seed(seed, robot)
    if source == PARTICLE_FILTER:
        parameters: dict[str, Any] = {
            "initial_pose": list(start), "robot": robot, "seed": seed,
            "own_half": "-x" if robot.startswith("blue") else "+x"}
    else:
        parameters = {"truth_topic": "ground_truth/pose"}
        if source == NOISY_GROUND_TRUTH:
            parameters["seed"] = seed
    return {"source": source, "parameters": parameters}


def start_poses(robots: Sequence[str], seed: int
                ) -> tuple[dict[str, tuple[float, float, float]], tuple[float, float]]:
    """Each robot's start (x, y, heading) and the ball's (x, y) for ``seed``.

    Seed 0: every robot at its :data:`~.world.DEFAULT_START`, the ball on the centre mark.
    Others draw a start the rules allow before ``ready``: each robot in its own half (blue
    x < 0, red x > 0), 0.5 m inside the lines and off the halfway line, facing anywhere, at
    least 0.6 m from every other; the ball within 1.5 m of the centre mark in x and y.
    """
    if seed == 0:
        return ({r: (DEFAULT_START[r].x, DEFAULT_START[r].y, DEFAULT_START[r].heading)
                 for r in robots}, (0.0, 0.0))
    rng = random.Random(f"soccer match start {seed}")
    half_l, half_w = KIDSIZE.half_length, KIDSIZE.half_width
    poses: dict[str, tuple[float, float, float]] = {}
    for robot in robots:
        side = -1.0 if robot.startswith("blue") else 1.0
        while True:
            pose = (side * rng.uniform(0.5, half_l - 0.5), rng.uniform(-half_w + 0.5,
                                                                      half_w - 0.5),
                    rng.uniform(-math.pi, math.pi))
            if all(math.dist(pose[:2], p[:2]) >= 0.6 for p in poses.values()):
                poses[robot] = pose
                break
    return poses, (rng.uniform(-1.5, 1.5), rng.uniform(-1.5, 1.5))


def free_port() -> int:
    """A TCP port on localhost the OS says is free now (for a robot's Zenoh listener)."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _die_with_parent() -> None:
    """In the child before exec: its own process group, and SIGTERM when we die."""
    os.setsid()
    with contextlib.suppress(OSError, AttributeError):
        ctypes.CDLL("libc.so.6", use_errno=True).prctl(1, signal.SIGTERM)  # PR_SET_PDEATHSIG


@dataclass
class Child:
    """A process of the match: its latest status line, and how it ended."""

    name: str
    proc: subprocess.Popen[str]
    log: Path
    status: dict[str, Any] = field(default_factory=dict)
    ready: threading.Event = field(default_factory=threading.Event)
    eof: threading.Event = field(default_factory=threading.Event)  # stdout read to its end
    ended: str | None = None  # how it ended, once noticed
    cpu_s: float = 0.0
    started: float = field(default_factory=time.monotonic)

    def read(self) -> None:
        """The child's stdout: ``ready`` and ``status {json}`` lines (a thread)."""
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            if line.startswith("status "):
                with contextlib.suppress(ValueError):
                    self.status = json.loads(line[7:])
            elif line.strip() == "ready":
                self.ready.set()
        self.eof.set()

    def sample_cpu(self) -> None:
        """User + system CPU seconds so far (/proc/<pid>/stat, all threads)."""
        with contextlib.suppress(OSError, IndexError, ValueError):
            fields = Path(f"/proc/{self.proc.pid}/stat").read_text().rsplit(")", 1)[1].split()
            self.cpu_s = (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def _start(name: str, module: str, plan: dict[str, Any], *, domain: int, log_dir: Path
           ) -> Child:
    log = log_dir / f"{name}.log"
    err: IO[str] = log.open("w")
    proc = subprocess.Popen([sys.executable, "-m", module, json.dumps(plan)],
                            stdout=subprocess.PIPE, stderr=err, text=True,
                            env=ros_env(domain), preexec_fn=_die_with_parent)
    err.close()
    child = Child(name, proc, log)
    threading.Thread(target=child.read, daemon=True, name=f"{name} stdout").start()
    return child


def _ended(child: Child) -> str:
    code = child.proc.returncode
    how = f"killed by signal {-code}" if code < 0 else f"exit status {code}"
    return f"{how} after {time.monotonic() - child.started:.1f} s"


#: In lockstep, a team message reaches a teammate this much simulated time after the step it
#: was sent in (a WiFi link's latency, rounded to the world's 10 ms steps).
TEAM_LINK_LATENCY_S = 0.1


def bridge_config(robot: str, *, prefix: str, port: int, teammates: Sequence[int]
                  ) -> dict[str, Any]:
    """The robot's rf_bridge file: the team link on localhost, within the budget."""
    return {
        "team": {"robot_id": robot, "prefix": prefix,
                 "listen": [f"tcp/127.0.0.1:{port}"],
                 "connect": [f"tcp/127.0.0.1:{p}" for p in teammates],
                 "budget_bytes_per_s": BUDGET_BYTES_PER_S,
                 "budget_burst_bytes": BUDGET_BYTES_PER_S},
        "topics": [{"ros2": "team/messages", "type": "soccer_interfaces/msg/TeamMessage",
                    "peer": "team", "direction": "both"}],
    }


def _parser() -> DemoArguments:
    parser = DemoArguments(prog="soccer_match", description=__doc__.split("\n\n")[0])
    parser.add_argument("--robots", type=robot_names, default=robot_names("3"),
                        help="2 or 3: one team; AvB: A blue against B red, e.g. 3v3 "
                        "(default 3; 1 is the one-robot demo)")
    parser.add_argument("--duration", type=finite_number(low=0, what="seconds >= 0"),
                        default=60.0, help="wall seconds (with --lockstep: simulated "
                        "seconds); 0 = until Ctrl-C (default 60)")
    parser.add_argument("--seed", type=int, default=0,
                        help="start poses and ball (0: the default starts, ball on the "
                        "centre mark); printed in the report")
    parser.add_argument("--team-link", choices=["on", "off"], default="on",
                        help="off: no robot connects to a teammate (a cut link: each "
                        "plays alone); default on")
    parser.add_argument("--team-link-cut-at", type=finite_number(low=0, what="seconds >= 0"),
                        default=None, metavar="SECONDS",
                        help="the team link fails once the world's (simulated) time reaches "
                        "SECONDS: every robot's end is closed mid-game (default never)")
    parser.add_argument("--lockstep", action="store_true",
                        help="the world steps every robot's process as one barrier on "
                        "simulated time: slower than real time, never late, and a seed "
                        "plays the same game every run")
    parser.add_argument("--stats-period", type=finite_number(low=0.5, what="seconds >= 0.5"),
                        default=2.0, help="seconds between live lines (default 2)")
    parser.add_argument("--camera-hz", type=finite_number(low=0, high=60, what="0 to 60 Hz"),
                        default=30.0, help="each robot's camera rate (default 30)")
    parser.add_argument("--camera-transport", choices=TRANSPORTS, default="shm",
                        help="how each camera image crosses from the world's process to its "
                        "robot's: shm (shared memory, the default) or dds")
    parser.add_argument("--ready-s", type=finite_number(low=1, what="seconds >= 1"), default=45.0,
                        help="the referee's longest ready (default 45, the GameController's)")
    parser.add_argument("--localization", type=localization_choice,
                        default=(DEFAULT_LOCALIZATION, {}),
                        help="each robot's localization/pose: pf (the particle filter), "
                        "noisy (noisy ground truth) or truth; for all robots, per robot "
                        "(blue1=pf,red1=noisy) or both (noisy,blue1=pf) (default noisy)")
    parser.add_argument("--role-margin", type=finite_number(low=0, what="seconds >= 0"),
                        default=None, metavar="S",
                        help="how much sooner at the ball a teammate must be to take the "
                        "striker's role from another (default 1; 0 with --role-hold 0 lets "
                        "roles oscillate, for trying log_analysis's role_oscillation)")
    parser.add_argument("--role-hold", type=finite_number(low=0, what="seconds >= 0"),
                        default=None, metavar="S",
                        help="the least time a robot keeps a role it took (default 2)")
    parser.add_argument("--report", type=Path, default=Path("match_report.md"))
    parser.add_argument("--out-dir", type=Path, default=Path("match"),
                        help="each process's log, the bags, the merged log and the video go "
                        "here (default ./match)")
    parser.add_argument("--video-fps", type=finite_number(low=0, high=30, what="0 to 30 fps"),
                        default=5.0, help="the external video's frame rate, 0 for none "
                        "(default 5)")
    return parser


def plan_recording(world: dict[str, Any], robots: Sequence[str], args: argparse.Namespace,
                   paths: RecordingPaths) -> dict[str, ClockSkew]:
    """The world's ``recording`` (its bag, the video on the camera's clock, and every
    robot's clock, which :func:`main` hands to each robot's plan); the clocks drawn."""
    skews = clock_skews(robots, args.seed)
    video = {"video_path": str(paths.video), "truth_path": str(paths.video_truth),
             "fps": args.video_fps, "width": 480, "height": 270,
             "clock_offset_s": skews["camera"].offset_s,
             "clock_drift_ppm": skews["camera"].drift_ppm}
    if getattr(args, "lockstep", False):  # everyone on the world's /clock: nothing to skew
        skews.update({r: ClockSkew(0.0, 0.0) for r in robots})
    world["recording"] = {
        "bag_dir": str(paths.bag_dir("world")), "video": video if args.video_fps else None,
        "clocks": {r: {"offset_s": skews[r].offset_s, "drift_ppm": skews[r].drift_ppm}
                   for r in robots}}
    return skews


def world_plan(robots: Sequence[str], args: argparse.Namespace, *, domains: dict[str, int],
               port_dir: Path, status_period_s: float) -> dict[str, Any]:
    poses, ball = start_poses(robots, args.seed)
    world: dict[str, Any] = {"robots": list(robots), "ball_position": list(ball),
                             "port_dir": str(port_dir), "camera_hz": args.camera_hz,
                             "seed": args.seed}
    world.update({f"{r}.pose": list(p) for r, p in poses.items()})
    return {"robots": list(robots), "domains": domains, "world": world, "step_hz": 100.0,
            "referee": {"robots": list(robots), "ready_s": args.ready_s},
            "status_period_s": status_period_s, "lockstep": args.lockstep,
            "end_s": args.duration if args.lockstep else 0.0,
            "camera_transport": args.camera_transport}


def robot_plan(robot: str, *, start: tuple[float, float, float], port: str,
               bridge_file: Path, bag_dir: Path, status_period_s: float, players: int,
               localization: str = DEFAULT_LOCALIZATION, seed: int = 0,
               lockstep: bool = False, role_margin_s: float | None = None,
               role_min_hold_s: float | None = None) -> dict[str, Any]:
    team, number = robot.rstrip("123"), int(robot[-1])
    return {
        "robot": robot, "port": port, "bridge_file": str(bridge_file), "lockstep": lockstep,
        "localization": localization_plan(robot, localization, start=start, seed=seed),
        "bag_dir": str(bag_dir), "status_period_s": status_period_s,
        "striker": {"robot": robot, "start_pose": list(start)},
        # A team of three keeps player 3 in goal (its kick-off spot is there); smaller
        # teams play without a goalie.
        "team": {"team_number": TEAM_NUMBERS[team], "player_number": number,
                 "goalie_number": 3 if players == 3 else 0,
                 # The roles' hysteresis (soccer.roles): TeamComm's defaults unless given.
                 **({} if role_margin_s is None else {"role_margin_s": role_margin_s}),
                 **({} if role_min_hold_s is None else {"role_min_hold_s": role_min_hold_s})},
    }


def _link_figures(status: dict[str, Any]) -> tuple[float, float, float, float]:
    link = status.get("link") or {}
    return (link.get("sent_bytes", 0.0), link.get("received_bytes", 0.0),
            link.get("sent_bytes_per_s", 0.0), link.get("peak_bytes_per_s", 0.0))


def cut_team_link(children: dict[str, Child], sim_s: float) -> float:
    """The team link fails (in real time): SIGUSR1 to every robot still running, which
    closes its end (:class:`.match_robot.TeamLinkCut`; sent once every robot is ready, so
    that each has its handler); the world's time it happened at, also printed."""
    for child in children.values():
        if child.ended is None and child.proc.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                child.proc.send_signal(signal.SIGUSR1)
    return announce_cut(sim_s)


def announce_cut(sim_s: float) -> float:
    """Print when the team link failed (in lockstep the robots cut it themselves at the
    plan's ``team_link_cut_at_s``, at their first step from then on)."""
    print(f"team link cut at {sim_s:.1f} s simulated: each robot plays alone", flush=True)
    return sim_s


def _cut_text(args: argparse.Namespace) -> str:
    cut = getattr(args, "link_cut_s", None)
    if cut is not None:
        return f"team link cut at {cut:.1f} s; "
    if getattr(args, "team_link_cut_at", None) is not None:
        return f"team link never cut (--team-link-cut-at {args.team_link_cut_at:g}); "
    return ""


def game_line(world: Child, wall_s: float) -> str:
    s = world.status
    score = s.get("score", {})
    return (f"{wall_s:6.1f} s wall, {s.get('sim_time_s', 0.0):6.1f} s simulated, RTF "
            f"{s.get('real_time_factor', 0.0):4.2f}, {s.get('game_state', '-'):<8} "
            f"blue {score.get('blue', 0)} : {score.get('red', 0)} red")


def robot_line(child: Child) -> str:
    if child.ended:
        return f"  {child.name:<6} ENDED ({child.ended})"
    s = child.status
    if not s:
        return f"  {child.name:<6} starting"
    ball = "-" if s.get("ball_m") is None else f"{s['ball_m']:.2f} m"
    return (f"  {child.name:<6} {s.get('role', '-'):<9} {s.get('behaviour', '-'):<8} "
            f"game {s.get('game_state', '-'):<8} falls {s.get('falls', 0)} ball {ball:<7} "
            + ("link   cut" if s.get("link_cut") else f"link {_link_figures(s)[2]:5.0f} B/s"))


def _figure(figures: dict[str, Any], key: str, spec: str) -> str:
    value = figures.get(key)
    return "-" if value is None or not math.isfinite(value) else format(value, spec)


def state_lines(world: dict[str, Any]) -> list[str]:
    """One line per game state the world entered: ``- set from 2.0 s: blue1 at (-0.75,
    0.00) moved 0.02 m; ...`` (what the SIL tests read)."""
    lines = []
    starts, moved = world.get("at_state_start", []), world.get("moved_in_state_m", [])
    for i, (state, t) in enumerate(world.get("states", [])):
        robots = [f"{r} at ({x:.2f}, {y:.2f}) moved {moved[i].get(r, 0.0):.2f} m"
                  for r, (x, y) in (starts[i].items() if i < len(starts) else ())
                  if i < len(moved)]
        lines.append(f"- {state} from {t:.1f} s: " + ("; ".join(robots) or "-"))
    return lines


def report(robots: Sequence[str], args: argparse.Namespace, world: Child,
           children: dict[str, Child], wall_s: float, *,
           imu_sent: dict[str, int] | None = None) -> str:
    """``imu_sent``: the world's IMU counts as the robots were stopped (its later status
    counts on while a stopping robot's reader is still matched but no longer counting)."""
    s = world.status
    score = s.get("score", {})
    goals = ", ".join(f"{team} at {t:.1f} s" for t, team in s.get("goals", [])) or "none"
    cpus = {c.name: c.cpu_s / wall_s * 100 if wall_s else 0.0
            for c in (world, *children.values())}
    lines = [
        "# Team match report", "",
        f"Robots {', '.join(robots)}; seed {args.seed}; "
        f"{'lockstep' if args.lockstep else 'real time'}; "
        f"{'' if args.team_link == 'on' else 'team link cut; '}"
        f"{_cut_text(args)}"
        f"{wall_s:.1f} s wall, {s.get('sim_time_s', 0.0):.1f} s simulated, real-time factor "
        f"{s.get('real_time_factor', 0.0):.2f} (world physics "
        f"{s.get('physics_ms', 0.0):.2f} ms a step, render {s.get('render_ms', 0.0):.1f} ms a "
        f"frame); game state at the end {s.get('game_state', '-')}.", "",
        f"Goals: blue {score.get('blue', 0)}, red {score.get('red', 0)} ({goals}).", "",
        "| robot | process | role (switches) | game state seen | camera frames / IMU "
        "messages | falls | walked m | team link sent / received bytes | B/s sent (peak) | "
        "CPU % |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for name in robots:
        c = children.get(name)
        if c is None:  # stopped before it started
            lines.append(f"| {name} | not started |" + " - |" * 8)
            continue
        st = c.status
        sent, received, rate, peak = _link_figures(st)
        walked = s.get("walked_m", {}).get(name, 0.0)
        lines.append(
            f"| {name} | {c.ended or 'ran to the end'} | {st.get('role', '-')} "
            f"({st.get('role_switches', 0)}) | {st.get('game_state', '-')} | "
            f"{st.get('frames', 0)} / {st.get('imus', 0)} | {st.get('falls', 0)} | {walked:.2f} | "
            f"{sent:.0f} / {received:.0f} | {rate:.0f} ({peak:.0f}) of {BUDGET_BYTES_PER_S} | "
            f"{cpus[name]:.0f} |")
    lines += ["", "Localization, each robot's estimates against ground truth:", ""]
    for name in robots:
        c = children.get(name)
        loc = (c.status.get("localization") if c is not None else None) or {}
        e = loc.get("errors") or {}
        lines.append(
            f"- {name}: {loc.get('source', '-')}, {e.get('estimates', 0):.0f} estimates; "
            f"position error mean {_figure(e, 'position_error_mean_m', '.3f')} m, p95 "
            f"{_figure(e, 'position_error_p95_m', '.3f')} m, max "
            f"{_figure(e, 'position_error_max_m', '.3f')} m; heading error mean "
            f"{_figure(e, 'heading_error_mean_deg', '.1f')}°, p95 "
            f"{_figure(e, 'heading_error_p95_deg', '.1f')}°")
    lines += ["", "Game states (ground truth: where each robot stood as the state began, "
              "and the farthest it moved from where it stood "
              f"{STATE_SETTLE_S:g} s into it):", ""]
    lines += state_lines(s)
    if args.lockstep:
        lines += ["", f"Ground truth fingerprint {s.get('truth_sha', '-')} (every robot's "
                  "and the ball's pose each 0.1 s simulated: equal for equal games)."]
    lines += ["", f"World process CPU {cpus['world']:.0f} % of one core "
              f"({world.ended or 'ran to the end'}); logs and bags in {args.out_dir}.",
              "", world_cpu_line(s),
              "", "IMU messages heard of those the world sent while the robot's reader was "
              "matched: " + ", ".join(
                  f"{n} {children[n].status.get('imus', 0)} of "
                  f"{(imu_sent or s.get('imu_sent', {})).get(n, 0)}"
                  for n in robots if n in children) + ".",
              "", "Since each robot was ready, IMU messages heard a wall second (the world "
              f"ticks {s.get('tick_hz', 0.0):.1f}, one message per robot each) and CPU % of "
              "a core: " + ", ".join(
                  f"{n} {children[n].status.get('imu_hz', 0.0):.1f} Hz "
                  f"{children[n].status.get('cpu_pct', 0.0):.0f} %"
                  for n in robots if n in children) + ".",
              "", camera_line(s, args.camera_transport), ""]
    return "\n".join(lines)


def camera_line(status: dict[str, Any], transport: str) -> str:
    """How the camera images reached the robots' processes: through shared memory, per
    robot the frames the world sent so and those it also wrote to DDS (for a plain reader
    on the robot's domain, such as ``ros2 topic echo``), or over DDS."""
    if transport != "shm":
        return "Camera images to the robots over DDS."
    traffic = status.get("camera_traffic") or {}
    return ("Camera images to the robots through shared memory (frames sent so, of them "
            "also written to DDS for a plain reader): " + ", ".join(
                f"{r} {shm} ({dds})" for r, (shm, dds) in traffic.items()) + ".")


def world_cpu_line(status: dict[str, Any]) -> str:
    """The world process's CPU by part and its ticks (each one IMU message per robot): what
    ``bench/match_bench.py`` reads back."""
    cpu = status.get("cpu_s") or {}
    parts = ", ".join(f"{k} {cpu.get(k, 0.0):.2f}" for k in ("physics", "render", "bus",
                                                              "other"))
    return f"World CPU s: {parts}; ticks {status.get('ticks', 0)}."


def main(argv: Sequence[str] | None = None) -> int:
    given = list(sys.argv[1:] if argv is None else argv)
    pre = argparse.ArgumentParser(add_help=False)
    pre.add_argument("--robots")
    known, rest = pre.parse_known_args(given)
    if known.robots is not None and known.robots.strip() == "1":
        from .demo import main as demo_main
        return demo_main(rest)
    parser = _parser()
    args = parser.parse_args(given)
    robots: list[str] = args.robots
    default_source, own_sources = args.localization
    args.link_cut_s = None  # the world's time the link was cut at (--team-link-cut-at)
    if unknown := sorted(set(own_sources) - set(robots)):
        parser.error(f"--localization names {', '.join(unknown)}, not in this match "
                     f"({', '.join(robots)})")
    sources = {r: own_sources.get(r, default_source or DEFAULT_LOCALIZATION) for r in robots}
    stop_on_sigterm()
    args.out_dir.mkdir(parents=True, exist_ok=True)
    period = min(args.stats_period, 1.0)
    token = os.urandom(4).hex()
    paths = recording_paths(args.out_dir, time.strftime("%Y%m%d_%H%M%S", time.gmtime()))
    with tempfile.TemporaryDirectory(prefix="soccer_match_") as tmp:
        port_dir = Path(tmp, "ports")
        domains = {r: isolated_domain_id() for r in ["world", *robots]}
        print(watch_line(domains), flush=True)
        plan = world_plan(robots, args, domains=domains, port_dir=port_dir,
                          status_period_s=period)
        skews = plan_recording(plan, robots, args, paths)
        clocks = plan["recording"]["clocks"]
        world = _start("world", "humanoid_sim.match_world", plan,
                       domain=domains["world"], log_dir=args.out_dir)
        children: dict[str, Child] = {}
        started = time.monotonic()
        ok = True
        try:
            if not _wait_ready(world, 120):
                print(f"soccer_match: the world did not start ({world.log}):\n"
                      + world.log.read_text()[-2000:], file=sys.stderr)
                return EXIT_ENDED
            ports = {r: free_port() for r in robots}
            poses, _ = start_poses(robots, args.seed)
            for robot in robots:
                team = robot.rstrip("123")
                mates = [ports[m] for m in robots if m.startswith(team) and m < robot
                         and args.team_link == "on"]
                bridge_file = Path(tmp, f"{robot}_bridge.yaml")
                bridge_file.write_text(yaml.safe_dump(bridge_config(
                    robot, prefix=f"match_{token}_{team}", port=ports[robot], teammates=mates)))
                players = sum(1 for m in robots if m.startswith(team))
                plan = robot_plan(
                    robot, start=poses[robot], port=str(port_dir / robot), bridge_file=bridge_file,
                    bag_dir=paths.bag_dir(robot), status_period_s=period,
                    players=players, localization=sources[robot], seed=args.seed,
                    lockstep=args.lockstep, role_margin_s=args.role_margin,
                    role_min_hold_s=args.role_hold)
                plan["clock"] = clocks[robot]
                plan["team_peers"] = [m for m in robots if m.startswith(team) and m != robot
                                      and args.team_link == "on"]
                plan["team_latency_s"] = TEAM_LINK_LATENCY_S
                plan["camera_transport"] = args.camera_transport
                # In lockstep each robot cuts its end itself at that simulated time: a
                # signal sent when the match saw the world's time pass it arrived a load-
                # dependent while later (the game did not repeat; an offline check of the
                # cut's time failed in a full run).
                plan["team_link_cut_at_s"] = args.team_link_cut_at if args.lockstep else None
                children[robot] = _start(robot, "humanoid_sim.match_robot", plan,
                                         domain=domains[robot], log_dir=args.out_dir)
            print("localization: " + ", ".join(f"{r} {s}" for r, s in sources.items()),
                  flush=True)
            print(f"soccer match: {', '.join(robots)}, seed {args.seed}, domains "
                  + ", ".join(f"{k} {v}" for k, v in domains.items())
                  + f"; {'until Ctrl-C' if not args.duration else f'{args.duration:g} s'}"
                  + (" simulated, in lockstep" if args.lockstep else "") + "; "
                  f"logs in {args.out_dir}", flush=True)
            ok = _run(world, children, args, started)
        except KeyboardInterrupt:
            print("interrupted", flush=True)
        finally:
            imu_sent = dict(world.status.get("imu_sent", {}))
            for child in (*children.values(), world):
                child.sample_cpu()
            wall_s = time.monotonic() - started
            for child in (*children.values(), world):  # robots first: the world serves them
                with contextlib.suppress(ProcessLookupError):
                    stop_process_group(child.proc, timeout_s=10)
            for child in (world, *children.values()):
                if child.proc.stdout is not None:
                    child.proc.stdout.close()
    _, merge_line = merge_recordings(paths, robots, lockstep=args.lockstep)
    text = report(robots, args, world, children, wall_s, imu_sent=imu_sent) + recording_report(
        paths, skews, merge_line, video=bool(args.video_fps))
    args.report.parent.mkdir(parents=True, exist_ok=True)
    args.report.write_text(text)
    print(f"\n{text}\nreport written to {args.report.resolve()}", flush=True)
    ok = ok and not any(c.ended for c in children.values()) and not world.ended
    return EXIT_OK if ok else EXIT_ENDED


def watch_line(domains: dict[str, int]) -> str:
    """The line that says, before anything starts, how to watch the match's robots with
    debug_gui (``python -m debug_gui.demo`` reads it to find them): their domains, the
    world's apart (its process is no robot)."""
    robots = ",".join(str(d) for name, d in domains.items() if name != "world")
    return (f"soccer match: debug_gui --domains {robots} watches its robots "
            f"(the world is in domain {domains['world']})")


def _wait_ready(child: Child, timeout_s: float) -> bool:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if child.ready.wait(0.2):
            return True
        if child.proc.poll() is not None:
            return False
    return False


def _run(world: Child, children: dict[str, Child], args: argparse.Namespace,
         started: float) -> bool:
    """The live lines until the end; False if the world ended."""
    # In lockstep the world ends the match after --duration simulated seconds.
    end = started + args.duration if args.duration and not args.lockstep else math.inf
    next_line = time.monotonic()
    told = 0  # game state changes printed
    while (now := time.monotonic()) < end:
        if (args.team_link_cut_at is not None and args.link_cut_s is None
                and world.status.get("sim_time_s", 0.0) >= args.team_link_cut_at
                and all(c.ready.is_set() or c.ended for c in children.values())):
            args.link_cut_s = (announce_cut(args.team_link_cut_at) if args.lockstep
                               else cut_team_link(children, world.status["sim_time_s"]))
        for state, sim_s in world.status.get("states", [])[told:]:
            print(f"game state {state} at {sim_s:.1f} s simulated", flush=True)
            told += 1
        for child in children.values():
            if child.ended is None and child.proc.poll() is not None:
                child.ended = _ended(child)
                print(f"{child.name}: its process ended ({child.ended}); the match goes on "
                      f"(log {child.log})", flush=True)
            if child.ended is None:
                child.sample_cpu()
        world.sample_cpu()
        if world.proc.poll() is not None:
            if world.proc.returncode == 0 and args.lockstep and args.duration:
                world.eof.wait(10)  # its last status line: the end of the game
                return True  # played its simulated --duration
            world.ended = _ended(world)
            print(f"world: its process ended ({world.ended}); the match is over "
                  f"(log {world.log})", flush=True)
            return False
        if now >= next_line:
            next_line += args.stats_period
            print(game_line(world, now - started), flush=True)
            for child in children.values():
                print(robot_line(child), flush=True)
        time.sleep(min(0.2, max(0.0, end - now)))
    return True


if __name__ == "__main__":
    sys.exit(main())
