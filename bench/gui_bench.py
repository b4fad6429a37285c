"""What watching robots costs: the debug GUI's Hub against a generic bridge's subscriptions.

Three simulated robots run as separate processes (``python -m humanoid_sim.demo``, one DDS
domain and namespace each). A watcher process looks at all of them, in one of three modes:

* ``none``: nobody watches (the baseline of the robots' CPU time);
* ``gui``: a typical debug_gui layout through its :class:`debug_gui.Hub`, at the rates the
  views display: components (the stats topic) at 1 Hz, image (``camera/image_raw/compressed``
  if the robot offers it, else the raw image, and the ``ball/debug_markers`` overlays) at
  15 Hz, world (``ground_truth/robot``, ``ground_truth/ball``, ``ball/estimate``) at 10 Hz;
* ``generic``: what a generic bridge (foxglove_bridge, rosbridge) does for the same views:
  a plain subscription to every topic of the robot, at full rate, the image raw (not its
  JPEG topic).

Per mode and run it measures, over the same ``--window``: bytes per second on the robot ->
watcher link (serialized sizes of what the watcher received) and the CPU time the robot
processes spent (utime + stime from ``/proc/PID/stat``), per wall second and per camera
frame (on a loaded machine a starved robot renders fewer frames, so CPU per wall second
measures the scheduler as much as the robot: see :class:`Probe`). Modes are interleaved (the order
rotates per run), every figure is the median of ``--repeat`` runs, and the ratios are taken
against the baseline measured in the same run: ``generic / gui`` for bytes, and for the CPU
cost of being watched (a mode's robot CPU minus the ``none`` CPU), ``gui / generic``.

    source scripts/env.sh && python bench/gui_bench.py            # 3 robots, 5 runs (~6 min)
    python bench/gui_bench.py --quick --out /tmp/gui.json        # smoke run: 1 robot, 1 run
    python bench/gui_bench.py --lockstep --window 30             # robots on a manual clock
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import selectors
import statistics
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import IO, Any

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = str(Path(__file__).resolve())
DEFAULT_OUT = ROOT / "bench" / "out" / "gui_bench.json"
MODES = ("none", "gui", "generic")
#: The views of the typical layout: topic (relative to the robot) -> displayed rate (Hz).
COMPONENTS = {"efficient_comm/stats": 1.0}
WORLD = {"ground_truth/robot": 10.0, "ground_truth/ball": 10.0, "ball/estimate": 10.0}
IMAGE_RATE_HZ = 15.0
COMPRESSED = "camera/image_raw/compressed"
RAW = "camera/image_raw"
#: The image view's overlay layers (the ball detector's debug drawings), where offered.
OVERLAYS = "ball/debug_markers"


# -- the watcher (a child process) ----------------------------------------------------------


class Counter:
    """Bytes and messages per topic since the start (``add`` from executor threads);
    ``start``/``stop`` take the difference over the window. ``totals`` may be replaced by
    another source of the same figures (the Hub counts what crosses the link itself)."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._totals: dict[str, tuple[int, int]] = {}
        self._base: dict[str, tuple[int, int]] = {}
        self.seen: set[str] = set()
        self.totals: Callable[[], dict[str, tuple[int, int]]] = self._own_totals

    def add(self, key: str, size: int) -> None:
        with self._lock:
            self.seen.add(key)
            messages, size_sum = self._totals.get(key, (0, 0))
            self._totals[key] = (messages + 1, size_sum + size)

    def _own_totals(self) -> dict[str, tuple[int, int]]:
        with self._lock:
            return dict(self._totals)

    def start(self) -> None:
        self._base = self.totals()

    def stop(self) -> dict[str, Any]:
        now, base = self.totals(), self._base
        diff = {k: (m - base.get(k, (0, 0))[0], b - base.get(k, (0, 0))[1])
                for k, (m, b) in now.items()}
        return {"bytes": {k: b for k, (_, b) in diff.items()},
                "messages": {k: m for k, (m, _) in diff.items()}}


