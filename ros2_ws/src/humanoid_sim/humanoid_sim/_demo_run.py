"""The soccer demo's run (:mod:`.demo` is its command line): the robot composed, played
for the given time with live lines, and the report."""

from __future__ import annotations

import argparse
import contextlib
import math
import sys
import time
from datetime import UTC, datetime
from functools import partial
from pathlib import Path
from tempfile import TemporaryDirectory

from efficient_comm import (
    ComponentError,
    Container,
    ManualClock,
    format_stats,
    stop_on_sigterm,
)
from robot_recorder import Recorder

from .arguments import EXIT_BUG, EXIT_FELL, EXIT_OK, DemoArguments, start_positions
from .errors import HumanoidSimError, ProcessError
from .match_video import MatchCamera
from .soccer.compose import SoccerRobot, compose
from .soccer.monitor import Figures
from .split import Perception

#: What the robot's recorder records once started (relative to the robot's namespace);
#: a viewer may change it (the recorder's ``~/set_topics`` service).
RECORDED_TOPICS = [
    "joint_states", "imu/data", "ball/detection", "ball/estimate", "head/goal",
    "fall/state", "ground_truth/robot", "ground_truth/ball", "camera/image_raw max_rate_hz=5",
    "ball/position", "behaviour/state", "cmd_vel", "odom", "motion/state",
]

HEADER = (f"{'sim s':>6} {'RTF':>5} {'cam fps':>7} {'det Hz':>6} {'bus Hz':>6} "
          f"{'err mean°':>9} {'err p95°':>8} {'lat ms':>6} {'walked m':>8} {'kicks':>5} "
          f"{'goals':>5} {'falls':>5} {'striker':<8} {'head':<9} {'bus err':>7}")


def _f(value: float, spec: str) -> str:
    return "n/a" if math.isnan(value) else format(value, spec)


#: The split robot's extra column: the camera images its publisher also wrote to DDS.
SPLIT_HEADER = f" {'img DDS':>7}"


def live_line(robot: SoccerRobot, window: Figures) -> str:
    s = window.summary()
    return (f"{robot.simulator.sim_time_s:>6.1f} {robot.simulator.real_time_factor:>5.2f} "
            f"{s['camera_fps']:>7.1f} {s['detection_rate_hz']:>6.1f} "
            f"{s['joint_state_rate_hz']:>6.1f} {_f(s['tracking_error_mean_deg'], '9.2f'):>9} "
            f"{_f(s['tracking_error_p95_deg'], '8.2f'):>8} "
            f"{_f(s['latency_median_ms'], '6.1f'):>6} {robot.monitor.walked_m:>8.2f} "
            f"{robot.monitor.kicks:>5} {robot.referee.goals:>5} {robot.fall_detector.falls:>5} "
            f"{robot.striker.state if robot.striker else '-':<8} {robot.behaviour.state:<9} "
            f"{robot.driver.comm_errors:>7}")


def posture(robot: SoccerRobot, frames_down: int) -> str:
    """What the fall detector saw, for the report: the robot fell, or it stood throughout."""
    fall = robot.fall_detector
    pushes = robot.simulator.status()["pushes"]
    pushed = f"; pushed {pushes} time{'s' * (pushes != 1)}" if pushes else ""
    if not fall.falls:
        return f"stood throughout, now {fall.state}{pushed}"
    when = ", ".join(f"{(t - robot.monitor.started_ns) / 1e9:.1f} s" for t in fall.fell_at_ns)
    return (f"**FELL** {fall.falls} time{'s' * (fall.falls != 1)} (at {when}), now "
            f"{fall.state}; {frames_down} frames while down, not scored{pushed}")


