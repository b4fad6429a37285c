"""Event detection over a team log: how long every built-in generator takes, against just
reading the same log with rosbags (issue 21 point 6: a 10-minute six-robot log in at most
10 % of its duration).

The log is written once per run: ``--robots`` robots for ``--minutes`` minutes with the
topics and rates a match records (humanoid_sim's ``ROBOT_TOPICS``: JPEG images at 2 Hz,
statistics, poses, the ball, team messages, IMU and joint states thinned) and the world's
ground truth at 100 Hz, merged-log-shaped (``/blue1/...``, ``/world/...``). Each robot falls
once a minute and flips its role in bursts, so the generators have something to find.

Figures (median of ``--repeat`` runs):

* ``read rosbags``: every message of the log read raw with rosbags' AnyReader (the floor
  for any tool that looks at the whole log);
* ``read ours``: the same with rosbag2_layout's BagReader;
* ``detect``: ``log_analysis.detect`` with every built-in generator (reads only the topics
  they need, decodes each of those messages once);
* ``detect 1 min``: the same over a one-minute window in the middle of the log (seeking).

Run: ``source scripts/env.sh && python bench/events_bench.py`` (``--quick`` for a smoke run).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import statistics
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import PointStamped, PoseStamped, PoseWithCovarianceStamped, Twist
from rclpy.serialization import serialize_message
from rosbags.highlevel import AnyReader
from sensor_msgs.msg import CompressedImage, Imu, JointState
from std_msgs.msg import String

from efficient_comm_interfaces.msg import CallbackStats, ExecutorStats
from log_analysis import TeamLog, detect, load_generators
from rosbag2_layout import BagReader, BagWriter, type_name
from soccer_interfaces.msg import GameState, TeamInfo, TeamMessage

NS = 1_000_000_000


def _pose(x: float, y: float, yaw: float) -> PoseWithCovarianceStamped:
    msg = PoseWithCovarianceStamped()
    msg.pose.pose.position.x, msg.pose.pose.position.y = x, y
    msg.pose.pose.orientation.z, msg.pose.pose.orientation.w = math.sin(yaw / 2), math.cos(yaw / 2)
    return msg


def _stats(i: int) -> ExecutorStats:
    return ExecutorStats(window_ns=NS, callbacks=[
        CallbackStats(node=f"/node{k}", name=f"cb{k}", calls=100, max_ns=(12 if i % 30 == k
                                                                           else 4) * 1_000_000,
                      period_ns=10_000_000 if k % 2 else 0) for k in range(12)])


def write_log(path: Path, *, robots: int, minutes: float) -> int:
    """The log at ``path``; returns how many messages it holds."""
    names = [f"blue{i}" for i in range(1, 4)][:robots] + \
        [f"red{i}" for i in range(1, 4)][:max(0, robots - 3)]
    fixed: dict[str, tuple[str, bytes]] = {}

    def once(msg: Any) -> tuple[str, bytes]:
        key = repr(msg)
        if key not in fixed:
            fixed[key] = (type_name(type(msg)), bytes(serialize_message(msg)))
        return fixed[key]

    image = once(CompressedImage(format="jpeg", data=bytes(20_000)))
    diag = once(DiagnosticArray(status=[DiagnosticStatus(name=f"servo{k}") for k in range(20)]))
    joints = once(JointState(name=[f"j{k}" for k in range(20)], position=[0.0] * 20,
                             velocity=[0.0] * 20, effort=[0.0] * 20))
    imu, twist, point = once(Imu()), once(Twist()), once(PointStamped())
    truth = once(PoseStamped())
    # (topic, rate Hz, message maker of the tick) for each robot.
    per_robot: list[tuple[str, float, Callable[[str, int], tuple[str, bytes]]]] = [
        ("camera/image_raw/compressed", 2, lambda r, i: image),
        ("efficient_comm/stats", 1, lambda r, i: once(_stats(i))),
        ("diagnostics", 2, lambda r, i: diag),
        ("localization/pose", 10, lambda r, i: once(_pose((i % 40) / 10, 0.0, 0.0))),
        ("ball/detection", 4, lambda r, i: point),
        ("ball/estimate", 4, lambda r, i: point),
        ("ball/position", 4, lambda r, i: once(PointStamped())),
        ("team_ball", 8, lambda r, i: once(PoseWithCovarianceStamped())),
        ("cmd_vel", 8, lambda r, i: twist),
        ("team/messages", 2 * min(3, robots), lambda r, i: once(TeamMessage(
            player_number=i % 3 + 1))),
        ("ground_truth/pose", 10, lambda r, i: truth),
        ("ground_truth/ball", 10, lambda r, i: truth),
        ("joint_states", 10, lambda r, i: joints),
        ("imu/data", 20, lambda r, i: imu),
        ("game_state", 2, lambda r, i: once(GameState(teams=[TeamInfo(), TeamInfo()]))),
        # A fall a minute, a burst of role flips every 40 s.
        ("fall/state", 0.5, lambda r, i: once(String(data="fallen" if i % 30 == 5
                                                     else "standing"))),
        ("role", 1, lambda r, i: once(String(data="striker" if (i % 40 < 6 and i % 2)
                                             else "supporter"))),
    ]
    world: list[tuple[str, float, Callable[[str, int], tuple[str, bytes]]]] = [
        *[(f"ground_truth/{r}/pose", 100, lambda r, i: truth) for r in names],
        ("ground_truth/ball", 100, lambda r, i: truth),
        ("game_state", 2, lambda r, i: once(GameState(teams=[
            TeamInfo(team_colour=0, score=i // 120), TeamInfo(team_colour=1)]))),
    ]
    schedule = [(f"/{r}/{t}", rate, make, r) for r in names for t, rate, make in per_robot]
    schedule += [(f"/world/{t}", rate, make, "world") for t, rate, make in world]
    count = 0
    end_ns = int(minutes * 60 * NS)
    # Interleaved by time, as a recorder writes: one 100 ms slice of every topic at a time.
    slice_ns = NS // 10
    with BagWriter(path, min_free_bytes=0) as writer:
        for start in range(0, end_ns, slice_ns):
            for topic, rate, make, robot in schedule:
                period = int(NS / rate)
                first = -(-start // period) * period
                for t in range(first, min(start + slice_ns, end_ns), period):
                    kind, data = make(robot, t // period)
                    writer.write(topic, kind, data, NS + t)
                    count += 1
    return count


def _timed(fn: Callable[[], Any]) -> tuple[float, Any]:
    t0 = time.perf_counter()
    result = fn()
    return time.perf_counter() - t0, result


def read_rosbags(path: Path) -> int:
    with AnyReader([path]) as reader:
        return sum(1 for _ in reader.messages())


def read_ours(path: Path) -> int:
    return sum(1 for _ in BagReader(path).messages())


def run_once(path: Path, minutes: float, run: int) -> dict[str, Any]:
    rosbags_s, rosbags_n = _timed(lambda: read_rosbags(path))
    ours_s, ours_n = _timed(lambda: read_ours(path))
    detect_s, found = _timed(lambda: detect(TeamLog(path), load_generators()))
    middle = NS + int(minutes * 30 * NS)
    window_s, windowed = _timed(lambda: detect(TeamLog(path), load_generators(),
                                               start_ns=middle, end_ns=middle + 60 * NS))
    return {"run": run, "messages": rosbags_n, "ours_messages": ours_n,
            "read_rosbags_s": rosbags_s, "read_ours_s": ours_s, "detect_s": detect_s,
            "detect_window_s": window_s, "events": len(found.events),
            "window_events": len(windowed.events), "decoded": found.messages,
            "failures": found.failures,
            "by_name": {name: sum(1 for e in found.events if e.name == name)
                        for name in sorted({e.name for e in found.events})}}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--robots", type=int, default=6, choices=range(1, 7))
    parser.add_argument("--minutes", type=float, default=10.0)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--quick", action="store_true", help="a short smoke run")
    parser.add_argument("--out", type=Path,
                        default=Path(__file__).with_name("out") / "events_bench.json")
    args = parser.parse_args()
    if args.quick:
        args.robots, args.minutes, args.repeat = 2, 1.0, 1
    started = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "log"
        write_s, written = _timed(lambda: write_log(path, robots=args.robots,
                                                    minutes=args.minutes))
        print(f"wrote {written:,} messages ({args.robots} robots, {args.minutes:g} min) in "
              f"{write_s:.1f} s", file=sys.stderr)
        results = [run_once(path, args.minutes, run) for run in range(args.repeat)]
    meta = {"date": time.strftime("%Y-%m-%dT%H:%M:%S%z"), "python": platform.python_version(),
            "platform": platform.platform(), "cpu_count": os.cpu_count(),
            "load": os.getloadavg()[0], "robots": args.robots, "minutes": args.minutes,
            "quick": args.quick, "elapsed_s": round(time.perf_counter() - started, 1)}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({"meta": meta, "results": results}, indent=1))
    report(results, args.minutes, meta)
    return 0


def report(results: list[dict[str, Any]], minutes: float, meta: dict[str, Any]) -> None:
    med = statistics.median
    log_s = minutes * 60
    rosbags, ours = med(r["read_rosbags_s"] for r in results), med(r["read_ours_s"]
                                                                    for r in results)
    found, window = med(r["detect_s"] for r in results), med(r["detect_window_s"]
                                                              for r in results)
    last = results[-1]
    print(f"\nevent detection over a {minutes:g}-minute log of {meta['robots']} robots "
          f"({last['messages']:,} messages; median of {len(results)} runs, load "
          f"{meta['load']:.1f})")
    print(f"{'':14}{'seconds':>9}{'of log':>9}{'vs rosbags':>12}")
    for label, s in (("read rosbags", rosbags), ("read ours", ours), ("detect", found),
                     ("detect 1 min", window)):
        print(f"{label:14}{s:9.2f}{s / log_s:9.1%}{s / rosbags:11.2f}x")
    print(f"target: detect <= 10 % of the log's duration: {found / log_s:.1%} "
          f"({'met' if found / log_s <= 0.10 else 'NOT met'})")
    print(f"events: {last['events']} ({', '.join(f'{k} {v}' for k, v in last['by_name'].items())}"
          f"); {last['decoded']:,} messages decoded; failures: {last['failures'] or 'none'}")


if __name__ == "__main__":
    sys.exit(main())