def _wait(predicate: Callable[[], bool], timeout_s: float, what: str) -> None:
    end = time.monotonic() + timeout_s
    while not predicate():
        if time.monotonic() > end:
            raise SystemExit(f"error: gave up waiting for {what}")
        time.sleep(0.05)


def watch_gui(robots: list[tuple[int, str]], counter: Counter) -> Iterator[dict[str, Any]]:
    """Subscribe the typical layout through the Hub; yields what it subscribed."""
    from debug_gui import Hub, RobotId

    with Hub(domains=sorted({d for d, _ in robots}), node_name="gui_bench") as hub:
        # What crossed the link, as the Hub counts it (serialized sizes, before decoding).
        counter.totals = lambda: {f"{r.domain}:{t}": (c.messages, c.bytes)
                                  for (r, t), c in hub.counters().items()}
        wanted = [RobotId(domain=d, namespace=ns) for d, ns in robots]
        _wait(lambda: all(r in hub.robots() for r in wanted), 60, "the robots in the Hub")
        feeds: list[Any] = []
        subscribed: dict[str, float] = {}
        for robot in wanted:
            _wait(lambda robot=robot: robot.resolve(RAW) in hub.topics(robot), 60,  # type: ignore[misc]
                  f"{robot.resolve(RAW)}")
            # The JPEG topic is discovered on its own: give it a moment before settling for
            # the raw image (a robot without a compressor never offers it).
            end = time.monotonic() + 10
            while (robot.resolve(COMPRESSED) not in hub.topics(robot)
                   and time.monotonic() < end):
                time.sleep(0.1)
            topics = hub.topics(robot)
            image = COMPRESSED if robot.resolve(COMPRESSED) in topics else RAW
            layout = {**COMPONENTS, image: IMAGE_RATE_HZ, **WORLD}
            if robot.resolve(OVERLAYS) in topics:
                layout[OVERLAYS] = IMAGE_RATE_HZ
            for topic, rate in layout.items():
                name = robot.resolve(topic)
                msg_type = _import_type(topics[name][0])
                key = f"{robot.domain}:{name}"

                def count(msg: Any, key: str = key) -> None:
                    counter.add(key, 0)  # only "seen": the Hub counts the bytes

                feeds.append(hub.subscribe(robot, topic, msg_type, count, rate_hz=rate))
                subscribed[key] = rate
        # A feed turns throttled once the Hub discovers the publisher's request reader:
        # measure after that (every topic but the statistics is throttle-aware here), or
        # after 15 s, whatever the Hub then has.
        def throttled() -> int:
            return sum(bool(getattr(f, "throttled", False)) for f in feeds)

        end = time.monotonic() + 15
        while throttled() < len(feeds) - len(wanted) * len(COMPONENTS) and (
                time.monotonic() < end):
            time.sleep(0.1)
        yield {"subscribed": subscribed, "throttled": throttled()}
        for feed in feeds:
            feed.close()


