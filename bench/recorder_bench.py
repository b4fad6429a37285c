"""Recorder benchmark: what recording costs the robot, with the recorder off the callback path
vs serializing and writing in the callback (the rosbag2 path), measured in the same run.

A robot process composes, in one container (no DDS, so only recording differs):

* three robots' cameras, 320x240 RGB at 30 Hz, and 100 Hz joint states each;
* a control loop: robot 1's joint states -> a controller that computes and publishes a
  command. Its latency is measured from the joint-state timer's due time to the command.

Modes (each run in a fresh process, interleaved, ``--repeat`` times):

* ``none``      nothing records (the baseline);
* ``recorder``  robot_recorder's Recorder composed in: the callback enqueues by reference,
  its writer thread serializes, compresses (zstd) and writes MCAP;
* ``unpaced``   the same without keeping the writer off the GIL around timer deadlines;
* ``inline``    the same storage code called in the subscription callback.

Reported (median over runs): control-loop latency p50/p99 and its ratio to ``none``
(target: recorder <= +10 % at p99), drops (target 0), CPU seconds per recorded message for
the whole process and for the executor thread (callbacks), minus the ``none`` run's CPU.

    source scripts/env.sh && python bench/recorder_bench.py --rt       # ~5 min
    python bench/recorder_bench.py --seconds 2 --repeat 1 --out /tmp/r.json   # smoke
"""

from __future__ import annotations

import argparse
import functools
import json
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
DEFAULT_OUT = ROOT / "bench" / "out" / "recorder_bench.json"
MODES = ("none", "recorder", "unpaced", "inline")
ROBOTS = 3
WIDTH, HEIGHT, CAMERA_HZ, JOINT_HZ = 320, 240, 30.0, 100.0


# -- the robot process -------------------------------------------------------------------------


def _frames(seed: int) -> list[bytes]:
    """Camera-like frames: smooth gradients with sensor noise (partly compressible)."""
    import numpy as np

    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:HEIGHT, 0:WIDTH]
    frames = []
    for k in range(8):
        base = np.stack([(x + 4 * k) % 256, (y + 2 * k) % 256, (x + y) % 256], axis=-1)
        noise = rng.integers(0, 8, size=base.shape)
        frames.append((base + noise).astype(np.uint8).tobytes())
    return frames


