"""Clock offsets and merging: accuracy of the estimate, alignment after merge, merge speed.

Three figures, each against a baseline measured in the same run:

* ``accuracy``: a simulated team (reference; ``a`` +250 ms, +50 ppm, linked to it; ``b``
  -400 ms, -50 ppm, linked only to ``a``) over links with a fixed latency plus exponential
  queueing delay each way and 20 % loss per message. Every 0.25 s from 10 s to 60 s the
  error of each robot's team time is taken. Baseline: Cristian's method on the same
  exchanges (the offset of the latest round trip alone, no filtering, no drift).
  Also: how often the stated uncertainty covered the error (must be 100 %).
* ``alignment``: the same team records "flash" events seen by all robots at one instant,
  each log on its own clock; after ``merge`` the spread of each event's times across robots.
  Baseline: the unmerged logs' spread.
* ``merge``: messages per second merging three logs in team time (with header stamps),
  against copying the same messages from the three logs into one MCAP without alignment.

Run: ``source scripts/env.sh && python bench/clock_bench.py`` (``--quick`` for a smoke run).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from geometry_msgs.msg import PointStamped
from mcap.reader import make_reader
from mcap.writer import Writer
from rclpy.serialization import serialize_message

from efficient_comm import to_msg
from rosbag2_layout import BagWriter
from team_clock.merge import RobotLog, merge
from team_clock.testing import SimDelay, SimTeam, flash_times
from team_clock_interfaces.msg import ClockOffset

MS = 1_000_000
SKEWS = {"ref": (1000 * MS, 0.0), "a": (250 * MS, 50.0), "b": (-400 * MS, -50.0)}
LINKS = [("ref", "a"), ("a", "b")]
NETWORKS = {"lan": SimDelay(min_s=0.0002, jitter_s=0.0002),
            "wifi": SimDelay(min_s=0.001, jitter_s=0.002)}


def _percentile(values: list[float], q: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, round(q * (len(ordered) - 1)))]


def accuracy(network: str, seed: int, seconds: float) -> dict[str, Any]:
    team = SimTeam(SKEWS, reference="ref", links=LINKS, delay=NETWORKS[network], loss=0.2,
                   seed=seed)
    team.advance(10.0)
    ours: dict[str, list[float]] = {"a": [], "b": []}
    cristian: dict[str, list[float]] = {"a": [], "b": []}
    uncertainty: dict[str, list[float]] = {"a": [], "b": []}
    covered = total = 0
    for _ in range(round((seconds - 10.0) / 0.25)):
        team.advance(0.25)
        for robot in ours:
            err, unc = team.error_ns(robot), team.uncertainty_ns(robot)
            state = team.syncs[robot].state
            if err is None or unc is None or state is None:
                continue
            total += 1
            covered += abs(err) <= unc
            ours[robot].append(abs(err))
            uncertainty[robot].append(unc)
            # Cristian: the latest round trip of the same source, taken as it is.
            last = team.syncs[robot].estimators[state.source].newest
            if last is not None:
                local = team.clocks[robot].now_ns()
                cristian[robot].append(abs(local + last.offset_ns - team.reference_now()))
    out: dict[str, Any] = {"kind": "accuracy", "network": network, "seed": seed,
                           "covered": covered / max(total, 1)}
    for robot in ours:
        out[robot] = {
            "median_us": statistics.median(ours[robot]) / 1e3,
            "p99_us": _percentile(ours[robot], 0.99) / 1e3,
            "cristian_median_us": statistics.median(cristian[robot]) / 1e3,
            "cristian_p99_us": _percentile(cristian[robot], 0.99) / 1e3,
            "uncertainty_median_us": statistics.median(uncertainty[robot]) / 1e3,
        }
    return out


def alignment(network: str, seed: int, seconds: float, tmp: Path) -> dict[str, Any]:
    team = SimTeam(SKEWS, reference="ref", links=LINKS, delay=NETWORKS[network], loss=0.2,
                   seed=seed)
    directory = tmp / f"{network}_{seed}"
    paths, _ = team.record_flashes(directory, events=round((seconds - 10.0) * 2), seed=seed)
    merged = directory / "merged"
    merge([RobotLog(p) for p in paths.values()], merged, stamps=True)

    def spreads(by_robot: list[dict[str, tuple[int, int]]]) -> list[float]:
        events = set.intersection(*(set(v) for v in by_robot))
        return [max(v[e][0] for v in by_robot) - min(v[e][0] for v in by_robot)
                for e in events]

    after = spreads(list(flash_times(merged).values()))
    before = spreads([flash_times(p)[""] for p in paths.values()])
    return {"kind": "alignment", "network": network, "seed": seed, "events": len(after),
            "max_spread_us": max(after) / 1e3, "median_spread_us": statistics.median(after) / 1e3,
            "unmerged_median_spread_us": statistics.median(before) / 1e3}


def _synthetic_logs(tmp: Path, messages: int) -> list[Path]:
    paths = []
    for i, robot in enumerate(("ref", "a", "b")):
        path = tmp / f"synthetic_{robot}"
        with BagWriter(path, min_free_bytes=0) as w:
            offsets = ("/team_clock/offset", "team_clock_interfaces/msg/ClockOffset")
            events = ("/points", "geometry_msgs/msg/PointStamped")
            start = 1_700_000_000_000_000_000 + i * 250 * MS
            for s in range(messages // 100 + 1):
                msg = ClockOffset(robot=robot, reference="ref", offset_ns=-i * 250 * MS,
                                  valid=True, uncertainty_ns=1000)
                msg.stamp = to_msg(start + s * 1_000_000_000)
                w.write(*offsets, serialize_message(msg), start + s * 1_000_000_000)
            point = PointStamped()
            point.header.frame_id = "base_link"
            for n in range(messages):
                t = start + n * 10 * MS
                point.header.stamp = to_msg(t)
                w.write(*events, serialize_message(point), t)
        paths.append(path)
    return paths


def merge_speed(messages: int, tmp: Path, run: int) -> dict[str, Any]:
    logs = _synthetic_logs(tmp / f"speed{run}", messages)
    t0 = time.perf_counter()
    report = merge([RobotLog(p) for p in logs], tmp / f"speed{run}_merged", stamps=True)
    merged_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    copied = 0
    with open(tmp / f"speed{run}_copy.mcap", "wb") as f:
        writer = Writer(f)
        writer.start(profile="ros2", library="bench")
        channels: dict[tuple[int, int], int] = {}
        for index, path in enumerate(logs):
            with open(path / f"{path.name}_0.mcap", "rb") as stream:
                for schema, channel, message in make_reader(stream).iter_messages(
                        log_time_order=False):
                    key = (index, channel.id)
                    if key not in channels:
                        assert schema is not None
                        sid = writer.register_schema(schema.name, schema.encoding, schema.data)
                        channels[key] = writer.register_channel(
                            f"/r{index}{channel.topic}", "cdr", sid, dict(channel.metadata))
                    writer.add_message(channels[key], log_time=message.log_time,
                                       data=message.data, publish_time=message.publish_time)
                    copied += 1
        writer.finish()  # type: ignore[no-untyped-call]
    copy_s = time.perf_counter() - t0
    return {"kind": "merge", "run": run, "messages": report.messages,
            "merge_msgs_per_s": report.messages / merged_s, "copy_msgs_per_s": copied / copy_s}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seeds", type=int, default=5)
    parser.add_argument("--seconds", type=float, default=60.0)
    parser.add_argument("--messages", type=int, default=20_000, help="per log, merge speed")
    parser.add_argument("--repeat", type=int, default=3, help="runs of the merge speed")
    parser.add_argument("--quick", action="store_true", help="a short smoke run")
    parser.add_argument("--out", type=Path,
                        default=Path(__file__).with_name("out") / "clock_bench.json")
    args = parser.parse_args()
    if args.quick:
        args.seeds, args.seconds, args.messages, args.repeat = 1, 20.0, 2000, 1
    started = time.perf_counter()
    results: list[dict[str, Any]] = []
    with tempfile.TemporaryDirectory() as tmp_name:
        tmp = Path(tmp_name)
        for network in NETWORKS:
            for seed in range(args.seeds):
                results.append(accuracy(network, seed, args.seconds))
                results.append(alignment(network, seed, args.seconds, tmp))
                print(f"[{network} seed {seed}] ok", file=sys.stderr)
        for run in range(args.repeat):
            results.append(merge_speed(args.messages, tmp, run))
    meta = {"date": time.strftime("%Y-%m-%dT%H:%M:%S%z"), "python": platform.python_version(),
            "platform": platform.platform(), "cpu_count": os.cpu_count(), "seeds": args.seeds,
            "seconds": args.seconds, "quick": args.quick,
            "elapsed_s": round(time.perf_counter() - started, 1)}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({"meta": meta, "results": results}, indent=1))
    report(results)
    return 0


def report(results: list[dict[str, Any]]) -> None:
    med = statistics.median
    print("\nteam-time error, median over seeds of each run's median / p99 (µs); "
          "baseline = Cristian (latest round trip only)")
    print(f"{'network':<8} {'robot':<6} {'ours med':>9} {'ours p99':>9} {'Crist med':>10} "
          f"{'Crist p99':>10} {'p99 ratio':>10} {'bound med':>10} {'covered':>8}")
    for network in NETWORKS:
        runs = [r for r in results if r["kind"] == "accuracy" and r["network"] == network]
        for robot in ("a", "b"):
            ours_p99 = med([r[robot]["p99_us"] for r in runs])
            crist_p99 = med([r[robot]["cristian_p99_us"] for r in runs])
            print(f"{network:<8} {robot:<6} {med([r[robot]['median_us'] for r in runs]):>9.0f} "
                  f"{ours_p99:>9.0f} {med([r[robot]['cristian_median_us'] for r in runs]):>10.0f} "
                  f"{crist_p99:>10.0f} {crist_p99 / ours_p99:>9.1f}x "
                  f"{med([r[robot]['uncertainty_median_us'] for r in runs]):>10.0f} "
                  f"{min(r['covered'] for r in runs):>8.0%}")
    print("\nsimultaneous events after merge: spread across robots (µs)")
    for network in NETWORKS:
        runs = [r for r in results if r["kind"] == "alignment" and r["network"] == network]
        print(f"{network:<8} median {med([r['median_spread_us'] for r in runs]):8.0f}   "
              f"worst {max(r['max_spread_us'] for r in runs):8.0f}   unmerged median "
              f"{med([r['unmerged_median_spread_us'] for r in runs]):10.0f}   "
              f"({sum(r['events'] for r in runs)} events, {len(runs)} seeds)")
    runs = [r for r in results if r["kind"] == "merge"]
    merged, copied = med([r["merge_msgs_per_s"] for r in runs]), med([r["copy_msgs_per_s"]
                                                                       for r in runs])
    print(f"\nmerge {merged:,.0f} msg/s vs plain copy {copied:,.0f} msg/s "
          f"({merged / copied:.2f}x of copy; median of {len(runs)} runs)")


if __name__ == "__main__":
    sys.exit(main())