def watch_generic(robots: list[tuple[int, str]], counter: Counter) -> Iterator[dict[str, Any]]:
    """A plain subscription to every topic of each robot, raw bytes, full rate."""
    import rclpy
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from rclpy.qos import QoSProfile, ReliabilityPolicy

    # Best effort matches reliable and best-effort publishers alike (what bridges do to
    # reach every publisher); it does not change what a reliable writer sends.
    qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.BEST_EFFORT)
    stack = contextlib.ExitStack()
    nodes: list[tuple[Node, str, int]] = []
    executors = []
    for domain in sorted({d for d, _ in robots}):
        context = Context()
        rclpy.init(context=context, domain_id=domain)
        stack.callback(context.try_shutdown)
        node = Node("generic_bridge", context=context)
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(node)
        executors.append(executor)
        for d, ns in robots:
            if d == domain:
                nodes.append((node, ns, domain))
    stop = threading.Event()

    def spin(executor: Any) -> None:
        while not stop.is_set():
            executor.spin_once(timeout_sec=0.05)

    threads = [threading.Thread(target=spin, args=(e,), daemon=True) for e in executors]
    subscribed: dict[str, float] = {}
    try:
        for node, ns, domain in nodes:
            def names(node: Node = node, ns: str = ns) -> dict[str, list[str]]:
                # Hidden topics (a token starting with "_": throttle requests and replies)
                # are left out, as ros2 topic list and the bridges' topic lists do.
                # Its image view shows the raw image, so the JPEG topic is not one of its
                # subscriptions (subscribing it too would make the robot encode at 30 fps).
                return {n: t for n, t in node.get_topic_names_and_types()
                        if n.startswith(ns + "/") and n != f"{ns}/{COMPRESSED}"
                        and not any(tok.startswith("_") for tok in n.split("/"))}

            _wait(lambda names=names, ns=ns: f"{ns}/{RAW}" in names(), 60,  # type: ignore[misc]
                  f"{ns}/{RAW}")
            time.sleep(2.0)  # let discovery finish: a bridge subscribes to what it sees
            for name, types in sorted(names().items()):
                key = f"{domain}:{name}"

                def count(data: bytes, key: str = key) -> None:
                    counter.add(key, len(data))

                node.create_subscription(_import_type(types[0]), name, count, qos, raw=True)
                subscribed[key] = 0.0
        for t in threads:
            t.start()
        yield {"subscribed": subscribed, "throttled": 0}
    finally:
        stop.set()
        for t in threads:
            if t.is_alive():
                t.join(5)
        for executor in executors:
            executor.shutdown()
        for node, _, _ in nodes:
            with contextlib.suppress(Exception):
                node.destroy_node()
        stack.close()


def _import_type(name: str) -> type:
    import importlib

    package, kind, cls = name.split("/")
    return getattr(importlib.import_module(f"{package}.{kind}"), cls)  # type: ignore[no-any-return]


def watcher(role: str, robots: list[tuple[int, str]]) -> int:
    """Subscribe as ``role``, print ``ready``; ``start``/``stop`` on stdin bound the window."""
    counter = Counter()
    watch = watch_gui if role == "gui" else watch_generic
    gen = watch(robots, counter)
    setup = next(gen)
    keys = set(setup["subscribed"])
    _wait(lambda: {k.split(":")[0] for k in counter.seen} >= {str(d) for d, _ in robots},
          60, "data from every robot")
    print(json.dumps({"ready": True, **setup, "topics": sorted(keys)}), flush=True)
    for line in sys.stdin:
        if line.strip() == "start":
            counter.start()
            print(json.dumps({"started": True}), flush=True)
        elif line.strip() == "stop":
            print(json.dumps({"counts": counter.stop()}), flush=True)
            break
    with contextlib.suppress(StopIteration):
        next(gen)
    return 0


# -- the parent: robots, windows, figures ---------------------------------------------------


def cpu_s(pids: Sequence[int]) -> float:
    """CPU seconds (user + system, all threads) the processes have used so far."""
    tick = os.sysconf("SC_CLK_TCK")
    total = 0
    for pid in pids:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
        total += int(fields[11]) + int(fields[12])  # utime, stime (fields 14 and 15)
    return total / tick