def robot(mode: str, seconds: float, bag_dir: Path, params: dict[str, Any]) -> dict[str, Any]:
    import numpy as np
    from sensor_msgs.msg import Image, JointState
    from std_msgs.msg import Float64MultiArray

    from efficient_comm import Container, from_msg, to_msg
    from efficient_comm.handle import NodeHandle
    from robot_recorder import BagWriter, Recorder
    from rosbag2_layout import trim, type_name

    joint_names = [f"joint_{i}" for i in range(20)]

    class Camera:
        def __init__(self, node: NodeHandle, seed: int) -> None:
            self.frames = _frames(seed)
            self.pub = node.create_publisher(Image, "camera/image", qos=5)
            self.k = 0
            node.create_timer(1.0 / CAMERA_HZ, self.tick)

        def tick(self) -> None:
            msg = Image(height=HEIGHT, width=WIDTH, encoding="rgb8", step=WIDTH * 3,
                        data=self.frames[self.k % len(self.frames)])
            msg.header.frame_id = "camera"
            self.k += 1
            self.pub.publish(msg)

    class Joints:
        def __init__(self, node: NodeHandle) -> None:
            self.node = node
            self.pub = node.create_publisher(JointState, "joint_states", qos=10)
            self.k = 0
            self.wake_ns: list[int] = []
            self.period_ns = round(1e9 / JOINT_HZ)
            timer = node.create_timer(1.0 / JOINT_HZ, self.tick)
            self.first_due: int = timer.next_ns  # type: ignore[attr-defined]

        def tick(self) -> None:
            msg = JointState(name=joint_names, position=[0.01 * self.k] * 20,
                             velocity=[0.0] * 20, effort=[0.0] * 20)
            # The stamp is when this sample was due (the timer's schedule has no drift and
            # skips missed periods), so the loop's latency includes waking up.
            now = self.node.clock.now_ns()
            due = now - (now - self.first_due) % self.period_ns
            self.wake_ns.append(now - due)
            msg.header.stamp = to_msg(due)
            self.k += 1
            self.pub.publish(msg)

    class Controller:
        def __init__(self, node: NodeHandle) -> None:
            self.node = node
            self.gain = np.eye(20) * 0.5
            self.pub = node.create_publisher(Float64MultiArray, "command", qos=10)
            self.latencies: list[int] = []
            self.k = 0
            node.create_subscription(JointState, "joint_states", self.on_joints, qos=10)

        def on_joints(self, msg: JointState) -> None:
            q = np.asarray(msg.position)
            command = Float64MultiArray(data=(self.gain @ q).tolist())
            self.latencies.append(self.node.clock.now_ns() - from_msg(msg.header.stamp))
            self.k += 1
            self.pub.publish(command)

    class InlineRecorder:
        """The rosbag2 path: serialize and write in the subscription callback."""

        def __init__(self, node: NodeHandle, topics: list[tuple[str, type]]) -> None:
            self.node = node
            self.bag = BagWriter(bag_dir / "inline", min_free_bytes=0)
            self.messages = 0
            for topic, msg_type in topics:
                name = type_name(msg_type)
                node.create_subscription(msg_type, topic, self.writer_for(topic, name), qos=100)

        def writer_for(self, topic: str, type_str: str) -> Callable[[Any], None]:
            return lambda msg: self.write(topic, type_str, msg)

        def write(self, topic: str, type_str: str, msg: Any) -> None:
            self.bag.write(topic, type_str, trim(msg, serialize(msg)), self.node.clock.now_ns())
            self.bag.tick()
            self.messages += 1

        def close(self) -> None:
            self.bag.close()

    from rclpy.serialization import serialize_message as serialize

    topics: list[tuple[str, type]] = []
    publishers: list[Any] = []  # what published the recorded topics (each counts in ``k``)
    with Container("robot", dds=False, serve=False) as container:
        for r in range(1, ROBOTS + 1):
            ns = f"/robot{r}"
            camera = container.add(functools.partial(Camera, seed=r), name="camera",
                                   namespace=ns)
            joints = container.add(Joints, name="joints", namespace=ns)
            if r == 1:
                loop_sensor = joints
            topics += [(f"{ns}/camera/image", Image), (f"{ns}/joint_states", JointState)]
            publishers += [camera, joints]
        controller = container.add(Controller, name="controller", namespace="/robot1")
        publishers.append(controller)
        topics.append(("/robot1/command", Float64MultiArray))
        recorder: Any = None
        inline: Any = None
        if mode in ("recorder", "unpaced"):
            recorder_params: dict[str, Any] = (
                {"pace_before_timers_s": 0.0, "pace_after_timers_s": 0.0}
                if mode == "unpaced" else {})
            recorder_params = {**params, **recorder_params}
            recorder = container.add(
                lambda n: Recorder(n, topics=[t for t, _ in topics], output_dir=bag_dir),
                name="recorder", parameters={"min_free_bytes": 0, **recorder_params})
            recorder.start(bag_dir / "recorder").result(10)
        elif mode == "inline":
            inline = container.add(lambda n: InlineRecorder(n, topics), name="inline")
        container.spin_for(1.0)  # warm-up: allocations, first chunks
        controller.latencies.clear()
        loop_sensor.wake_ns.clear()
        base_msgs = _recorded(recorder, inline)
        base_published = sum(p.k for p in publishers)
        base_drops = _drops(recorder)
        cpu0, thread0, wall0 = time.process_time(), time.thread_time(), time.monotonic()
        container.spin_for(seconds)
        if recorder is not None:
            recorder.writer.drain().result(60)  # the writer's backlog is part of the cost
        cpu, thread, wall = (time.process_time() - cpu0, time.thread_time() - thread0,
                             time.monotonic() - wall0)
        recorded = _recorded(recorder, inline) - base_msgs
        published = sum(p.k for p in publishers) - base_published
        drops = _drops(recorder) - base_drops
        high_water = recorder.writer.high_water if recorder is not None else 0
    lat = sorted(controller.latencies)
    wake = sorted(loop_sensor.wake_ns)
    written = sum(p.stat().st_size for p in bag_dir.rglob("*.mcap"))
    return {
        "mode": mode, "seconds": wall, "cpu_s": cpu, "executor_thread_cpu_s": thread,
        "published": published, "recorded": recorded, "drops": drops,
        "queue_high_water": high_water,
        "loop_samples": len(lat), "loop_p50_us": _pct(lat, 50) / 1e3,
        "loop_p99_us": _pct(lat, 99) / 1e3, "bytes_on_disk": written,
        "wake_p50_us": _pct(wake, 50) / 1e3, "wake_p99_us": _pct(wake, 99) / 1e3,
    }


