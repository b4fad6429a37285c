"""Communication benchmark: efficient_comm composition vs plain rclpy executors.

One run measures, for every backend, and prints with ratios to the rclpy baselines:

1. publish -> callback latency, one message in flight (String, Image 64 B .. 8 MiB);
2. small-message throughput (String bursts);
3. per-callback dispatch cost without payload (1 µs timer; Empty-message bursts);
4. end-to-end latency of a 5-component chain A -> B -> C -> D -> E;
5. latency seen by a subscriber in another process (plain rclpy) of a composed publisher
   (Container dds=True) vs a plain rclpy publisher;
6. publish from another thread -> callback (no timers anywhere), and messages lost when a
   thread publishes at 1 kHz to a depth-10 subscriber (rclpy SingleThreadedExecutor and
   the composed backends).

Each (scenario, backend) runs in a fresh process (``--scenario X --backend Y --json``), so
plain rclpy baselines never share a process with efficient_comm's DDS set-up; the whole set
runs ``--repeat`` times (interleaved) and the median of the per-run medians is reported.
Results: bench/out/comm_bench.json, plot: docs/bench/comm_latency.png, method and figures:
docs/BENCHMARKS.md.

    source scripts/env.sh && python bench/comm_bench.py            # full (~8 min)
    python bench/comm_bench.py --quick --out /tmp/q.json           # smoke run (<1 min)
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
import time
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
SCRIPT = str(Path(__file__).resolve())
DEFAULT_OUT = ROOT / "bench" / "out" / "comm_bench.json"
DEFAULT_PLOT = ROOT / "docs" / "bench" / "comm_latency.png"
#: Allocator variants of the >= 1 MiB latency runs (glibc reads these at start-up). Setting
#: the mmap threshold alone also fixes the trim threshold at its 128 KiB default (glibc's
#: dynamic adjustment is off then), so freeing a large block trims the heap every time;
#: "mmap64M+trim" raises both.
ALLOC_VARIANTS: dict[str, dict[str, str]] = {
    "mmap64M": {"MALLOC_MMAP_THRESHOLD_": "67108864"},
    "mmap64M+trim": {"MALLOC_MMAP_THRESHOLD_": "67108864", "MALLOC_TRIM_THRESHOLD_": "268435456"},
}

Record = dict[str, Any]

RCLPY = ("single", "multi", "events")
COMPOSED = ("composed", "composed_bf", "composed_dds")
BACKENDS = RCLPY + COMPOSED
LABELS = {
    "single": "rclpy SingleThreadedExecutor",
    "multi": "rclpy MultiThreadedExecutor",
    "events": "rclpy EventsExecutor",
    "composed": "composed depth_first (dds=False)",
    "composed_bf": "composed breadth_first (dds=False)",
    "composed_dds": "composed depth_first (dds=True)",
    "plain": "plain rclpy publisher",
}
SHORT = {
    "single": "Single",
    "multi": "Multi",
    "events": "Events",
    "composed": "composed",
    "composed_bf": "comp.bf",
    "composed_dds": "comp.dds",
}
LAT_PAYLOADS = ("string", "image_64B", "image_64KiB", "image_1MiB", "image_8MiB")
LARGE_PAYLOADS = ("image_1MiB", "image_8MiB")
CHAIN_PAYLOADS = ("string", "image_1MiB")
EXT_PAYLOADS = ("string", "image_1MiB")
THR_PAYLOADS = ("string", "empty")
#: The foreign-thread scenario's backends (as in _comm_cases.FOREIGN_BACKENDS).
FOREIGN_BACKENDS = ("single", "composed", "composed_dds")

#: Iterations per payload (after a warm-up of 10 %, at least 3).
LAT_N = {
    "string": 2000,
    "image_64B": 2000,
    "image_64KiB": 1000,
    "image_1MiB": 300,
    "image_8MiB": 120,
}
LAT_N_QUICK = {"string": 60, "image_64B": 60, "image_64KiB": 40, "image_1MiB": 20, "image_8MiB": 8}
#: Composed deliveries cost about a microsecond: take more samples for a steadier p99.
COMPOSED_FACTOR = 5
CHAIN_N = {"string": 1000, "image_1MiB": 150}
CHAIN_N_QUICK = {"string": 40, "image_1MiB": 8}
EXT_N = {"string": 1000, "image_1MiB": 200}
EXT_N_QUICK = {"string": 30, "image_1MiB": 8}
THR_MSGS = {
    "single": 5000,
    "multi": 3000,
    "events": 30000,
    "composed": 200000,
    "composed_bf": 200000,
    "composed_dds": 200000,
}
THR_MSGS_QUICK = 1000
#: Foreign-thread scenario: messages in flight one by one, then a burst at 1 kHz.
FOREIGN_N, FOREIGN_BURST = 1000, 2000
FOREIGN_N_QUICK, FOREIGN_BURST_QUICK = 60, 200
DISPATCH_S, DISPATCH_S_QUICK = 1.0, 0.15
#: Wall-clock budget of one rclpy latency/chain/throughput measurement (MultiThreadedExecutor
#: stalls: it is cut short there and reports the samples it got).
BUDGET_S, BUDGET_S_QUICK = 10.0, 1.5

#: Figures measured on a machine of this kind (shared/ROS2_PIP.md "Baselines measured here").
DOC_BASELINE_LATENCY_US: dict[str, dict[str, float]] = {
    "single": {"string": 197, "image_64KiB": 266, "image_1MiB": 1390, "image_8MiB": 3206},
    "events": {"string": 24.5, "image_64KiB": 100, "image_1MiB": 1191, "image_8MiB": 3653},
}
DOC_BASELINE_DISPATCH_US: dict[str, float] = {"single": 87, "multi": 258, "events": 1.6}
DOC_BASELINE_THROUGHPUT: dict[str, float] = {"single": 5300, "events": 60000}


# -- child side -----------------------------------------------------------------------------


def _scaled(table: dict[str, int], factor: int) -> dict[str, int]:
    return {k: v * factor for k, v in table.items()}


def run_child(args: argparse.Namespace) -> list[Record]:
    """Run one scenario for one backend in this process."""
    sys.path.insert(0, str(ROOT))
    from bench import _comm_cases as cases

    quick: bool = args.quick
    backend: str = args.backend
    payloads: list[str] = args.payloads.split(",") if args.payloads else []
    factor = COMPOSED_FACTOR if backend in COMPOSED else 1
    budget = BUDGET_S_QUICK if quick else BUDGET_S
    if args.scenario == "latency":
        table = _scaled(LAT_N_QUICK if quick else LAT_N, factor)
        return cases.latency(backend, payloads or LAT_PAYLOADS, table, budget)
    if args.scenario == "throughput":
        msgs = THR_MSGS_QUICK * factor if quick else THR_MSGS[backend]
        return cases.throughput(backend, payloads or THR_PAYLOADS, msgs, budget)
    if args.scenario == "dispatch":
        return cases.dispatch(backend, DISPATCH_S_QUICK if quick else DISPATCH_S)
    if args.scenario == "chain":
        table = _scaled(CHAIN_N_QUICK if quick else CHAIN_N, factor)
        return cases.chain(backend, payloads or CHAIN_PAYLOADS, table, budget)
    if args.scenario == "external":
        return cases.external(
            backend, payloads or EXT_PAYLOADS, EXT_N_QUICK if quick else EXT_N, SCRIPT
        )
    if args.scenario == "foreign":
        return cases.foreign(backend, FOREIGN_N_QUICK if quick else FOREIGN_N,
                             FOREIGN_BURST_QUICK if quick else FOREIGN_BURST)
    raise SystemExit(f"unknown scenario {args.scenario}")


# -- parent side: jobs ----------------------------------------------------------------------


@dataclass(frozen=True)
class Job:
    scenario: str
    backend: str
    payloads: tuple[str, ...] = ()
    variant: str = "default"
    env: tuple[tuple[str, str], ...] = ()

    @property
    def name(self) -> str:
        extra = f" [{self.variant}]" if self.variant != "default" else ""
        payloads = f" {','.join(self.payloads)}" if self.payloads else ""
        return f"{self.scenario}/{self.backend}{payloads}{extra}"


def make_jobs(scenarios: Sequence[str], mmap: bool, quick: bool) -> list[Job]:
    jobs: list[Job] = []
    for backend in BACKENDS:
        if "latency" in scenarios:
            # One process per payload: the allocator's state (glibc's dynamic mmap threshold
            # moves up after large frees) would otherwise depend on the sizes run before.
            # (Not in the quick smoke run, which only checks that everything runs.)
            if quick:
                jobs.append(Job("latency", backend))
            else:
                jobs += [Job("latency", backend, (payload,)) for payload in LAT_PAYLOADS]
            # MultiThreadedExecutor's figures are GIL stalls, not allocation: no variants.
            if mmap and backend != "multi":
                for payload in LARGE_PAYLOADS:
                    for variant, env in ALLOC_VARIANTS.items():
                        jobs.append(
                            Job("latency", backend, (payload,), variant, tuple(env.items()))
                        )
        for scenario in ("throughput", "dispatch", "chain"):
            if scenario in scenarios:
                jobs.append(Job(scenario, backend))
    if "external" in scenarios:
        jobs += [Job("external", "plain"), Job("external", "composed")]
    if "foreign" in scenarios:
        jobs += [Job("foreign", b) for b in FOREIGN_BACKENDS]
    return jobs


def run_job(job: Job, quick: bool, timeout_s: float) -> tuple[list[Record], str | None]:
    cmd = [sys.executable, SCRIPT, "--scenario", job.scenario, "--backend", job.backend, "--json"]
    if job.payloads:
        cmd += ["--payloads", ",".join(job.payloads)]
    if quick:
        cmd.append("--quick")
    env = dict(os.environ)
    env.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    env.pop("ROS_DOMAIN_ID", None)  # each child reserves its own
    env.pop("FASTRTPS_DEFAULT_PROFILES_FILE", None)
    env.update(job.env)
    try:
        proc = subprocess.run(
            ["timeout", "-k", "5", str(int(timeout_s)), *cmd],
            capture_output=True,
            text=True,
            env=env,
            check=False,
        )
    except OSError as exc:
        return [], f"{job.name}: {exc}"
    lines = [ln for ln in proc.stdout.splitlines() if ln.startswith("[")]
    if proc.returncode != 0 or not lines:
        tail = "\n".join(proc.stderr.strip().splitlines()[-8:])
        return [], f"{job.name}: exit {proc.returncode}\n{tail}"
    records: list[Record] = json.loads(lines[-1])
    for rec in records:
        rec["variant"] = job.variant
    return records, None


# -- parent side: aggregation ---------------------------------------------------------------

METRICS = (
    "median_us", "p99_us", "min_us", "msgs_per_s", "us_per_msg", "us_per_callback", "lost"
)


def key_of(rec: Record) -> tuple[str, str, str, str]:
    return (rec["scenario"], rec["backend"], rec["payload"], rec["variant"])


def aggregate(runs: Iterable[Record]) -> dict[tuple[str, str, str, str], Record]:
    groups: dict[tuple[str, str, str, str], list[Record]] = {}
    for rec in runs:
        groups.setdefault(key_of(rec), []).append(rec)
    out: dict[tuple[str, str, str, str], Record] = {}
    for key, recs in groups.items():
        agg: Record = {k: v for k, v in recs[0].items() if k not in METRICS and k != "n"}
        agg["runs"] = len(recs)
        agg["n_per_run"] = recs[0].get("n")
        for metric in METRICS:
            values = [r[metric] for r in recs if metric in r]
            if values:
                agg[metric] = statistics.median(values)
                agg[f"{metric}_runs"] = values
        out[key] = agg
    return out


class Results:
    def __init__(self, agg: dict[tuple[str, str, str, str], Record]) -> None:
        self.agg = agg

    def get(
        self, scenario: str, backend: str, payload: str, metric: str, variant: str = "default"
    ) -> float | None:
        rec = self.agg.get((scenario, backend, payload, variant))
        if rec is None or metric not in rec:
            return None
        return float(rec[metric])


def ratio(a: float | None, b: float | None) -> float | None:
    if a is None or b is None or b == 0:
        return None
    return a / b


def fmt(value: float | None, unit: str = "") -> str:
    if value is None:
        return "-"
    if value >= 1000:
        text = f"{value:,.0f}"
    elif value >= 100:
        text = f"{value:.0f}"
    elif value >= 10:
        text = f"{value:.1f}"
    else:
        text = f"{value:.2f}"
    return text + unit


def fmt_ratio(value: float | None) -> str:
    if value is None:
        return "-"
    if value >= 100:
        return f"{value:,.0f}x"
    return f"{value:.1f}x" if value >= 10 else f"{value:.2f}x"


# -- targets --------------------------------------------------------------------------------


@dataclass
class Target:
    name: str
    value: float | None
    limit: str
    met: bool | None


def targets(r: Results) -> list[Target]:
    out: list[Target] = []
    worst = None
    for p in LAT_PAYLOADS:
        v = r.get("latency", "composed", p, "median_us")
        if v is not None:
            worst = v if worst is None else max(worst, v)
    out.append(
        Target(
            "composed latency, worst median over all sizes (µs)",
            worst,
            "≤ 2",
            None if worst is None else worst <= 2.0,
        )
    )
    flat = ratio(
        r.get("latency", "composed", "image_8MiB", "median_us"),
        r.get("latency", "composed", "image_64B", "median_us"),
    )
    out.append(
        Target(
            "composed latency 8 MiB ÷ 64 B", flat, "≤ 1.5", None if flat is None else flat <= 1.5
        )
    )
    for p, need in (("image_64B", 12.0), ("image_1MiB", 500.0)):
        sp = ratio(
            r.get("latency", "events", p, "median_us"), r.get("latency", "composed", p, "median_us")
        )
        out.append(
            Target(
                f"EventsExecutor ÷ composed latency, {p}",
                sp,
                f"≥ {need:g}",
                None if sp is None else sp >= need,
            )
        )
    for b in ("composed", "composed_bf"):
        sp = ratio(
            r.get("throughput", b, "string", "msgs_per_s"),
            r.get("throughput", "events", "string", "msgs_per_s"),
        )
        out.append(
            Target(
                f"throughput {b} ÷ EventsExecutor (String)",
                sp,
                "≥ 8",
                None if sp is None else sp >= 8.0,
            )
        )
    d = ratio(
        r.get("dispatch", "composed", "timer", "us_per_callback"),
        r.get("dispatch", "events", "timer", "us_per_callback"),
    )
    out.append(
        Target(
            "timer dispatch cost consecutive ÷ EventsExecutor",
            d,
            "≤ 1",
            None if d is None else d <= 1.0,
        )
    )
    for p in EXT_PAYLOADS:
        for metric in ("median_us", "p99_us"):
            x = ratio(
                r.get("external", "composed", p, metric), r.get("external", "plain", p, metric)
            )
            out.append(
                Target(
                    f"external subscriber, composed ÷ plain publisher, {p} {metric.split('_')[0]}",
                    x,
                    "≤ 1.1",
                    None if x is None else x <= 1.1,
                )
            )
    fd = r.get("foreign", "composed_dds", "string", "median_us")
    out.append(
        Target(
            "publish from another thread -> callback, composed dds=True, median (µs)",
            fd,
            "≤ 1000",
            None if fd is None else fd <= 1000.0,
        )
    )
    lost = r.get("foreign", "composed_dds", "string", "lost")
    out.append(
        Target("1 kHz from another thread at depth 10, composed dds=True, lost", lost, "0",
               None if lost is None else lost == 0)
    )
    return out


# -- report ---------------------------------------------------------------------------------


def table(headers: Sequence[str], rows: Sequence[Sequence[str]]) -> str:
    widths = [max(len(h), *(len(row[i]) for row in rows)) for i, h in enumerate(headers)]
    line = "  ".join(h.ljust(w) for h, w in zip(headers, widths, strict=True))
    out = [line, "  ".join("-" * w for w in widths)]
    out += [
        "  ".join(
            c.rjust(w) if i else c.ljust(w)
            for i, (c, w) in enumerate(zip(row, widths, strict=True))
        )
        for row in rows
    ]
    return "\n".join(out)


def report(r: Results, tgts: Sequence[Target], repeat: int) -> str:
    parts: list[str] = [
        f"median of {repeat} run(s); µs unless stated; ratio 'A÷B' = A's figure divided by B's"
    ]

    parts.append("\n1. publish -> callback latency, one message in flight (median / p99 µs)")
    rows = []
    for p in LAT_PAYLOADS:
        row = [p]
        for b in BACKENDS:
            row.append(
                f"{fmt(r.get('latency', b, p, 'median_us'))} / "
                f"{fmt(r.get('latency', b, p, 'p99_us'))}"
            )
        comp = r.get("latency", "composed", p, "median_us")
        row.append(fmt_ratio(ratio(r.get("latency", "events", p, "median_us"), comp)))
        row.append(fmt_ratio(ratio(r.get("latency", "single", p, "median_us"), comp)))
        doc_single = DOC_BASELINE_LATENCY_US["single"].get(p)
        doc_events = DOC_BASELINE_LATENCY_US["events"].get(p)
        row.append(f"{fmt(doc_single)} / {fmt(doc_events)}")
        rows.append(row)
    parts.append(
        table(
            [
                "payload",
                *(SHORT[b] for b in BACKENDS),
                "Events÷comp",
                "Single÷comp",
                "doc Single/Events",
            ],
            rows,
        )
    )

    mm = [
        (b, p)
        for b in BACKENDS
        for p in LARGE_PAYLOADS
        if r.get("latency", b, p, "median_us", "mmap64M") is not None
    ]
    if mm:
        parts.append(
            "\n1b. large messages and glibc malloc (median / p99 µs): default; "
            "MALLOC_MMAP_THRESHOLD_=67108864; the same + MALLOC_TRIM_THRESHOLD_=268435456"
        )
        rows = []
        for b, p in mm:
            row = [f"{SHORT[b]} {p}"]
            for variant in ("default", *ALLOC_VARIANTS):
                row.append(
                    f"{fmt(r.get('latency', b, p, 'median_us', variant))} / "
                    f"{fmt(r.get('latency', b, p, 'p99_us', variant))}"
                )
            for variant in ALLOC_VARIANTS:
                row.append(
                    fmt_ratio(
                        ratio(
                            r.get("latency", b, p, "median_us"),
                            r.get("latency", b, p, "median_us", variant),
                        )
                    )
                )
            rows.append(row)
        parts.append(
            table(
                [
                    "backend payload",
                    "default",
                    "mmap 64M",
                    "mmap 64M+trim",
                    "speed-up mmap",
                    "speed-up +trim",
                ],
                rows,
            )
        )

    parts.append("\n2./3. throughput (bursts of 100, one thread unless Multi) and dispatch cost")
    rows = []
    ev_thr = r.get("throughput", "events", "string", "msgs_per_s")
    ev_tmr = r.get("dispatch", "events", "timer", "us_per_callback")
    for b in BACKENDS:
        thr = r.get("throughput", b, "string", "msgs_per_s")
        tmr = r.get("dispatch", b, "timer", "us_per_callback")
        rows.append(
            [
                LABELS[b],
                fmt(thr, "/s"),
                fmt_ratio(ratio(thr, ev_thr)),
                fmt(r.get("throughput", b, "empty", "us_per_msg")),
                fmt(tmr),
                fmt_ratio(ratio(ev_tmr, tmr)),
                fmt(DOC_BASELINE_THROUGHPUT.get(b), "/s") if b in DOC_BASELINE_THROUGHPUT else "-",
                fmt(DOC_BASELINE_DISPATCH_US.get(b)),
            ]
        )
    parts.append(
        table(
            [
                "backend",
                "String msgs/s",
                "÷Events",
                "Empty µs/msg",
                "timer µs/cb",
                "Events÷this",
                "doc msgs/s",
                "doc µs/cb",
            ],
            rows,
        )
    )

    parts.append(
        "\n4. 5-component chain A -> B -> C -> D -> E, publish in A to callback in E "
        "(median / p99 µs)"
    )
    rows = []
    for b in BACKENDS:
        row = [LABELS[b]]
        for p in CHAIN_PAYLOADS:
            row.append(
                f"{fmt(r.get('chain', b, p, 'median_us'))} / {fmt(r.get('chain', b, p, 'p99_us'))}"
            )
            row.append(
                fmt_ratio(
                    ratio(
                        r.get("chain", "events", p, "median_us"), r.get("chain", b, p, "median_us")
                    )
                )
            )
        rows.append(row)
    parts.append(table(["backend", "String", "Events÷this", "Image 1 MiB", "Events÷this"], rows))

    parts.append(
        "\n5. subscriber in another process (plain rclpy, EventsExecutor): publish -> "
        "its callback (µs)"
    )
    rows = []
    for p in EXT_PAYLOADS:
        for metric in ("median_us", "p99_us"):
            plain = r.get("external", "plain", p, metric)
            comp = r.get("external", "composed", p, metric)
            rows.append(
                [
                    f"{p} {metric.split('_')[0]}",
                    fmt(plain),
                    fmt(comp),
                    fmt_ratio(ratio(comp, plain)),
                ]
            )
    parts.append(
        table(["payload", "plain rclpy pub", "composed (dds=True)", "composed÷plain"], rows)
    )

    parts.append(
        "\n6. publish from another thread -> callback, no timers (median / p99 µs), and "
        "messages lost of a 1 kHz burst at depth 10"
    )
    rows = []
    base = r.get("foreign", "single", "string", "median_us")
    for b in FOREIGN_BACKENDS:
        med = r.get("foreign", b, "string", "median_us")
        lost = r.get("foreign", b, "string", "lost")
        rows.append([
            LABELS[b],
            f"{fmt(med)} / {fmt(r.get('foreign', b, 'string', 'p99_us'))}",
            fmt_ratio(ratio(med, base)),
            "-" if lost is None else f"{lost:.0f}",
        ])
    parts.append(table(["backend", "latency", "÷Single", "lost"], rows))

    parts.append("\nTargets")
    rows = [
        [t.name, fmt(t.value), t.limit, "n/a" if t.met is None else ("met" if t.met else "NOT met")]
        for t in tgts
    ]
    parts.append(table(["target", "measured", "wanted", ""], rows))
    return "\n".join(parts)


# -- plot -----------------------------------------------------------------------------------

COLORS = {
    "single": "tab:red",
    "multi": "tab:orange",
    "events": "tab:purple",
    "composed": "tab:green",
    "composed_bf": "tab:olive",
    "composed_dds": "tab:blue",
}


def plot(r: Results, path: Path, repeat: int) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from bench import _comm_cases as cases

    sizes = [p for p in LAT_PAYLOADS if p.startswith("image_")]
    fig, (ax, ax2) = plt.subplots(1, 2, figsize=(13, 6.5), gridspec_kw={"width_ratios": [3, 2]})
    for b in BACKENDS:
        xs, med, p99 = [], [], []
        for p in sizes:
            m = r.get("latency", b, p, "median_us")
            q = r.get("latency", b, p, "p99_us")
            if m is not None and q is not None:
                xs.append(cases.payload_bytes(p))
                med.append(m)
                p99.append(q)
        if not xs:
            continue
        ax.plot(xs, med, "o-", color=COLORS[b], label=LABELS[b], lw=2)
        ax.plot(xs, p99, ":", color=COLORS[b], lw=1)
        for variant, marker in (("mmap64M", "x"), ("mmap64M+trim", "+")):
            pts = [
                (cases.payload_bytes(p), v)
                for p in LARGE_PAYLOADS
                if (v := r.get("latency", b, p, "median_us", variant)) is not None
            ]
            if pts:
                ax.plot(*zip(*pts, strict=True), marker, color=COLORS[b], ms=10, mew=2)
    ax.plot([], [], "k:", label="p99 (dotted)")
    ax.plot([], [], "kx", ls="none", label="median, MALLOC_MMAP_THRESHOLD_=64 MiB")
    ax.plot([], [], "k+", ls="none", label="median, same + MALLOC_TRIM_THRESHOLD_=256 MiB")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xticks([cases.payload_bytes(p) for p in sizes], ["64 B", "64 KiB", "1 MiB", "8 MiB"])
    ax.set_xlabel("sensor_msgs/Image data size")
    ax.set_ylabel("publish → callback latency (µs, log)")
    ax.set_title("Latency, one message in flight (median, solid)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.13), ncol=2)

    names = [b for b in BACKENDS if r.get("throughput", b, "string", "msgs_per_s") is not None]
    vals = [r.get("throughput", b, "string", "msgs_per_s") or 0.0 for b in names]
    bars = ax2.bar([SHORT[b] for b in names], vals, color=[COLORS[b] for b in names])
    for bar, v in zip(bars, vals, strict=True):
        ax2.annotate(
            f"{v / 1000:,.0f}k" if v >= 1000 else f"{v:.0f}",
            (bar.get_x() + bar.get_width() / 2, v),
            ha="center",
            va="bottom",
            fontsize=8,
        )
    ax2.set_yscale("log")
    ax2.set_ylabel("std_msgs/String messages per second (log)")
    ax2.set_title("Small-message throughput, one process")
    ax2.grid(True, axis="y", which="both", alpha=0.3)
    ax2.tick_params(axis="x", labelsize=8)
    fig.suptitle(
        f"efficient_comm vs rclpy (Jazzy, PyPI wheels), median of {repeat} runs, "
        f"{os.cpu_count()} cores",
        fontsize=11,
    )
    fig.tight_layout()
    fig.subplots_adjust(bottom=0.26)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


# -- main -----------------------------------------------------------------------------------


def _cmd(*c: str) -> str:
    try:
        return subprocess.run(
            c, capture_output=True, text=True, cwd=ROOT, check=False
        ).stdout.strip()
    except OSError:
        return ""


def source_state() -> dict[str, str]:
    """The commit and uncommitted library edits at the start of the run."""
    return {
        "git_commit": _cmd("git", "rev-parse", "--short", "HEAD"),
        "uncommitted_in_ros2_ws_src": _cmd("git", "status", "--porcelain", "--", "ros2_ws/src"),
    }


def meta(args: argparse.Namespace, elapsed_s: float, state: dict[str, str]) -> dict[str, Any]:
    rclpy_version = _cmd(
        sys.executable, "-c", "from importlib.metadata import version; print(version('ros-rclpy'))"
    )
    return {
        "date": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        **state,
        "python": platform.python_version(),
        "rclpy": rclpy_version,
        "platform": platform.platform(),
        "cpu_count": os.cpu_count(),
        "repeat": args.repeat,
        "quick": args.quick,
        "mmap_threshold": args.mmap_threshold,
        "elapsed_s": round(elapsed_s, 1),
        "doc_baselines": {
            "latency_median_us": DOC_BASELINE_LATENCY_US,
            "dispatch_us": DOC_BASELINE_DISPATCH_US,
            "throughput_msgs_per_s": DOC_BASELINE_THROUGHPUT,
        },
    }


def parse_args(argv: Sequence[str] | None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0] if __doc__ else None)
    ap.add_argument("--repeat", type=int, default=None, help="runs of everything (default 3)")
    ap.add_argument("--quick", action="store_true", help="few iterations, 1 run: a smoke test")
    ap.add_argument(
        "--mmap-threshold",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="also run the >= 1 MiB latencies with MALLOC_MMAP_THRESHOLD_=67108864 (alone and "
        "with MALLOC_TRIM_THRESHOLD_=268435456); default: on, off with --quick",
    )
    ap.add_argument(
        "--only",
        default="latency,throughput,dispatch,chain,external,foreign",
        help="comma-separated scenarios to run",
    )
    ap.add_argument("--out", type=Path, default=None, help=f"JSON output (default {DEFAULT_OUT})")
    ap.add_argument(
        "--plot",
        type=Path,
        default=None,
        help=f"PNG output (default {DEFAULT_PLOT}; none with --quick)",
    )
    ap.add_argument("--no-plot", action="store_true")
    ap.add_argument("--timeout", type=float, default=300.0, help="per child process, seconds")
    ap.add_argument(
        "--replot",
        type=Path,
        default=None,
        metavar="JSON",
        help="print the table and redraw the plot from an earlier JSON output",
    )
    # Child process interface (used by the parent).
    ap.add_argument("--scenario", help=argparse.SUPPRESS)
    ap.add_argument("--backend", help=argparse.SUPPRESS)
    ap.add_argument("--payloads", default="", help=argparse.SUPPRESS)
    ap.add_argument("--json", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--role", help=argparse.SUPPRESS)
    ap.add_argument("--payload", help=argparse.SUPPRESS)
    ap.add_argument("--topic", help=argparse.SUPPRESS)
    ap.add_argument("--count", type=int, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.repeat is None:
        args.repeat = 1 if args.quick else 3
    if args.mmap_threshold is None:
        args.mmap_threshold = not args.quick
    return args


def main(argv: Sequence[str] | None = None) -> int:
    args = parse_args(argv)
    if args.role == "ext-sub":
        sys.path.insert(0, str(ROOT))
        from bench import _comm_cases as cases

        cases.external_subscriber(args.payload, args.topic, args.count)
        return 0
    if args.scenario:
        records = run_child(args)
        if args.json:
            print(json.dumps(records))
        else:
            for rec in records:
                print(rec)
        return 0

    sys.path.insert(0, str(ROOT))
    if args.replot is not None:
        old = json.loads(args.replot.read_text())
        results = Results({key_of(rec): rec for rec in old["results"]})
        repeat = int(old["meta"]["repeat"])
        print(report(results, targets(results), repeat))
        if not args.no_plot:
            plot(results, args.plot or DEFAULT_PLOT, repeat)
        return 0
    scenarios = args.only.split(",")
    jobs = make_jobs(scenarios, args.mmap_threshold, args.quick)
    state = source_state()
    start = time.monotonic()
    all_records: list[Record] = []
    errors: list[str] = []
    for rep in range(args.repeat):
        for job in jobs:
            t = time.monotonic()
            records, error = run_job(job, args.quick, args.timeout)
            print(
                f"[run {rep + 1}/{args.repeat}] {job.name}: "
                f"{'FAILED' if error else 'ok'} ({time.monotonic() - t:.1f} s)",
                file=sys.stderr,
                flush=True,
            )
            if error:
                errors.append(error)
                print(error, file=sys.stderr)
            for rec in records:
                rec["run"] = rep
            all_records += records
    elapsed = time.monotonic() - start
    agg = aggregate(all_records)
    results = Results(agg)
    tgts = targets(results)
    print(report(results, tgts, args.repeat))
    out_path: Path = args.out or (
        DEFAULT_OUT.with_name("comm_bench_quick.json") if args.quick else DEFAULT_OUT
    )
    out_path.parent.mkdir(parents=True, exist_ok=True)
    doc = {
        "meta": meta(args, elapsed, state),
        "results": sorted(agg.values(), key=lambda a: tuple(str(x) for x in key_of(a))),
        "targets": [t.__dict__ for t in tgts],
        "errors": errors,
        "raw": all_records,
    }
    out_path.write_text(json.dumps(doc, indent=1, ensure_ascii=False) + "\n")
    print(f"\nJSON: {out_path}", file=sys.stderr)
    plot_path: Path | None = args.plot or (None if args.quick else DEFAULT_PLOT)
    if plot_path is not None and not args.no_plot:
        plot(results, plot_path, args.repeat)
        print(f"plot: {plot_path}", file=sys.stderr)
    if errors:
        print(f"{len(errors)} job(s) failed", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