class Robots:
    """``n`` demo processes, one domain and namespace each, in their own sessions."""

    def __init__(self, n: int, workdir: Path, *, lockstep: bool = False) -> None:
        from efficient_comm.testing import isolated_domain_id, ros_env

        self.procs: list[subprocess.Popen[bytes]] = []
        self.robots: list[tuple[int, str]] = []
        self.logs: list[Path] = []
        for k in range(1, n + 1):
            domain, ns = isolated_domain_id(), f"/robot{k}"
            log = workdir / f"robot{k}.log"
            with open(log, "wb") as out:
                self.procs.append(subprocess.Popen(
                    [sys.executable, "-m", "humanoid_sim.demo", "--duration", "0",
                     "--namespace", ns,
                     # In lockstep the period is simulated time, which passes slower.
                     "--stats-period", "1" if lockstep else "5",
                     "--report", str(workdir / f"report{k}.md"),
                     "--bag-dir", str(workdir / "bags"),
                     *(["--lockstep"] if lockstep else [])],
                    env=ros_env(domain), stdout=out, stderr=subprocess.STDOUT,
                    start_new_session=True, cwd=workdir,
                ))
            self.robots.append((domain, ns))
            self.logs.append(log)
        self.env = ros_env(self.robots[0][0])

    def wait_up(self, timeout_s: float) -> None:
        end = time.monotonic() + timeout_s
        for proc, log in zip(self.procs, self.logs, strict=True):
            while "sim s" not in log.read_text(errors="replace"):
                if proc.poll() is not None or time.monotonic() > end:
                    raise SystemExit(f"error: robot did not start; its log:\n{log.read_text()}")
                time.sleep(0.1)

    @property
    def pids(self) -> list[int]:
        return [p.pid for p in self.procs]

    def close(self) -> None:
        from efficient_comm.testing import stop_process_group

        for proc in self.procs:
            stop_process_group(proc)


class Probe:
    """Counts each robot's camera frames and its CPU time at the same moments.

    A starved robot (a loaded machine) renders fewer frames, and its CPU time per wall
    second says more about the scheduler than about its work. So the parent also follows
    every robot's statistics topic at 1 Hz (in every mode alike: one snapshot a second) and,
    as each arrives, reads the frames the ball detector has taken so far with the robot's
    CPU time then: CPU per camera frame, watched and not, is what being watched costs.
    """

    def __init__(self, robots: list[tuple[int, str]], pids: list[int]) -> None:
        import rclpy
        from rclpy.context import Context
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.node import Node

        from efficient_comm_interfaces.msg import ExecutorStats

        self.samples: dict[str, list[tuple[float, int, float]]] = {ns: [] for _, ns in robots}
        self._stop = threading.Event()
        self._parts: list[tuple[Any, Any, Any]] = []
        self._threads = []
        for domain in sorted({d for d, _ in robots}):
            context = Context()
            rclpy.init(context=context, domain_id=domain)
            node = Node("gui_bench_probe", context=context)
            executor = SingleThreadedExecutor(context=context)
            executor.add_node(node)
            for (d, ns), pid in zip(robots, pids, strict=True):
                if d == domain:
                    node.create_subscription(ExecutorStats, f"{ns}/efficient_comm/stats",
                                             self._listener(ns, pid), 10)
            self._parts.append((context, node, executor))
            thread = threading.Thread(target=self._spin, args=(executor,), daemon=True)
            thread.start()
            self._threads.append(thread)

    def _listener(self, ns: str, pid: int) -> Callable[[Any], None]:
        def on_stats(msg: Any) -> None:
            frames = sum(c.calls for c in msg.callbacks
                         if c.node == f"{ns}/ball_detector" and c.kind == "subscription"
                         and c.name == f"{ns}/{RAW}")
            self.samples[ns].append((time.monotonic(), frames, cpu_s([pid])))

        return on_stats

    def _spin(self, executor: Any) -> None:
        while not self._stop.is_set():
            executor.spin_once(timeout_sec=0.1)

    def per_frame(self, t0: float, t1: float) -> tuple[float, int]:
        """CPU seconds and frames of all robots between the samples inside [t0, t1]."""
        cpu, frames = 0.0, 0
        for samples in self.samples.values():
            inside = [s for s in samples if t0 <= s[0] <= t1]
            # A count that went down (the detector's subscription was re-created, a robot
            # restarted) says nothing about this window: that robot is left out of it.
            if len(inside) >= 2 and inside[-1][1] > inside[0][1]:
                frames += inside[-1][1] - inside[0][1]
                cpu += inside[-1][2] - inside[0][2]
        return cpu, frames

    def close(self) -> None:
        self._stop.set()
        for thread in self._threads:
            thread.join(5)
        for context, node, executor in self._parts:
            executor.shutdown()
            node.destroy_node()
            context.try_shutdown()