def play(robot: SoccerRobot) -> list[str]:
    """The report's rows on the game: goals, kicks, falls and get-ups, walking."""
    monitor, referee, striker = robot.monitor, robot.referee, robot.striker
    goals = ", ".join(f"{t / 1e9:.1f} s" for t in referee.goal_at_ns)
    first = (f"{monitor.first_kick_ns / 1e9:.1f} s" if monitor.first_kick_ns is not None
             else "no kick")
    return [
        f"| goals (ball over the opponent goal line between the posts) | {referee.goals}"
        f"{f' (at {goals})' if goals else ''}; own goals {referee.own_goals}, "
        f"balls out {referee.outs} |",
        f"| kicks | {monitor.kicks} ({striker.kicks if striker else 0} finished as the striker "
        f"asked) |",
        f"| time to the first kick | {first} |",
        f"| falls and get-ups | {robot.fall_detector.falls} falls, {monitor.getups} get-ups |",
        f"| distance walked (ground truth) | {monitor.walked_m:.2f} m |",
        f"| striker | {striker.state if striker else 'none'} |",
    ]


def localization(robot: SoccerRobot) -> str:
    """Which source published ``localization/pose`` and its error, for the report."""
    if robot.pose_error is None:
        return "none"
    errors = robot.pose_error.errors
    e = errors.summary()
    return (f"{errors.source}: {e['estimates']:.0f} estimates, position error mean "
            f"{_f(e['position_error_mean_m'], '.3f')} m, p95 "
            f"{_f(e['position_error_p95_m'], '.3f')} m; heading error mean "
            f"{_f(e['heading_error_mean_deg'], '.1f')}°, p95 "
            f"{_f(e['heading_error_p95_deg'], '.1f')}°")


def image_traffic(robot: SoccerRobot, container: Container) -> tuple[int, int] | None:
    """The camera image's messages through shared memory and written to DDS by this
    process (None: the transport is off here)."""
    if container.shm is None:
        return None
    traffic = container.shm.traffic().get(robot.simulator.image_pub.topic_name)
    return (0, 0) if traffic is None else (traffic.shm_sends, traffic.dds_writes)


def split_row(robot: SoccerRobot, container: Container, transport: str,
              cpu: tuple[float, float, float], *, frames: int) -> str:
    """The report's row on the split robot: how the image crossed, both processes' CPU
    and the camera's ``frames`` while the robot played (after perception was connected)."""
    body_s, perception_s, wall_s = cpu
    traffic = image_traffic(robot, container)
    crossed = ("over DDS" if traffic is None else
               f"{traffic[0]} through shared memory, {traffic[1]} also written to DDS")
    return (f"| split: perception (ball detector, JPEG compressor) in a process of its own "
            f"| {transport}; camera image {crossed}; CPU in {wall_s:.1f} s ({frames} camera "
            f"frames): body "
            f"{body_s:.2f} s, perception {perception_s:.2f} s, together "
            f"{100 * (body_s + perception_s) / max(wall_s, 1e-9):.0f} % of one core |")


