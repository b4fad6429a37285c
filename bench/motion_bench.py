"""Kicking, measured: success over seeds, the ball's distance and angle, cost per control cycle.

Every trial runs the kicking rig (``humanoid_sim.soccer.kick_rig``: simulator, the real servo
driver on the emulated bus, fall detector, walk engine, kick and motion arbiter) on a manual
clock, each in a fresh child process (``--jobs`` at a time). A seed chooses the kicking foot
(even seeds right, odd left), where the ball lies (up to ``--jitter`` m off its spot in x and
y, as an approach leaves it), how long the robot stands first (1 to 1.5 s) and the bus's
line noise pattern (``--line-noise``, default 1 %). ``--plant`` runs the kick on the MuJoCo
plant without driver and bus (``kick_rig.plant_kick_trial``), for tuning; there ``--shove``
shoves the torso sideways for 0.1 s while the robot stands on one foot (the seed draws when,
1.0 to 2.0 s into the kick, and which way).

* ``kick``: ``--seeds`` trials, the ball followed until it rests (at most ``--seconds``);
  prints each trial and the share that succeeded (ball >= 0.3 m within ±15° of straight ahead,
  robot standing) against the 80 % target, the median distance, angle and ball speed, and
  the servos' peak torque and speed against the XM430-W350's;
* ``cost``: µs per callback of the kick's timer and of the arbiter's callbacks while the
  robot kicks (the one that forwards the kick's goals alone, all of them, and all of them
  per 10 ms control cycle), from the container's callback statistics, against the driver's
  cycle in the same run.

Run: ``source scripts/env.sh && python bench/motion_bench.py`` (``--quick`` for a smoke run).
"""

from __future__ import annotations

import argparse
import json
import random
import statistics
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # run as a script: the repo root holds the bench package
from bench._children import run_child as run_json_child  # noqa: E402

DEFAULT_OUT = ROOT / "bench" / "out" / "motion_bench.json"
TARGET_SUCCESS = 0.8
DISTANCE_M, ANGLE_DEG = 0.3, 15.0  # on turf-like rolling friction (docs/HUMANOID_SIM.md)
STALL_TORQUE_NM, NO_LOAD_RAD_S = 4.1, 4.817


def _setup(seed: int, jitter: float, shove: float
           ) -> tuple[str, tuple[float, float], float, tuple[float, tuple[float, float, float]]]:
    rng = random.Random(seed)
    side = "right" if seed % 2 == 0 else "left"
    dx, dy = rng.uniform(-jitter, jitter), rng.uniform(-jitter, jitter)
    settle = round(1.0 + rng.uniform(0.0, 0.5), 2)
    # A sideways shove while on one foot (1.0 to 2.0 s into the kick), either way.
    at, force = round(rng.uniform(1.0, 2.0), 2), shove * rng.choice((-1.0, 1.0))
    return side, (dx, dy), settle, (at, (0.0, force, 0.0))


def trial(seed: int, seconds: float, line_noise: float, jitter: float,
          plant: bool, shove: float) -> dict[str, Any]:
    """One kick in this process (the child's side)."""
    from efficient_comm.testing import test_container
    from humanoid_sim.soccer.kick_rig import ball_spot, compose_kicker, kick_trial, plant_kick_trial

    side, (dx, dy), settle, push = _setup(seed, jitter, shove)
    ball = ball_spot(side, dx=dx, dy=dy)
    started = time.perf_counter()
    if plant:
        r = plant_kick_trial(side, ball=ball, settle_s=settle, seconds=seconds,
                             shove=push if shove else None)
    else:
        with test_container(guard_mutation=False) as container:
            robot = compose_kicker(container, simulator={
                "seed": seed, "line_noise": line_noise, "ball_position": list(ball)})
            r = kick_trial(container, robot, side, settle_s=settle, seconds=seconds)
    return {"seed": seed, "side": side, "ball_offset": [dx, dy], "distance_m": r.distance_m,
            "angle_deg": r.angle_deg, "ball_speed": r.ball_speed, "fell_at_s": r.fell_at_s,
            "completed": r.completed, "success": r.success(), "seconds": r.seconds,
            "shove": [push[0], push[1][1]] if plant and shove else None,
            "peak_torque": r.peak_torque, "peak_speed": r.peak_speed,
            "wall_s": time.perf_counter() - started}