class Watcher:
    """A watcher child and its line protocol."""

    def __init__(self, role: str, robots: list[tuple[int, str]], env: dict[str, str]) -> None:
        spec = ",".join(f"{d}{ns}" for d, ns in robots)
        self.proc = subprocess.Popen(
            [sys.executable, SCRIPT, "--role", role, "--robots", spec],
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
            env=env, start_new_session=True, text=True,
        )

    def read(self, key: str, timeout_s: float) -> dict[str, Any]:
        assert self.proc.stdout is not None
        sel = selectors.DefaultSelector()
        sel.register(self.proc.stdout, selectors.EVENT_READ)
        end = time.monotonic() + timeout_s
        while time.monotonic() < end:
            if not sel.select(timeout=end - time.monotonic()):
                break
            line = self.proc.stdout.readline()
            if not line:
                break
            with contextlib.suppress(json.JSONDecodeError):
                doc = json.loads(line)
                if key in doc:
                    return dict(doc)
        err = self.proc.stderr.read() if self.proc.poll() is not None and self.proc.stderr else ""
        raise SystemExit(f"error: the watcher did not say {key!r}: {err[-2000:]}")

    def send(self, line: str) -> None:
        stdin: IO[str] | None = self.proc.stdin
        assert stdin is not None
        stdin.write(line + "\n")
        stdin.flush()

    def close(self) -> None:
        from efficient_comm.testing import stop_process_group

        stop_process_group(self.proc)


def measure(mode: str, robots: Robots, probe: Probe, window_s: float) -> dict[str, Any]:
    watcher = Watcher(mode, robots.robots, robots.env) if mode != "none" else None
    try:
        setup: dict[str, Any] = {}
        if watcher is not None:
            setup = watcher.read("ready", 120)
            watcher.send("start")
            watcher.read("started", 30)
        cpu0, t0 = cpu_s(robots.pids), time.monotonic()
        time.sleep(window_s)
        cpu1, t1 = cpu_s(robots.pids), time.monotonic()
        counts: dict[str, Any] = {"bytes": {}, "messages": {}}
        if watcher is not None:
            watcher.send("stop")
            counts = watcher.read("counts", 30)["counts"]
    finally:
        if watcher is not None:
            watcher.close()
    elapsed = t1 - t0
    frame_cpu, frames = probe.per_frame(t0, t1)
    return {
        "mode": mode,
        "window_s": elapsed,
        "robot_cpu_cores": (cpu1 - cpu0) / elapsed,
        "frames": frames,
        "robot_cpu_ms_per_frame": frame_cpu / frames * 1e3 if frames else None,
        "bytes_per_s": sum(counts["bytes"].values()) / elapsed,
        "messages_per_s": sum(counts["messages"].values()) / elapsed,
        "per_topic_bytes_per_s": {k: v / elapsed for k, v in sorted(counts["bytes"].items())},
        "topics": setup.get("topics", []),
        "throttled_feeds": setup.get("throttled", 0),
    }


