"""A seek in debug_gui's playback: how long until every view's model holds the new instant
(issue 21 point 6: a seek shows the new instant in every view within 0.5 s).

The log is events_bench's match-sized team log (``--robots`` robots, ``--minutes`` minutes,
every topic a match records at its rate, the world's ground truth at 100 Hz). The views are
the ones a user watches a match with, as their models subscribe live: the world view of the
team (poses, beliefs, ball, roles, motion, game state of every robot), and per robot the
components view (statistics) and the logs view (/rosout, /diagnostics).

Figures (median over ``--seeks`` seeks to random instants, seeded):

* ``seek``: from ``Playback.seek(t)`` until the playback has reset every model and
  delivered the last message of each subscribed topic at or before ``t`` (``settle``),
  i.e. until every model holds the data of instant ``t``; checked on the world model
  (each robot's pose is that of ``t``);
* ``read window``: the baseline, measured in the same run: reading the same topics' last
  second before ``t`` with ``log_analysis.TeamLog`` and nothing else (the floor of any
  seek that reads by time window).

The page shows a model's data at its view's next poll (the world view's every 0.1 s, the
bar's time every 0.2 s), which adds at most that to the figure.

Run: ``source scripts/env.sh && python bench/playback_bench.py`` (``--quick`` for a smoke run).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import random
import statistics
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from debug_gui import Playback
from debug_gui.models.components import ComponentsModel
from debug_gui.models.logs import LogsModel
from debug_gui.models.world import WorldModel
from log_analysis import TeamLog

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
from bench.events_bench import NS, write_log  # noqa: E402 (events_bench's match-sized log)

TARGET_S = 0.5


def expected_x(t_ns: int) -> float:
    """events_bench's robots believe x = (i % 40) / 10 at their i-th pose (10 Hz from 1 s)."""
    i = (t_ns - NS) // (NS // 10)
    return float(i % 40) / 10


def run(path: Path, *, seeks: int, seed: int) -> dict[str, Any]:
    rng = random.Random(seed)
    with Playback(path) as playback:
        robots = playback.robots()
        world = WorldModel(playback, robots, clock=playback.now)
        others: list[Any] = [ComponentsModel(playback, r, clock=playback.now) for r in robots]
        others += [LogsModel(playback, r) for r in robots]
        world.activate()
        for model in others:
            model.activate()
        if not playback.settle(60.0):
            raise SystemExit("the views' first instant was not delivered in 60 s")
        names = playback.subscribed()
        seek_s, read_s, held = [], [], 0
        log = TeamLog(path)
        for _ in range(seeks):
            t_ns = rng.randrange(playback.start_ns + 2 * NS, playback.end_ns)
            t0 = time.perf_counter()
            playback.seek(t_ns / NS)
            if not playback.settle(60.0):
                raise SystemExit(f"a seek to {t_ns / NS:.3f} s was not delivered in 60 s")
            seek_s.append(time.perf_counter() - t0)
            poses = [s.pose.x for s in world.states() if s.pose is not None]
            held += len(poses) == len(robots) and all(
                abs(x - expected_x(t_ns)) < 1e-9 for x in poses)
            t0 = time.perf_counter()
            sum(1 for _ in log.messages(names, start_ns=t_ns - NS, end_ns=t_ns + 1))
            read_s.append(time.perf_counter() - t0)
        world.deactivate()
        for model in others:
            model.deactivate()
    return {"seeks": seeks, "robots": len(robots), "topics": len(names),
            "seek_s": seek_s, "read_window_s": read_s, "held": held}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--robots", type=int, default=6, choices=range(1, 7))
    parser.add_argument("--minutes", type=float, default=10.0)
    parser.add_argument("--seeks", type=int, default=40)
    parser.add_argument("--seed", type=int, default=21)
    parser.add_argument("--quick", action="store_true", help="a short smoke run")
    parser.add_argument("--out", type=Path,
                        default=Path(__file__).with_name("out") / "playback_bench.json")
    args = parser.parse_args()
    if args.quick:
        args.robots, args.minutes, args.seeks = 2, 0.5, 8
    started = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "log"
        written = write_log(path, robots=args.robots, minutes=args.minutes)
        print(f"wrote {written:,} messages ({args.robots} robots, {args.minutes:g} min)",
              file=sys.stderr)
        result = run(path, seeks=args.seeks, seed=args.seed)
    result["messages"] = written
    meta = {"date": time.strftime("%Y-%m-%dT%H:%M:%S%z"), "python": platform.python_version(),
            "platform": platform.platform(), "cpu_count": os.cpu_count(),
            "load": os.getloadavg()[0], "minutes": args.minutes, "quick": args.quick,
            "elapsed_s": round(time.perf_counter() - started, 1)}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({"meta": meta, "results": [result]}, indent=1))
    seek, read = (statistics.median(result[k]) for k in ("seek_s", "read_window_s"))
    print(f"\na seek in a {args.minutes:g}-minute log of {result['robots']} robots "
          f"({written:,} messages; {result['topics']} topics subscribed by the world, "
          f"components and logs views; median of {args.seeks} seeks, load {meta['load']:.1f})")
    print(f"{'':14}{'ms':>9}{'vs read':>10}{'of 0.5 s':>10}")
    for label, s in (("read window", read), ("seek", seek)):
        print(f"{label:14}{s * 1e3:9.1f}{s / read:9.2f}x{s / TARGET_S:10.1%}")
    print(f"target: every view holds the new instant within {TARGET_S} s: "
          f"{seek / TARGET_S:.2f} of the target "
          f"({'met' if seek <= TARGET_S else 'NOT met'}); "
          f"slowest seek {max(result['seek_s']) * 1e3:.0f} ms")
    print(f"every robot's pose was that of the instant after {result['held']} of "
          f"{args.seeks} seeks")
    return 0


if __name__ == "__main__":
    sys.exit(main())