def cost() -> dict[str, float]:
    """Callback costs while kicking, from the container's statistics (deltas over the kick)."""
    from std_msgs.msg import String

    from efficient_comm.testing import TestHandle, test_container
    from humanoid_sim.soccer.kick_rig import ball_spot, compose_kicker

    with test_container(guard_mutation=False) as container:
        robot = compose_kicker(container,
                               simulator={"ball_position": list(ball_spot("right"))})
        container.advance(1.0)
        before = {(s.node, s.kind, s.name): (s.calls, s.total_ns) for s in container.stats()}
        probe = TestHandle("probe", container=container)
        probe.create_publisher(String, "/robot/motion/kick/request", qos=10).publish(
            String(data="right"))
        container.advance(0.05)
        while robot.kick.active:
            container.advance(0.1)
        after = list(container.stats())

    def delta(node: str, kinds: tuple[str, ...], name: str = "") -> tuple[int, int]:
        calls = total = 0
        for s in after:
            if s.node.endswith(node) and s.kind in kinds and s.name.endswith(name):
                c0, t0 = before.get((s.node, s.kind, s.name), (0, 0))
                calls += s.calls - c0
                total += s.total_ns - t0
        return calls, total

    def per_call(node: str, kinds: tuple[str, ...], name: str = "") -> float:
        calls, total = delta(node, kinds, name)
        return total / calls / 1e3 if calls else 0.0

    kick_calls, _ = delta("/kick", ("timer",))
    _, arbiter_total = delta("/motion", ("timer", "subscription"))
    return {"kick_callback_us": per_call("/kick", ("timer",)),
            "arbiter_forward_us": per_call("/motion", ("subscription",), "motion/kick"),
            "arbiter_callback_us": per_call("/motion", ("timer", "subscription")),
            "arbiter_cycle_us": arbiter_total / kick_calls / 1e3 if kick_calls else 0.0,
            "driver_cycle_us": per_call("/servo_driver", ("timer",))}


def child(args: argparse.Namespace) -> None:
    task = json.loads(args.child)
    if task["kind"] == "trial":
        result = trial(task["seed"], task["seconds"], task["line_noise"], task["jitter"],
                       task["plant"], task["shove"])
    else:
        result = cost()
    print(json.dumps(result))