def summarize(records: list[dict[str, Any]], runs: int) -> dict[str, Any]:
    def med(mode: str, key: str) -> float:
        return float(statistics.median(r[key] for r in records if r["mode"] == mode))

    per_run = []
    for run in range(runs):
        rec = {r["mode"]: r for r in records if r["run"] == run}
        gui_cost = rec["gui"]["robot_cpu_cores"] - rec["none"]["robot_cpu_cores"]
        gen_cost = rec["generic"]["robot_cpu_cores"] - rec["none"]["robot_cpu_cores"]
        frame = {m: rec[m]["robot_cpu_ms_per_frame"] for m in MODES}
        gui_frame = frame["gui"] - frame["none"] if None not in frame.values() else None
        gen_frame = frame["generic"] - frame["none"] if None not in frame.values() else None
        per_run.append({
            "gui_cost_ms_per_frame": gui_frame,
            "generic_cost_ms_per_frame": gen_frame,
            "frame_cost_gui_over_generic": gui_frame / gen_frame
            if gui_frame is not None and gen_frame else None,
            "bytes_generic_over_gui": rec["generic"]["bytes_per_s"] / rec["gui"]["bytes_per_s"]
            if rec["gui"]["bytes_per_s"] else None,
            "gui_cpu_cost_cores": gui_cost,
            "generic_cpu_cost_cores": gen_cost,
            "cpu_cost_gui_over_generic": gui_cost / gen_cost if gen_cost > 0 else None,
        })

    def med_opt(mode: str, key: str) -> float | None:
        values = [r[key] for r in records if r["mode"] == mode and r[key] is not None]
        return float(statistics.median(values)) if values else None

    def med_run(key: str) -> float | None:
        values = [p[key] for p in per_run if p[key] is not None]
        return statistics.median(values) if values else None

    image = "compressed" if any(COMPRESSED in t for r in records if r["mode"] == "gui"
                                for t in r["topics"]) else "raw (no compressed topic yet)"
    return {
        "gui_bytes_per_s": med("gui", "bytes_per_s"),
        "generic_bytes_per_s": med("generic", "bytes_per_s"),
        "bytes_generic_over_gui": med_run("bytes_generic_over_gui"),
        "robot_cpu_cores_none": med("none", "robot_cpu_cores"),
        "robot_cpu_cores_gui": med("gui", "robot_cpu_cores"),
        "robot_cpu_cores_generic": med("generic", "robot_cpu_cores"),
        "gui_cpu_cost_cores": med_run("gui_cpu_cost_cores"),
        "generic_cpu_cost_cores": med_run("generic_cpu_cost_cores"),
        "cpu_cost_gui_over_generic": med_run("cpu_cost_gui_over_generic"),
        "robot_cpu_ms_per_frame_none": med_opt("none", "robot_cpu_ms_per_frame"),
        "robot_cpu_ms_per_frame_gui": med_opt("gui", "robot_cpu_ms_per_frame"),
        "robot_cpu_ms_per_frame_generic": med_opt("generic", "robot_cpu_ms_per_frame"),
        "gui_cost_ms_per_frame": med_run("gui_cost_ms_per_frame"),
        "generic_cost_ms_per_frame": med_run("generic_cost_ms_per_frame"),
        "frame_cost_gui_over_generic": med_run("frame_cost_gui_over_generic"),
        "frames_per_s": med("none", "frames") / med("none", "window_s"),
        "gui_image": image,
        "per_run": per_run,
    }


def _fmt(value: float | None, spec: str) -> str:
    return "-" if value is None else format(value, spec)