def report(robot: SoccerRobot, container: Container, args: argparse.Namespace,
           wall_s: float, *, split: str | None = None) -> str:
    totals = robot.monitor.totals()
    s = totals.summary()
    sim = robot.simulator.status()
    skipped = (f" ({sim['skipped_s']:.2f} s of simulated time given up while behind)"
               if sim["skipped_s"] else "")
    lines = [
        "# Soccer demo report",
        "",
        f"Run at {datetime.now(UTC):%Y-%m-%d %H:%M:%S} UTC, "
        f"{'lockstep' if args.lockstep else 'real time'}, seed {args.seed}, "
        f"{'no DDS' if args.no_dds else 'DDS on'}.",
        "",
        "| figure | value |",
        "|---|---|",
        f"| start | robot at {','.join(f'{v:g}' for v in args.robot_pose)} (x, y, heading), "
        f"ball at {','.join(f'{v:g}' for v in args.ball)} |",
        f"| simulated time | {sim['sim_time_s']:.1f} s in {wall_s:.1f} s wall |",
        *play(robot),
        f"| real-time factor | {sim['real_time_factor']:.2f}{skipped} |",
        f"| camera frames | {totals.frames} ({s['camera_fps']:.1f} fps, "
        f"render {sim['render_ms_mean']:.1f} ms each) |",
        f"| ball detections | {totals.detections} ({s['detection_rate_hz']:.1f} Hz) |",
        f"| servo bus cycles (joint states) | {totals.joint_states} "
        f"({s['joint_state_rate_hz']:.1f} Hz) |",
        f"| ball outside the image (searching, not scored) | {totals.frames_out_of_view} "
        f"frames |",
        f"| tracking error (ball from image centre) | mean "
        f"{_f(s['tracking_error_mean_deg'], '.2f')}°, p95 "
        f"{_f(s['tracking_error_p95_deg'], '.2f')}°, max "
        f"{_f(s['tracking_error_max_deg'], '.2f')}° |",
        f"| detection error vs ground truth | p95 {_f(s['detection_error_p95_deg'], '.2f')}° |",
        f"| image -> joint command latency | median {_f(s['latency_median_ms'], '.2f')} ms, "
        f"p99 {_f(s['latency_p99_ms'], '.2f')} ms"
        f"{' (lockstep: no wall time passes)' if args.lockstep else ''} |",
        f"| servos answering | {len(robot.driver.present)} of {len(robot.driver.ids)}, "
        f"{robot.driver.comm_errors} bus errors seen by the driver |",
        f"| emulated bus | {sim['bus_crc_errors']} requests with a bad CRC, "
        f"{sim['bus_discarded_bytes']} bytes of unfinished packets dropped, "
        f"{sim['bus_dropped_replies']} replies nobody read |",
        f"| head behaviour | {robot.behaviour.state}, {robot.behaviour.switches} switches |",
        f"| posture (fall detector) | {posture(robot, totals.frames_down)} |",
        f"| localization (vs ground truth) | {localization(robot)} |",
        *([split] if split else []),
        "",
        "## Callbacks",
        "",
        "```",
        format_stats(container.stats()),
        "```",
        "",
    ]
    return "\n".join(lines)


def add_recorder(container: Container, namespace: str, bag_dir: Path, *,
                 autostart: bool = False) -> Recorder:
    """The robot's recorder, ``<namespace>/recorder``: idle until told to start (recording
    from the start with ``autostart``)."""
    recorder: Recorder = container.add(
        Recorder, name="recorder", namespace=namespace,
        parameters={"topics": RECORDED_TOPICS, "output_dir": str(bag_dir),
                    "autostart": autostart},
    )
    return recorder