def run_child(task: dict[str, Any]) -> dict[str, Any]:
    result = run_json_child(__file__, task, name="motion_bench")
    if task["kind"] == "trial":
        fell = (f"FELL at {result['fell_at_s']:.1f} s" if result["fell_at_s"] is not None
                else "stood")
        print(f"  seed {result['seed']:>3} {result['side']:<5} ball off by "
              f"({result['ball_offset'][0]:+.3f}, {result['ball_offset'][1]:+.3f}) m: "
              f"{result['distance_m']:.2f} m at {result['angle_deg']:+.1f}°, ball "
              f"{result['ball_speed']:.2f} m/s, {fell}, "
              f"{'ok' if result['success'] else 'MISSED'}"
              + (f", shoved {result['shove'][1]:+.0f} N at {result['shove'][0]:.2f} s"
                 if result["shove"] else "") + f" [{result['wall_s']:.0f} s wall]",
              flush=True)
    return result


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seeds", type=int, default=10)
    parser.add_argument("--seconds", type=float, default=15.0,
                        help="follow the ball at most this long after the request")
    parser.add_argument("--line-noise", type=float, default=0.01)
    parser.add_argument("--jitter", type=float, default=0.02,
                        help="the ball lies up to this far (m) off its spot in x and y")
    parser.add_argument("--plant", action="store_true",
                        help="the kick on the MuJoCo plant alone (no driver, no bus)")
    parser.add_argument("--shove", type=float, default=0.0,
                        help="--plant: shove the torso sideways with this many newtons for "
                             "0.1 s while on one foot (seeded time and direction)")
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--only", choices=["kick", "cost"], action="append")
    parser.add_argument("--quick", action="store_true", help="2 seeds, 4 s: a smoke run")
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT)
    parser.add_argument("--child", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        child(args)
        return 0
    if args.quick:
        args.seeds, args.seconds = 2, 4.0
    parts = args.only or ["cost", "kick"]
    summary: dict[str, Any] = {}
    results: dict[str, Any] = {}
    if "cost" in parts:
        c = run_child({"kind": "cost"})
        results["cost"] = c
        print(f"cost while kicking: kick timer {c['kick_callback_us']:.0f} µs per callback; "
              f"arbiter {c['arbiter_forward_us']:.0f} µs per forwarded kick command, "
              f"{c['arbiter_callback_us']:.0f} µs per callback (all its callbacks), "
              f"{c['arbiter_cycle_us']:.0f} µs per 10 ms cycle; the driver's cycle in the same "
              f"run {c['driver_cycle_us']:.0f} µs: kick/driver "
              f"{c['kick_callback_us'] / c['driver_cycle_us']:.3f}, arbiter/driver "
              f"{c['arbiter_callback_us'] / c['driver_cycle_us']:.3f}; kick "
              f"{c['kick_callback_us'] / 100:.1f} % of the 10 ms period", flush=True)
        summary |= c
    if "kick" in parts:
        tasks = [{"kind": "trial", "seed": seed, "seconds": args.seconds,
                  "line_noise": args.line_noise, "jitter": args.jitter, "plant": args.plant,
                  "shove": args.shove if args.plant else 0.0}
                 for seed in range(args.seeds)]
        how = (f"kick on the plant, no driver, shoves of {args.shove:g} N" if args.plant
               else f"through the driver, line noise {args.line_noise:g}")
        print(f"{args.seeds} kicks ({how}; ball within ±{args.jitter:g} m of its spot):",
              flush=True)
        with ThreadPoolExecutor(max_workers=max(1, args.jobs)) as pool:
            runs = list(pool.map(run_child, tasks))
        results["kick"] = runs
        success = sum(r["success"] for r in runs) / len(runs)
        falls = sum(r["fell_at_s"] is not None for r in runs)
        distance = statistics.median(r["distance_m"] for r in runs)
        angle = statistics.median(abs(r["angle_deg"]) for r in runs)
        speed = statistics.median(r["ball_speed"] for r in runs)
        print(f"success (>= {DISTANCE_M:g} m within ±{ANGLE_DEG:g}°, standing): "
              f"{success:.0%} (target {TARGET_SUCCESS:.0%}); falls {falls} of {len(runs)}; "
              f"median distance {distance:.2f} m (min {min(r['distance_m'] for r in runs):.2f}),"
              f" median |angle| {angle:.1f}° (max "
              f"{max(abs(r['angle_deg']) for r in runs):.1f}°), median ball speed "
              f"{speed:.2f} m/s", flush=True)
        summary |= {"success": success, "falls": falls, "distance_m": distance,
                    "angle_deg": angle, "ball_speed": speed}
        torque: dict[str, float] = {}
        speeds: dict[str, float] = {}
        for r in runs:
            for name, v in r["peak_torque"].items():
                torque[name] = max(torque.get(name, 0.0), v)
            for name, v in r["peak_speed"].items():
                speeds[name] = max(speeds.get(name, 0.0), v)
        print(f"peak servo use (XM430-W350: stall {STALL_TORQUE_NM} N m, no-load "
              f"{NO_LOAD_RAD_S} rad/s):")
        for name in torque:
            if "hip" in name or "knee" in name or "ankle" in name:
                t, w = torque[name], speeds[name]
                print(f"  {name:<15} {t:5.2f} N m ({t / STALL_TORQUE_NM:4.0%})  "
                      f"{w:5.2f} rad/s ({w / NO_LOAD_RAD_S:4.0%})")
        summary["peak_torque"], summary["peak_speed"] = torque, speeds
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({"summary": summary, "results": results}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
