"""The lockstep barrier's overhead: steps per second with 1, 2 and 4 robot processes.

Each participant is a container process of its own (``python -m
efficient_comm.examples.lockstep robot``: one timer, one reliable publisher per step) and
the world is this process: a :class:`~efficient_comm.StepCoordinator` plus a container
that hears every robot (as a world hears its robots' commands). One step is both barrier
rounds (intake and step, see efficient_comm.simtime). Baseline, measured in the same run:
the same number of the same components in one container on a :class:`ManualClock`,
advanced by the same step (``Container.advance``): what lockstep costs when nothing
crosses a process boundary. Each figure is the median of ``--repeat`` runs (fresh
processes and a fresh domain each run). One more row: one participant with Fast DDS's
default 5 ms ``heartbeatResponseDelay`` in the world's readers (a child process given a
profile of its own, which efficient_comm.dds keeps), i.e. without prompt acknowledgements.

Run: ``source scripts/env.sh && python bench/lockstep_bench.py`` (``--quick``: smoke run).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from contextlib import ExitStack
from pathlib import Path

from efficient_comm import Container, ManualClock, StepCoordinator
from efficient_comm.examples.lockstep import Counter, Listener
from efficient_comm.testing import isolated_domain_id, ros_env, stop_process_group

DT_S = 0.01
#: A user's profile that keeps Fast DDS's default reader acknowledgement delay (5 ms).
DEFAULT_ACKS_XML = """<?xml version="1.0" encoding="UTF-8" ?>
<profiles xmlns="http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles">
  <data_reader profile_name="default_acks" is_default_profile="true">
    <times><heartbeatResponseDelay><sec>0</sec><nanosec>5000000</nanosec>
    </heartbeatResponseDelay></times>
  </data_reader>
</profiles>
"""
OUT = Path(__file__).resolve().parent / "out" / "lockstep_bench.json"


def baseline(n: int, steps: int) -> float:
    """Steps per second of n Counters in one container on a manual clock."""
    names = [f"p{i}" for i in range(n)]
    with Container("baseline", dds=False, clock=ManualClock(), stats_period_s=0) as c:
        for name in names:
            c.add(Counter, name=name, parameters={"robot": name, "period_s": DT_S})
        c.add(Listener, name="listener", parameters={"robots": names})
        for _ in range(max(1, steps // 10)):  # warm-up
            c.advance(DT_S)
        start = time.perf_counter()
        for _ in range(steps):
            c.advance(DT_S)
        return steps / (time.perf_counter() - start)


def lockstep(n: int, steps: int) -> dict[str, float]:
    """Steps per second of n robot processes stepped by a coordinator in this process."""
    domain = isolated_domain_id()
    names = [f"p{i}" for i in range(n)]
    with ExitStack() as stack:
        for name in names:
            proc = subprocess.Popen(
                [sys.executable, "-m", "efficient_comm.examples.lockstep", "robot",
                 "--name", name, "--period", str(DT_S)],
                env=ros_env(domain), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                start_new_session=True,
            )
            stack.callback(stop_process_group, proc)
        # The coordinator first: it prepares the process's DDS for lockstep.
        steps_ = stack.enter_context(StepCoordinator(names, domain_id=domain, timeout_s=30))
        ear = stack.enter_context(Container("world", clock=ManualClock(), domain_id=domain,
                                            stats_period_s=0))
        ear.add(Listener, name="listener", parameters={"robots": names})
        steps_.container = ear
        steps_.wait_ready(timeout_s=120)
        for _ in range(max(1, steps // 10)):  # warm-up
            steps_.advance(DT_S)
        start = time.perf_counter()
        for _ in range(steps):
            steps_.advance(DT_S)
        elapsed = time.perf_counter() - start
    return {"steps_per_s": steps / elapsed, "rtf": steps * DT_S / elapsed}


def default_acks(steps: int, tmp: Path) -> dict[str, float]:
    """:func:`lockstep` with one participant in a child whose readers wait 5 ms to ack."""
    profile = tmp / "default_acks.xml"
    profile.write_text(DEFAULT_ACKS_XML)
    env = dict(os.environ, FASTRTPS_DEFAULT_PROFILES_FILE=str(profile))
    out = subprocess.run([sys.executable, __file__, "--child-default-acks", str(steps)],
                         env=env, capture_output=True, text=True, check=False)
    if out.returncode != 0:
        raise SystemExit(f"the default-acks run failed:\n{out.stderr[-2000:]}")
    result: dict[str, float] = json.loads(out.stdout.strip().splitlines()[-1])
    return result


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="a smoke run (seconds)")
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--steps", type=int, default=300)
    parser.add_argument("--participants", type=int, nargs="+", default=[1, 2, 4])
    parser.add_argument("--out", type=Path, default=OUT)
    parser.add_argument("--child-default-acks", type=int, metavar="STEPS",
                        help=argparse.SUPPRESS)  # the default-acks run's child
    args = parser.parse_args()
    if args.child_default_acks:
        print(json.dumps(lockstep(1, args.child_default_acks)))
        return 0
    if args.quick:
        args.repeat, args.steps, args.participants = 1, 20, [1, 2]
    runs: dict[int, list[dict[str, float]]] = {n: [] for n in args.participants}
    slow_acks: list[dict[str, float]] = []
    started = time.time()
    with tempfile.TemporaryDirectory() as tmp:
        for _ in range(args.repeat):  # interleaved, so load drifts hit every figure alike
            for n in args.participants:
                base = baseline(n, args.steps * 10)
                measured = lockstep(n, args.steps)
                runs[n].append({"baseline_steps_per_s": base, **measured})
            slow_acks.append(default_acks(args.steps, Path(tmp)))
    results = []
    print(f"lockstep: steps of {DT_S * 1e3:g} ms simulated, {args.steps} timed steps, "
          f"median of {args.repeat}")
    print("| participants | lockstep steps/s | sim. s per wall s | in-process baseline "
          "steps/s | lockstep ÷ baseline | per step |")
    print("|---|---|---|---|---|---|")
    for n, per_run in runs.items():
        med = {k: statistics.median(r[k] for r in per_run) for k in per_run[0]}
        ratio = med["steps_per_s"] / med["baseline_steps_per_s"]
        results.append({"participants": n, **med, "ratio": ratio, "runs": per_run})
        print(f"| {n} | {med['steps_per_s']:,.0f} | {med['rtf']:.2f} | "
              f"{med['baseline_steps_per_s']:,.0f} | {ratio:.4f} | "
              f"{1e3 / med['steps_per_s']:.2f} ms |")
    slow = statistics.median(r["steps_per_s"] for r in slow_acks)
    print(f"| 1, Fast DDS's 5 ms ack delay | {slow:,.0f} | {slow * DT_S:.2f} | | | "
          f"{1e3 / slow:.2f} ms |")
    results.append({"participants": 1, "default_acks": True, "steps_per_s": slow,
                    "runs": slow_acks})
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({
        "meta": {"started": started, "seconds": time.time() - started,
                 "python": platform.python_version(), "cpus": os.cpu_count(),
                 "repeat": args.repeat, "steps": args.steps, "dt_s": DT_S},
        "results": results,
    }, indent=1))
    print(f"written {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
