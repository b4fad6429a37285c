"""What the team match costs: CPU per robot split into physics, rendering, bus emulation and
robot software, and the real-time factor, for 1, 3 and 6 robots, in real time and in lockstep.

Each run is the match as a user starts it (``python -m humanoid_sim.match --robots R
--duration D [--lockstep]``: one world process, one process per robot), for ``1v0`` (one
robot in the match's processes), ``3`` (one team) and ``3v3``, each in real time (``D`` wall
seconds) and in lockstep (``--lockstep-duration`` simulated seconds), ``--repeat`` times
interleaved, so drifting machine load hits all sizes alike; medians printed. It reads the
match's report:

* the world process's CPU split (``World CPU s``: physics, render with the rasteriser's
  threads, bus emulation, the rest: DDS sensor links, referee, the barrier) divided by the
  robots;
* each robot process's CPU (its software: driver, vision, behaviour, walk, team link,
  recorder, the camera and IMU it takes from DDS, its end of the barrier);
* the real-time factor, the world's tick rate and the IMU rate each robot heard (a starved
  robot hears fewer than the world sends, and falls), falls.

CPU is given in ms per simulated second per robot (1000 = one core at real time). In real
time, physics, render and the world's rest follow the world's steps (per simulated second),
bus emulation and robot software the robots' wall-clock timers (per wall second: a world
slowed to a real-time factor of 0.1 does not make a robot cheaper), so the sum is what a
robot needs at real time. In lockstep everything follows the steps: the robots' CPU is
their share of a core divided by the world's steps a wall second, which, unlike the
real-time factor, hardly depends on the machine's load. Ratios are against the one-robot
real-time match of the same run. Run: ``source scripts/env.sh && python
bench/match_bench.py`` (``--quick``: one short one-robot match each way, a smoke test).
"""

from __future__ import annotations

import argparse
import json
import os
import re
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_OUT = ROOT / "bench" / "out" / "match_bench.json"
SIZES = {"1v0": 1, "3": 3, "3v3": 6}
PARTS = ("physics", "render", "bus", "world_other", "robot_software")
STEP_HZ = 100.0  # the match world's physics steps a simulated second

_WORLD_CPU = re.compile(r"World CPU s: physics ([\d.]+), render ([\d.]+), bus ([\d.]+), "
                        r"other ([\d.]+); ticks (\d+)")
_TIMES = re.compile(r"([\d.]+) s wall, ([\d.]+) s simulated, real-time factor ([\d.]+)")
_IMU = re.compile(r"ticks ([\d.]+), one message per robot each\) and CPU % of a core: (.*)\.")
_ROW = re.compile(r"^\| (\w+) \| ([^|]+) \|(?:[^|]*\|){3} (\d+) \|(?:[^|]*\|){3} (\d+) \|$")


def parse_report(text: str, robots: int, *, lockstep: bool = False) -> dict[str, Any]:
    """The figures of one match report; ValueError if it lacks one."""
    times, cpu, imu = _TIMES.search(text), _WORLD_CPU.search(text), _IMU.search(text)
    if not (times and cpu and imu):
        raise ValueError(f"not a match report with CPU figures:\n{text}")
    wall, sim, rtf = (float(g) for g in times.groups())
    # The world's parts count from its first tick, the robots' from when each was ready
    # (start-ups left out).
    rows = [m for line in text.splitlines() if (m := _ROW.match(line))]
    if len(rows) != robots:
        raise ValueError(f"{len(rows)} robot rows, expected {robots}:\n{text}")
    robot = re.findall(r"(\w+) ([\d.]+) Hz ([\d.]+) %", imu.group(2))
    if sim <= 0 or rtf <= 0 or len(robot) != robots:
        raise ValueError(f"the match did not run (no simulated time, or robots not ready):"
                         f"\n{text}")
    share = sum(float(pct) / 100 for _, _, pct in robot)  # of a core, since ready
    per_robot = {
        "physics": float(cpu[1]), "render": float(cpu[2]),
        "bus": float(cpu[3]) * (1.0 if lockstep else rtf),
        "world_other": float(cpu[4]),
        # Real time: wall-clock driven (robots' timers, their drivers' packets the bus
        # answers): per wall second, i.e. per simulated second at real time, whatever the
        # world's pace. Lockstep: per step, the world's steps a wall second being its ticks.
        "robot_software": (share / float(imu[1]) * STEP_HZ * sim if lockstep
                           else share * sim),
    }
    return {
        "wall_s": wall, "sim_s": sim, "rtf": rtf, "ticks": int(cpu[5]),
        # CPU ms per simulated second per robot
        **{k: v * 1e3 / sim / robots for k, v in per_robot.items()},
        "tick_hz": float(imu[1]),
        "imu_hz_min": min(float(hz) for _, hz, _ in robot),
        "falls": sum(int(r[3]) for r in rows),
        "ended": sum(r[2].strip() != "ran to the end" for r in rows),
    }