def run(args: argparse.Namespace, parser: DemoArguments) -> int:
    """Play the robot as ``args`` (parsed by :func:`.demo.main`) say; the exit status."""
    pose, ball = start_positions(args.seed)
    args.robot_pose = args.robot_pose or list(pose)
    args.ball = args.ball or list(ball)
    bag_dir = args.bag_dir or Path("recordings", args.namespace.strip("/") or "root")
    stop_on_sigterm()

    clock = ManualClock() if args.lockstep else None
    started = time.monotonic()
    shm = None if args.split is None else args.split == "shm"
    with Container("soccer", namespace=args.namespace, dds=not args.no_dds, clock=clock,
                   stats_namespace=args.namespace, shm=shm) as container, \
            contextlib.ExitStack() as processes:
        try:
            robot = compose(container, namespace=args.namespace, simulator={
                "seed": args.seed, "robot_pose": args.robot_pose, "ball_position": args.ball,
                "line_noise": args.line_noise,
                "push_at": args.push_at, "push_force": [args.push_newtons, 0.0, 0.0],
            }, localization=None if args.localization == "none" else args.localization,
               perception=args.split is None)
        except HumanoidSimError as exc:  # what the parser let through and a component refused
            parser.error(str(exc))
        except ComponentError as exc:  # the container wraps what a constructor raised
            if not isinstance(exc.__cause__, HumanoidSimError):
                raise
            parser.error(str(exc.__cause__))
        add_recorder(container, args.namespace, bag_dir, autostart=args.record)
        if args.video is not None:
            try:
                sim = robot.simulator
                container.add(partial(MatchCamera, model=sim.model, data=sim.data,
                                      lock=sim.pty.lock), name="match_camera",
                              namespace=args.namespace,
                              parameters={"video_path": str(args.video)})
            except ComponentError as exc:  # a bad path or size: the camera's own one line
                if not isinstance(exc.__cause__, HumanoidSimError):
                    raise
                parser.error(f"--video: {exc.__cause__}")
        perception = None
        if args.split:
            try:
                perception = processes.enter_context(Perception(
                    namespace=args.namespace, transport=args.split,
                    config_dir=Path(processes.enter_context(TemporaryDirectory()))))
                perception.wait_connected(container)
            except ProcessError as exc:
                print(f"soccer_demo: {exc}", file=sys.stderr)
                return EXIT_BUG
        print(f"soccer demo: {robot.simulator.camera.backend if robot.simulator.camera else 'no'}"
              f" camera, servos on {robot.simulator.port}; "
              f"{'lockstep' if args.lockstep else 'real time'}, "
              f"{'until Ctrl-C' if args.duration <= 0 else f'{args.duration:g} s'}; "
              f"robot at {','.join(f'{v:g}' for v in args.robot_pose)}, "
              f"ball at {','.join(f'{v:g}' for v in args.ball)}"
              f"{f'; perception in process {perception.pid} ({args.split})' if perception else ''}")
        if args.stats_period:
            print(HEADER + (SPLIT_HEADER if perception else ""), flush=True)
        end = args.duration if args.duration > 0 else math.inf
        # Without live lines the loop still wakes every second (Ctrl-C, SIGTERM).
        period = args.stats_period or 1.0
        spin_start = time.monotonic()
        cpu_start = (time.process_time(), perception.cpu_s() if perception else 0.0)
        frames_start = robot.simulator.frames

        def elapsed() -> float:  # simulated seconds in lockstep, wall seconds in real time
            return robot.simulator.sim_time_s if args.lockstep else time.monotonic() - spin_start

        try:
            while (left := end - elapsed()) > 1e-3:
                step = min(period, left)
                if args.lockstep:
                    container.advance(step)
                else:
                    container.spin_for(step)
                if args.stats_period:
                    traffic = image_traffic(robot, container) if perception else None
                    extra = (f" {traffic[1] if traffic else '-':>7}" if perception else "")
                    print(live_line(robot, robot.monitor.window()) + extra, flush=True)
        except KeyboardInterrupt:
            print("interrupted")
        split = None
        perception_alive = True
        if perception is not None:
            perception_alive = perception.alive()
            if not perception_alive:  # a bug: exit status 1
                print(f"soccer_demo: the perception process ended during the run; its last "
                      f"words: {' | '.join(list(perception.lines)[-3:]) or 'none'}",
                      file=sys.stderr)
            cpu = (time.process_time() - cpu_start[0],
                   perception.cpu_s() - cpu_start[1] if perception_alive else math.nan,
                   time.monotonic() - spin_start)
            split = split_row(robot, container, args.split, cpu,
                              frames=robot.simulator.frames - frames_start)
            perception.close()
        text = report(robot, container, args, time.monotonic() - started, split=split)
        failures = sum(s.exceptions for s in container.stats())
        # A failing callback or an exception inside the emulator is a bug: exit status 1.
        ok = (robot.monitor.totals().detections > 0 and failures == 0
              and not robot.simulator.pty.errors and perception_alive)
        down = robot.fall_detector.falls > 0 and robot.fall_detector.state != "standing"
    args.report.parent.mkdir(parents=True, exist_ok=True)
    args.report.write_text(text)
    print(f"\n{text}\nreport written to {args.report.resolve()}")
    if not ok:
        why = [what for what, bad in (
            ("the robot detected no ball", not robot.monitor.totals().detections),
            (f"{failures} callbacks failed (the report's exc column)", failures),
            (f"the servo bus emulator failed: {robot.simulator.pty.errors[:1]}",
             robot.simulator.pty.errors),
            ("the perception process ended", not perception_alive)) if bad]
        print(f"soccer_demo: a bug (exit status 1): {'; '.join(why)}", file=sys.stderr)
        return EXIT_BUG
    if down:
        print("the robot fell and did not get up (exit status 3)")
        return EXIT_FELL
    return EXIT_OK