def report(summary: dict[str, Any], args: argparse.Namespace) -> str:
    s = summary
    lines = [
        f"{args.robots_n} robot(s){' in lockstep' if args.lockstep else ''}, {args.repeat} run(s) "
        f"of {args.window:g} s per mode, medians; "
        f"GUI image: {s['gui_image']}",
        "",
        f"{'mode':<10} {'robot->watcher kB/s':>20} {'robot CPU (cores)':>18} "
        f"{'cost of watching':>17}",
        f"{'none':<10} {'0':>20} {s['robot_cpu_cores_none']:>18.3f} {'-':>17}",
        f"{'gui':<10} {s['gui_bytes_per_s'] / 1e3:>20.1f} {s['robot_cpu_cores_gui']:>18.3f} "
        f"{_fmt(s['gui_cpu_cost_cores'], '+.3f'):>17}",
        f"{'generic':<10} {s['generic_bytes_per_s'] / 1e3:>20.1f} "
        f"{s['robot_cpu_cores_generic']:>18.3f} {_fmt(s['generic_cpu_cost_cores'], '+.3f'):>17}",
        "",
        f"robot CPU per camera frame (ms; {s['frames_per_s']:.1f} frames/s of all robots "
        "unwatched): none "
        f"{_fmt(s['robot_cpu_ms_per_frame_none'], '.2f')}, gui "
        f"{_fmt(s['robot_cpu_ms_per_frame_gui'], '.2f')}, generic "
        f"{_fmt(s['robot_cpu_ms_per_frame_generic'], '.2f')}; cost of being watched per "
        f"frame: gui {_fmt(s['gui_cost_ms_per_frame'], '+.2f')}, generic "
        f"{_fmt(s['generic_cost_ms_per_frame'], '+.2f')}",
        "",
        f"bytes on the link, generic bridge / GUI: {_fmt(s['bytes_generic_over_gui'], '.1f')}x",
        f"robot CPU cost of being watched, GUI / generic bridge: "
        f"{_fmt(s['cpu_cost_gui_over_generic'], '.2f')} (per wall second), "
        f"{_fmt(s['frame_cost_gui_over_generic'], '.2f')} (per camera frame)",
    ]
    return "\n".join(lines)


def parse_args(argv: Sequence[str] | None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(description=(__doc__ or "").split("\n\n")[0])
    ap.add_argument("--robots-n", type=int, default=3, help="simulated robots (default 3)")
    ap.add_argument("--repeat", type=int, default=5, help="runs of every mode (default 5)")
    ap.add_argument("--window", type=float, default=10.0, help="seconds measured per mode")
    ap.add_argument("--warmup", type=float, default=10.0, help="seconds before the first run")
    ap.add_argument("--quick", action="store_true", help="1 robot, 1 run, short windows")
    ap.add_argument("--lockstep", action="store_true",
                    help="robots on a manual clock, as fast as the machine allows: a camera "
                         "frame is then a fixed amount of simulated work however loaded the "
                         "machine, so CPU per frame is the figure to read")
    ap.add_argument("--out", type=Path, default=DEFAULT_OUT, help="JSON output")
    ap.add_argument("--role", choices=["gui", "generic"], help=argparse.SUPPRESS)
    ap.add_argument("--robots", help=argparse.SUPPRESS)  # the watcher's DOMAIN/NS,...
    args = ap.parse_args(argv)
    if args.quick:
        args.robots_n, args.repeat, args.window, args.warmup = 1, 1, 4.0, 2.0
    return args


def main(argv: Sequence[str] | None = None) -> int:
    args = parse_args(argv)
    if args.role:
        watched = []
        for item in args.robots.split(","):
            domain, _, ns = item.partition("/")
            watched.append((int(domain), "/" + ns))
        return watcher(args.role, watched)
    import tempfile

    with tempfile.TemporaryDirectory(prefix="gui_bench_") as tmp:
        robots = Robots(args.robots_n, Path(tmp), lockstep=args.lockstep)
        probe: Probe | None = None
        try:
            robots.wait_up(180)
            probe = Probe(robots.robots, robots.pids)
            time.sleep(args.warmup)
            records = []
            for run in range(args.repeat):
                for i in range(len(MODES)):
                    mode = MODES[(i + run) % len(MODES)]
                    print(f"[run {run + 1}/{args.repeat}] {mode} ...", flush=True)
                    rec = measure(mode, robots, probe, args.window)
                    rec["run"] = run
                    records.append(rec)
        finally:
            if probe is not None:
                probe.close()
            robots.close()
    summary = summarize(records, args.repeat)
    print(report(summary, args))
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({"summary": summary, "records": records,
                                    "args": {k: str(v) for k, v in vars(args).items()}},
                                   indent=1))
    print(f"JSON: {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