def _recorded(recorder: Any, inline: Any) -> int:
    if recorder is not None:
        return sum(s.messages for s in recorder.topic_states().values())
    return int(inline.messages) if inline is not None else 0


def _drops(recorder: Any) -> int:
    return sum(s.drops for s in recorder.topic_states().values()) if recorder else 0


def _pct(values: list[int], p: float) -> float:
    if not values:
        return float("nan")
    return float(values[min(len(values) - 1, int(len(values) * p / 100))])


# -- the driver --------------------------------------------------------------------------------


def run_once(mode: str, seconds: float, *, rt: bool, params: list[str]) -> dict[str, Any]:
    # --rt: the robot process runs SCHED_FIFO (as control loops on robots do), so other
    # processes on the machine do not blur the comparison; both modes alike.
    prefix = ["chrt", "-f", "10"] if rt else []
    with tempfile.TemporaryDirectory(prefix="recbench") as tmp:
        out = subprocess.run(
            [*prefix, sys.executable, __file__, "--role", mode, "--seconds", str(seconds),
             "--bag", tmp, *(f"--param={p}" for p in params)],
            capture_output=True, text=True, timeout=seconds * 4 + 120,
        )
    if out.returncode:
        raise RuntimeError(f"{mode} run failed:\n{out.stdout}\n{out.stderr}")
    result: dict[str, Any] = json.loads(out.stdout.strip().splitlines()[-1])
    return result


def summarize(runs: list[dict[str, Any]]) -> dict[str, Any]:
    def med(mode: str, key: str) -> float:
        return float(statistics.median(r[key] for r in runs if r["mode"] == mode))

    summary: dict[str, Any] = {"per_mode": {}}
    for mode in MODES:
        if not any(r["mode"] == mode for r in runs):
            continue
        summary["per_mode"][mode] = {k: med(mode, k) for k in (
            "loop_p50_us", "loop_p99_us", "cpu_s", "executor_thread_cpu_s", "published",
            "recorded",
            "drops", "queue_high_water", "seconds", "bytes_on_disk", "wake_p50_us",
            "wake_p99_us", "loop_samples")}
    per = summary["per_mode"]
    base = per["none"]
    for mode in ("recorder", "unpaced", "inline"):
        if mode not in per:
            continue
        m = per[mode]
        n = max(1.0, m["recorded"])
        m["p99_ratio_vs_none"] = m["loop_p99_us"] / base["loop_p99_us"]
        # The same ratio taken run by run (each run's "none" is its neighbour in time).
        base_by_run = {r["run"]: r["loop_p99_us"] for r in runs if r["mode"] == "none"}
        m["p99_ratio_paired_median"] = statistics.median(
            r["loop_p99_us"] / base_by_run[r["run"]] for r in runs
            if r["mode"] == mode and r["run"] in base_by_run)
        m["p50_ratio_vs_none"] = m["loop_p50_us"] / base["loop_p50_us"]
        # Extra CPU over the baseline, per recorded message (same wall time per run).
        scale = m["seconds"] / base["seconds"]
        m["cpu_us_per_msg"] = (m["cpu_s"] - base["cpu_s"] * scale) / n * 1e6
        m["executor_cpu_us_per_msg"] = (
            m["executor_thread_cpu_s"]
            - base["executor_thread_cpu_s"] * scale) / n * 1e6
    if "recorder" in per and "inline" in per:
        summary["recorder_vs_inline"] = {
            "cpu_per_msg_ratio": per["recorder"]["cpu_us_per_msg"]
            / per["inline"]["cpu_us_per_msg"],
            "executor_cpu_per_msg_ratio": per["recorder"]["executor_cpu_us_per_msg"]
            / per["inline"]["executor_cpu_us_per_msg"],
            "p99_ratio": per["recorder"]["loop_p99_us"] / per["inline"]["loop_p99_us"],
        }
    return summary