def run_match(robots: str, *, duration_s: float, camera_hz: float, lockstep: bool = False,
              transport: str = "shm") -> dict[str, Any]:
    with tempfile.TemporaryDirectory(prefix="match_bench_") as tmp:
        report = Path(tmp, "report.md")
        load = os.getloadavg()[0]
        subprocess.run(
            [sys.executable, "-m", "humanoid_sim.match", "--robots", robots, "--duration",
             str(duration_s), "--camera-hz", str(camera_hz), "--stats-period", "5",
             "--ready-s", "1", "--out-dir", tmp, "--report", str(report),
             "--camera-transport", transport]
            + (["--lockstep"] if lockstep else []),
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
            timeout=duration_s * (300 if lockstep else 1) + 300, check=False)
        if not report.exists():
            raise SystemExit(f"match_bench: the match ({robots}) wrote no report")
        figures = parse_report(report.read_text(), SIZES[robots], lockstep=lockstep)
    figures["load"] = (load, os.getloadavg()[0])
    return figures


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0] if __doc__ else None)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--duration", type=float, default=40.0,
                    help="wall seconds per real-time match")
    ap.add_argument("--lockstep-duration", type=float, default=4.0,
                    help="simulated seconds per lockstep match (0: no lockstep runs)")
    ap.add_argument("--camera-hz", type=float, default=30.0)
    ap.add_argument("--sizes", default=",".join(SIZES),
                    help=f"--robots values, comma-separated (default {','.join(SIZES)})")
    ap.add_argument("--camera-transport", default="shm",
                    help="how the camera images reach the robots, shm or dds, or both "
                    "(shm,dds: a row each, the DDS one named \"<size> dds\") (default shm)")
    ap.add_argument("--quick", action="store_true",
                    help="one short one-robot match in real time and one in lockstep")
    ap.add_argument("--out", type=Path, default=DEFAULT_OUT)
    args = ap.parse_args()
    sizes = args.sizes.split(",")
    if args.quick:
        args.repeat, args.duration, args.lockstep_duration, sizes = 1, 20.0, 1.0, ["1v0"]
    unknown = [s for s in sizes if s not in SIZES]
    if unknown:
        ap.error(f"--sizes: {', '.join(unknown)} not among {', '.join(SIZES)}")
    transports = args.camera_transport.split(",")
    if bad := [t for t in transports if t not in ("shm", "dds")]:
        ap.error(f"--camera-transport: {', '.join(bad)} is not shm or dds")
    kinds = [(size, False, t) for size in sizes for t in transports]
    if args.lockstep_duration > 0:
        kinds += [(size, True, t) for size in sizes for t in transports]
    runs: dict[str, list[dict[str, Any]]] = {_key(*k): [] for k in kinds}
    for _ in range(args.repeat):  # interleaved
        for size, lockstep, transport in kinds:
            runs[_key(size, lockstep, transport)].append(run_match(
                size, duration_s=args.lockstep_duration if lockstep else args.duration,
                camera_hz=args.camera_hz, lockstep=lockstep, transport=transport))

    def med(key: str, part: str) -> float:
        return float(statistics.median(r[part] for r in runs[key]))

    base = _key(*kinds[0])
    loads = [x for rs in runs.values() for r in rs for x in r["load"]]
    print(f"medians of {args.repeat} run(s) (real time: {args.duration:g} s wall; lockstep: "
          f"{args.lockstep_duration:g} s simulated), cameras at {args.camera_hz:g} Hz; load "
          f"average {min(loads):.1f} to {max(loads):.1f}; CPU ms per simulated second per "
          f"robot (real time: bus and robot software per wall s; 1000 = one core), ratio "
          f"against {base}")
    print("robots | physics | render | bus | world other | robot software | total (x) | "
          "RTF | world ticks Hz | IMU heard Hz (lowest) | falls")
    summary: dict[str, Any] = {}
    base_total = sum(med(base, k) for k in PARTS)
    for key in runs:
        row = {k: med(key, k) for k in (*PARTS, "rtf", "tick_hz", "imu_hz_min", "falls")}
        row["total"] = sum(row[k] for k in PARTS)
        row["total_ratio"] = row["total"] / base_total if base_total else 0.0
        summary[key] = row
        print(f"{key:>12} | " + " | ".join(f"{row[k]:6.0f}" for k in PARTS)
              + f" | {row['total']:6.0f} ({row['total_ratio']:.2f}) | {row['rtf']:.2f} | "
              f"{row['tick_hz']:5.1f} | {row['imu_hz_min']:5.1f} | {row['falls']:g}")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({"summary": summary, "runs": runs}, indent=1))
    return 0


def _key(size: str, lockstep: bool, transport: str = "shm") -> str:
    """A row's name: the --robots value, " lockstep" for lockstep runs, " dds" for the
    camera images over DDS."""
    return size + (" lockstep" if lockstep else "") + (" dds" if transport == "dds" else "")


if __name__ == "__main__":
    sys.exit(main())