def report(summary: dict[str, Any]) -> None:
    per = summary["per_mode"]
    print(f"{'mode':10} {'p50 µs':>8} {'p99 µs':>8} {'p99/none':>9} {'paired':>7} "
          f"{'recorded':>9} {'drops':>6} {'queue max':>9} {'CPU µs/msg':>10} "
          f"{'executor µs/msg':>15}")
    for mode, m in per.items():
        print(f"{mode:10} {m['loop_p50_us']:8.0f} {m['loop_p99_us']:8.0f} "
              f"{m.get('p99_ratio_vs_none', 1.0):9.2f} "
              f"{m.get('p99_ratio_paired_median', 1.0):7.2f} {m['recorded']:9.0f} "
              f"{m['drops']:6.0f} "
              f"{m['queue_high_water']:9.0f} {m.get('cpu_us_per_msg', float('nan')):10.0f} "
              f"{m.get('executor_cpu_us_per_msg', float('nan')):15.1f}")
    if "recorder_vs_inline" in summary:
        r = summary["recorder_vs_inline"]
        print(f"recorder / inline: CPU per message {r['cpu_per_msg_ratio']:.2f}, "
              f"executor-thread CPU per message {r['executor_cpu_per_msg_ratio']:.3f}, "
              f"loop p99 {r['p99_ratio']:.2f}")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seconds", type=float, default=15.0)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--modes", default=",".join(MODES))
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT)
    parser.add_argument("--rt", action="store_true",
                        help="run the robot process SCHED_FIFO (needs root or CAP_SYS_NICE)")
    parser.add_argument("--param", action="append", default=[], metavar="NAME=JSON",
                        help="a recorder parameter, e.g. pace_before_timers_s=0.002")
    parser.add_argument("--role", choices=MODES, help=argparse.SUPPRESS)
    parser.add_argument("--bag", type=Path, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.role:
        params = {k: json.loads(v) for k, _, v in (p.partition("=") for p in args.param)}
        print(json.dumps(robot(args.role, args.seconds, args.bag, params)))
        return 0
    modes = [m for m in args.modes.split(",") if m]
    if "none" not in modes:
        modes.insert(0, "none")
    runs = []
    for i in range(args.repeat):
        for mode in modes:
            result = run_once(mode, args.seconds, rt=args.rt, params=args.param)
            result["run"] = i
            runs.append(result)
            print(f"run {i} {mode:9} p99 {result['loop_p99_us']:7.0f} µs (wake-up "
                  f"{result['wake_p99_us']:5.0f})  recorded "
                  f"{result['recorded']:6}  drops {result['drops']}  cpu {result['cpu_s']:.2f} s",
                  flush=True)
    summary = summarize(runs)
    report(summary)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({"runs": runs, "summary": summary, "rt": args.rt,
                                    "params": args.param,
                                    "seconds": args.seconds, "repeat": args.repeat}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
