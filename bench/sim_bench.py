"""Software-in-the-loop speed: the servo bus, the simulator with the whole pipeline, the camera.

Three measures, each run in a fresh child process ``--repeat`` times, medians printed:

* ``bus`` and ``bus_fast``: cycles per second of the servo driver's work for 20 servos, one
  read of present velocity + position and one sync write (goal position), through
  dynamixel-sdk, the pty and the emulator with MuJoCo behind it; ``bus`` reads with plain
  Sync Read (20 status packets), ``bus_fast`` with Fast Sync Read (one status packet), as
  the driver does. Target >= 200 Hz; the ratio fast/plain is what Fast Sync Read gains. The
  baseline is a bare pty round trip of the same byte counts (an echo thread), the floor of
  the transport.
* ``lockstep``: the whole robot (simulator, camera, driver, pipeline) on a manual clock, as
  fast as the machine allows: simulated seconds per wall second is the real-time factor
  the machine can sustain. Target >= 1.0. ``lockstep_pty`` is the same robot with its
  driver going through the pty (a driver in another process does), where ``lockstep`` has
  it wired straight to the emulator (``PtyBus.direct_port``, what ``compose`` gives it on
  a manual clock): the ratio of their CPU per simulated second is what the direct port
  saves.
* ``realtime``: the same robot on the wall clock for ``--seconds``: the real-time factor and
  camera frame rate achieved, and the process's CPU use; the baseline for the camera is
  rendering alone (frames per second with nothing else running).
* ``demo_lockstep`` and ``demo_realtime``: the single-robot demo as a user starts it
  (``python -m humanoid_sim.demo --no-dds --duration <--seconds>``, with ``--lockstep`` or
  not): the robot plays, walking to the ball and kicking it; the real-time factor, distance
  walked and kicks are read from its report. Target >= 1.0 (lockstep: the machine keeps
  up with the walking robot; real time: it does not fall behind the wall clock).
* ``split_shm`` and ``split_dds``: the demo split into two processes (``--split shm`` /
  ``--split dds``, real time, DDS on, a DDS domain of its own): perception (ball detector,
  JPEG compressor) in a container process of its own, the camera image crossing through
  shared memory or over DDS. The camera's frame rate, the real-time factor and the CPU time
  of both processes while the robot plays, read from the demo's report; the ratios shm/dds
  are taken per run pair (run one after the other, under the same load). Target (issue 20):
  30 fps and RTF 1 over shared memory, with less CPU than over DDS.

Run: ``source scripts/env.sh && python bench/sim_bench.py`` (``--quick`` for a smoke run;
``--only KIND``, repeatable, for some of the measures).
"""

from __future__ import annotations

import argparse
import json
import os
import select
import statistics
import subprocess
import sys
import threading
import time
import tty
from collections.abc import Callable
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_OUT = ROOT / "bench" / "out" / "sim_bench.json"
TARGET_BUS_HZ = 200.0
TARGET_RTF = 1.0


def bus_cycles(cycles: int, *, fast: bool) -> dict[str, float]:
    from dynamixel_sdk import (
        COMM_SUCCESS,
        GroupSyncRead,
        GroupSyncWrite,
        PacketHandler,
        PortHandler,
    )

    from humanoid_sim.driver import ADDR_GOAL, ADDR_TORQUE, ADDR_VELOCITY, READ_LENGTH
    from humanoid_sim.dynamixel.bus import Bus
    from humanoid_sim.dynamixel.pty import PtyBus
    from humanoid_sim.joints import JOINTS
    from humanoid_sim.mujoco_plant import MujocoPlant

    with PtyBus(Bus(JOINTS, MujocoPlant())) as pty:
        port, packets = PortHandler(pty.port), PacketHandler(2.0)
        assert port.openPort() and port.setBaudRate(1_000_000)
        for dxl_id in JOINTS:
            packets.write1ByteTxRx(port, dxl_id, ADDR_TORQUE, 1)
        reader = GroupSyncRead(port, packets, ADDR_VELOCITY, READ_LENGTH)
        writer = GroupSyncWrite(port, packets, ADDR_GOAL, 4)
        for dxl_id in JOINTS:
            reader.addParam(dxl_id)
            writer.addParam(dxl_id, list((2048).to_bytes(4, "little")))
        read = reader.fastSyncRead if fast else reader.txRxPacket
        failures = 0
        started, cpu = time.perf_counter(), time.process_time()
        for _ in range(cycles):
            failures += read() != COMM_SUCCESS
            failures += writer.txPacket() != COMM_SUCCESS
        elapsed, cpu = time.perf_counter() - started, time.process_time() - cpu
        port.closePort()
    return {"bus_hz": cycles / elapsed, "bus_cpu_hz": cycles / cpu, "failures": failures,
            "echo_hz": _pty_echo(cycles, request=SYNC_READ_BYTES, reply=_reply_bytes(fast))}


def bus_work(cycles: int) -> dict[str, float]:
    """Microseconds of Python work of one read of 20 servos, plain and fast, without the pty.

    The emulator answering the request (MuJoCo state included) and dynamixel-sdk parsing
    the answer, in one thread, each the fastest of several batches: the work itself, which
    the machine's load and the thread hand-over of the pty hide in the wall-clock rate.
    """
    from dynamixel_sdk import BROADCAST_ID, PacketHandler

    from humanoid_sim.driver import ADDR_VELOCITY, READ_LENGTH
    from humanoid_sim.dynamixel.bus import Bus
    from humanoid_sim.dynamixel.protocol import Instruction, Parser, encode
    from humanoid_sim.joints import JOINTS
    from humanoid_sim.mujoco_plant import MujocoPlant

    class Replay:
        """What dynamixel-sdk reads a reply through: the bytes the emulator answered."""

        def __init__(self) -> None:
            self.data, self.is_using = b"", False

        def readPort(self, length: int) -> bytes:  # noqa: N802 (the SDK's name)
            out, self.data = self.data[:length], self.data[length:]
            return out

        def isPacketTimeout(self) -> bool:  # noqa: N802
            return True

    ids = list(JOINTS)
    bus, packets, port = Bus(ids, MujocoPlant()), PacketHandler(2.0), Replay()
    spec = ADDR_VELOCITY.to_bytes(2, "little") + READ_LENGTH.to_bytes(2, "little") + bytes(ids)
    kinds = {"sync": Instruction.SYNC_READ, "fast": Instruction.FAST_SYNC_READ}
    requests = {k: Parser().feed(encode(BROADCAST_ID, inst, spec))[0] for k, inst in kinds.items()}
    batches: dict[str, list[float]] = {f"{k}_{side}_us": [] for k in kinds
                                       for side in ("emulator", "sdk")}
    for _ in range(9):  # interleaved batches; the fastest of each is the work itself
        for kind, request in requests.items():
            started = time.perf_counter()
            for _ in range(cycles):
                reply = bus.handle(request)
            batches[f"{kind}_emulator_us"].append((time.perf_counter() - started) / cycles)
            started = time.perf_counter()
            for _ in range(cycles):
                port.data = reply
                if kind == "fast":
                    packets.fastSyncReadRx(port, BROADCAST_ID, (READ_LENGTH + 4) * len(ids))
                else:
                    for dxl_id in ids:
                        packets.readRx(port, dxl_id, READ_LENGTH)
            batches[f"{kind}_sdk_us"].append((time.perf_counter() - started) / cycles)
    return {key: min(times) * 1e6 for key, times in batches.items()}


#: A sync read's instruction for 20 servos: header, ID, length, instruction, address and
#: length, 20 IDs, CRC. A sync write of 20 goals: the same with 4 data bytes per servo.
SYNC_READ_BYTES = 10 + 4 + 20
SYNC_WRITE_BYTES = 10 + 4 + 20 * 5
BAUD = 1_000_000


def _reply_bytes(fast: bool) -> int:
    """Status bytes: 20 packets of 11 + 8, or one header of 8 and 20 blocks of 4 + 8."""
    from humanoid_sim.driver import READ_LENGTH

    return 8 + 20 * (4 + READ_LENGTH) if fast else 20 * (11 + READ_LENGTH)


def wire_ms(fast: bool) -> float:
    """A cycle's bytes on a 1 Mbps wire (10 bits a byte), return delay time 0: the floor a
    real bus sets, which the pty does not (it has no baud rate)."""
    return (SYNC_READ_BYTES + _reply_bytes(fast) + SYNC_WRITE_BYTES) * 10 / BAUD * 1000


def _pty_echo(cycles: int, *, request: int, reply: int) -> float:
    """Round trips per second on a bare pty: ``request`` bytes out, ``reply`` bytes back."""
    master, slave = os.openpty()
    tty.setraw(master)
    tty.setraw(slave)
    stop = threading.Event()

    def echo() -> None:
        got = 0
        while not stop.is_set():
            if select.select([master], [], [], 0.05)[0]:
                got += len(os.read(master, 65536))
                while got >= request:
                    got -= request
                    os.write(master, bytes(reply))

    thread = threading.Thread(target=echo, daemon=True)
    thread.start()
    started = time.perf_counter()
    for _ in range(cycles):
        os.write(slave, bytes(request))
        need = reply
        while need:
            need -= len(os.read(slave, need))
    elapsed = time.perf_counter() - started
    stop.set()
    thread.join()
    os.close(master)
    os.close(slave)
    return cycles / elapsed


def robot_run(seconds: float, *, lockstep: bool, pty: bool = False) -> dict[str, float]:
    """``pty``: the driver opens the simulator's pty (with dynamixel-sdk's own port, as in
    another process) even in lockstep."""
    from efficient_comm import Container, ManualClock
    from humanoid_sim.driver import WaitingPortHandler
    from humanoid_sim.soccer.compose import compose

    clock = ManualClock() if lockstep else None
    with Container("bench", dds=False, clock=clock) as container:
        # The robot stands and tracks a ball the simulator kicks (as before the striker):
        # comparable with earlier figures; the demo_* measures have it play.
        robot = compose(container, simulator={"ball_velocity": [0.0, 0.3],
                                              "ball_kick_period": 3.0}, play=False)
        if pty:
            robot.driver.port_factory = WaitingPortHandler
        warm = 1.0
        if lockstep:
            container.advance(warm)
        else:
            container.spin_for(warm)
        robot.monitor.window()
        sim0, cpu0, wall0 = robot.simulator.sim_time_s, time.process_time(), time.monotonic()
        frames0 = robot.simulator.frames
        if lockstep:
            container.advance(seconds)
        else:
            container.spin_for(seconds)
        wall = time.monotonic() - wall0
        window = robot.monitor.window().summary()
        return {
            "rtf": (robot.simulator.sim_time_s - sim0) / wall,
            "camera_fps_wall": (robot.simulator.frames - frames0) / wall,
            "cpu_share": (time.process_time() - cpu0) / wall,
            "cpu_per_sim_s": (time.process_time() - cpu0) / (robot.simulator.sim_time_s - sim0),
            "render_ms": robot.simulator.status()["render_ms_mean"],
            "tracking_p95_deg": window["tracking_error_p95_deg"],
            "latency_median_ms": window["latency_median_ms"],
        }


def render_only(frames: int) -> dict[str, float]:
    import mujoco
    import numpy as np

    from humanoid_sim.mujoco_plant import MujocoPlant
    from humanoid_sim.render import OffscreenCamera

    plant = MujocoPlant()
    camera = OffscreenCamera(plant.model, camera="head_camera", width=320, height=240)
    out = np.empty((240, 320, 3), dtype=np.uint8)
    mujoco.mj_forward(plant.model, plant.data)
    camera.render(plant.data, out)
    started = time.perf_counter()
    for _ in range(frames):
        camera.render(plant.data, out)
    fps = frames / (time.perf_counter() - started)
    camera.close()
    return {"render_fps": fps, "backend_egl": float(camera.backend == "egl")}


def _demo_report(options: list[str], *, timeout_s: float,
                 env: dict[str, str] | None = None) -> Callable[[str], float]:
    """Run the demo as a user runs it (``options`` and a report of its own); a reader of
    the report's figures: a pattern's first group as a number, an error if it is missing."""
    import re
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        report = Path(tmp, "report.md")
        result = subprocess.run(
            [sys.executable, "-m", "humanoid_sim.demo", *options, "--report", str(report)],
            capture_output=True, text=True, timeout=timeout_s, check=False, cwd=tmp, env=env)
        if result.returncode not in (0, 3):  # 3: fell and still down; a figure all the same
            raise RuntimeError(result.stdout[-2000:] + result.stderr[-2000:])
        text = report.read_text()

    def figure(pattern: str) -> float:
        found = re.search(pattern, text)
        if found is None:
            raise RuntimeError(f"no {pattern!r} in the demo's report:\n{text}")
        return float(found.group(1))

    return figure


def demo_run(seconds: float, *, lockstep: bool) -> dict[str, float]:
    """The demo as a user runs it; its figures from its report."""
    figure = _demo_report(
        ["--no-dds", "--duration", str(seconds), "--stats-period", str(seconds),
         *(["--lockstep"] if lockstep else [])], timeout_s=60 + 20 * seconds)
    return {"rtf": figure(r"\| real-time factor \| ([\d.]+)"),
            "walked_m": figure(r"\| distance walked \(ground truth\) \| ([\d.]+) m"),
            "kicks": figure(r"\| kicks \| (\d+)"),
            "falls": figure(r"\| falls and get-ups \| (\d+) falls"),
            "bus_hz": figure(r"\| servo bus cycles \(joint states\) \| \d+ \(([\d.]+) Hz\)")}


def split_run(seconds: float, *, transport: str) -> dict[str, float]:
    """The split demo (``--split TRANSPORT``) on a DDS domain of its own; figures from its
    report: the split's row gives both processes' CPU time while the robot played."""
    from efficient_comm.testing import isolated_domain_id, ros_env

    figure = _demo_report(
        ["--split", transport, "--duration", str(seconds), "--stats-period", str(seconds)],
        timeout_s=120 + 20 * seconds, env=ros_env(isolated_domain_id()))
    wall = figure(r"\| split: .*; CPU in ([\d.]+) s")
    body = figure(r"\| split: .*: body ([\d.]+) s") / wall
    perception = figure(r"\| split: .*, perception ([\d.]+) s") / wall
    simulated = figure(r"\| simulated time \| ([\d.]+) s in")
    # Frames over the robot's playing time: the report's own rate also counts the seconds
    # the body waited for perception to start and be discovered.
    camera_fps = figure(r"\| split: .*CPU in [\d.]+ s \((\d+) camera frames\)") / wall
    return {"rtf": figure(r"\| real-time factor \| ([\d.]+)"),
            "camera_fps": camera_fps,
            "detection_hz": figure(r"\| ball detections \| \d+ \(([\d.]+) Hz\)"),
            "body_cpu_share": body, "perception_cpu_share": perception,
            "cpu_share": body + perception, "load": os.getloadavg()[0],
            # CPU seconds per simulated second: the same work whatever share of the cores
            # the machine's load left the robot (a robot held back does less, and uses less)
            "cpu_per_sim_s": (body + perception) * wall / simulated,
            # perception's CPU per camera frame (it reads each): the transport's share
            "perception_ms_per_frame": 1000 * perception / max(camera_fps, 1e-9),
            "dds_writes": (figure(r"\| split: .*, (\d+) also written to DDS")
                           if transport == "shm" else -1.0),
            "falls": figure(r"\| falls and get-ups \| (\d+) falls")}


def child(kind: str, args: argparse.Namespace) -> dict[str, Any]:
    if kind.startswith("split_"):
        return split_run(args.seconds, transport=kind.removeprefix("split_"))
    if kind.startswith("demo_"):
        return demo_run(args.seconds, lockstep=kind == "demo_lockstep")
    if kind in ("bus", "bus_fast"):
        return bus_cycles(args.cycles, fast=kind == "bus_fast")
    if kind == "bus_work":
        return bus_work(max(5, args.cycles // 20))
    if kind == "render":
        return render_only(args.frames)
    return robot_run(args.seconds, lockstep=kind.startswith("lockstep"),
                     pty=kind == "lockstep_pty")


KINDS = ("bus", "bus_fast", "bus_work", "render", "lockstep", "realtime", "lockstep_pty",
         "demo_lockstep", "demo_realtime", "split_shm", "split_dds")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0] if __doc__ else None)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--seconds", type=float, default=10.0, help="per robot run")
    ap.add_argument("--cycles", type=int, default=1000, help="bus cycles per run")
    ap.add_argument("--frames", type=int, default=200, help="frames of the render baseline")
    ap.add_argument("--quick", action="store_true", help="1 short run each: a smoke test")
    ap.add_argument("--out", type=Path, default=DEFAULT_OUT)
    ap.add_argument("--only", action="append", choices=KINDS, metavar="KIND",
                    help=f"measure only this (repeatable): {', '.join(KINDS)}")
    ap.add_argument("--child", choices=KINDS, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.quick:
        args.repeat, args.seconds, args.cycles, args.frames = 1, 2.0, 100, 20
    if args.child:
        print(json.dumps(child(args.child, args)))
        return 0

    kinds = args.only or KINDS
    runs: dict[str, list[dict[str, float]]] = {k: [] for k in kinds}
    for _ in range(args.repeat):  # interleaved, so drifting machine load hits all alike
        for kind in kinds:
            result = subprocess.run(
                [sys.executable, __file__, "--child", kind, "--seconds", str(args.seconds),
                 "--cycles", str(args.cycles), "--frames", str(args.frames)],
                capture_output=True, text=True, timeout=600, check=False,
            )
            if result.returncode:
                print(result.stdout + result.stderr, file=sys.stderr)
                return 1
            runs[kind].append(json.loads(result.stdout.strip().splitlines()[-1]))

    def med(kind: str, key: str) -> float:
        return statistics.median(r[key] for r in runs[kind])

    print(f"medians of {args.repeat} run(s), {args.seconds:g} s robot runs, "
          f"{args.cycles} bus cycles")
    summary = _summary(runs, med) if set(kinds) >= set(KINDS[:6]) else {}
    for kind in ("demo_lockstep", "demo_realtime"):
        if kind in runs:
            for key in ("rtf", "walked_m", "kicks", "falls", "bus_hz"):
                summary[f"{kind}_{key}"] = med(kind, key)
            each = ", ".join(f"{r['rtf']:.2f}" for r in runs[kind])
            falls = ", ".join(f"{r['falls']:.0f}" for r in runs[kind])
            print(f"the demo, robot playing (walking, kicking), {kind.split('_')[1]}: RTF "
                  f"{med(kind, 'rtf'):.2f} = {med(kind, 'rtf') / TARGET_RTF:.2f}x the 1.0 "
                  f"target (runs: {each}); "
                  f"walked {med(kind, 'walked_m'):.2f} m, {med(kind, 'kicks'):.0f} kicks, "
                  f"{med(kind, 'falls'):.0f} falls in {args.seconds:g} s; servo bus "
                  f"{med(kind, 'bus_hz'):.0f} Hz of 100 (each run's falls: "
                  f"{falls})")
    if "lockstep" in runs and "lockstep_pty" in runs:
        summary.update(_port_summary(runs, med))
    if "split_shm" in runs and "split_dds" in runs:
        summary.update(_split_summary(runs, med, args.seconds))
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({"summary": summary, "runs": runs}, indent=1))
    print(f"written {args.out}")
    return 0


def _port_summary(runs: dict[str, list[dict[str, float]]],
                  med: Callable[[str, str], float]) -> dict[str, float]:
    """The lockstep robot with its driver wired straight to the emulator against the same
    robot with its driver on the pty, printed."""
    ratio = statistics.median(  # each run pair's ratio (run one after the other), then median
        d["cpu_per_sim_s"] / p["cpu_per_sim_s"]
        for d, p in zip(runs["lockstep"], runs["lockstep_pty"], strict=True))
    summary = {"lockstep_cpu_per_sim_s": med("lockstep", "cpu_per_sim_s"),
               "lockstep_pty_cpu_per_sim_s": med("lockstep_pty", "cpu_per_sim_s"),
               "lockstep_pty_rtf": med("lockstep_pty", "rtf"),
               "lockstep_direct_pty_cpu_ratio": ratio}
    print(f"lockstep robot, driver wired straight to the emulator: RTF "
          f"{med('lockstep', 'rtf'):.2f}, {summary['lockstep_cpu_per_sim_s']:.3f} CPU s per "
          f"simulated s; through the pty: RTF {summary['lockstep_pty_rtf']:.2f}, "
          f"{summary['lockstep_pty_cpu_per_sim_s']:.3f}; CPU direct/pty {ratio:.2f}x")
    return summary


def _split_summary(runs: dict[str, list[dict[str, float]]],
                   med: Callable[[str, str], float], seconds: float) -> dict[str, float]:
    """The split robot over shared memory against the same split over DDS, printed."""
    def ratio(key: str) -> float:  # each run pair's ratio, then the median
        return statistics.median(
            s[key] / d[key] if d[key] else float("nan")
            for s, d in zip(runs["split_shm"], runs["split_dds"], strict=True))

    summary = {f"{kind}_{key}": med(kind, key) for kind in ("split_shm", "split_dds")
               for key in ("rtf", "camera_fps", "detection_hz", "cpu_share", "body_cpu_share",
                           "perception_cpu_share", "cpu_per_sim_s",
                           "perception_ms_per_frame", "falls", "load")}
    summary.update({f"split_{key}_ratio": ratio(key) for key in
                    ("rtf", "camera_fps", "cpu_share", "body_cpu_share",
                     "perception_cpu_share", "cpu_per_sim_s", "perception_ms_per_frame")})
    summary["split_shm_dds_writes"] = max(r["dds_writes"] for r in runs["split_shm"])
    s = summary
    for kind, what in (("split_shm", "shared memory"), ("split_dds", "DDS")):
        each = ", ".join(f"{100 * r['cpu_share']:.0f}" for r in runs[kind])
        print(f"split robot, image over {what:<13}: camera {s[kind + '_camera_fps']:.1f} fps "
              f"of 30, RTF {s[kind + '_rtf']:.2f}, detections {s[kind + '_detection_hz']:.1f} "
              f"Hz; CPU {100 * s[kind + '_cpu_share']:.0f} % of one core (body "
              f"{100 * s[kind + '_body_cpu_share']:.0f} %, perception "
              f"{100 * s[kind + '_perception_cpu_share']:.0f} %; runs: {each} %), "
              f"{s[kind + '_cpu_per_sim_s']:.2f} CPU s per simulated s, perception "
              f"{s[kind + '_perception_ms_per_frame']:.1f} ms CPU a frame; {seconds:g} s each, "
              f"load average {s[kind + '_load']:.1f}")
    print(f"split robot, shared memory / DDS (median of each run pair): camera fps "
          f"{s['split_camera_fps_ratio']:.2f}x, RTF {s['split_rtf_ratio']:.2f}x, CPU "
          f"{s['split_cpu_share_ratio']:.2f}x (body {s['split_body_cpu_share_ratio']:.2f}x, "
          f"perception {s['split_perception_cpu_share_ratio']:.2f}x), CPU per simulated "
          f"second {s['split_cpu_per_sim_s_ratio']:.2f}x, perception per frame "
          f"{s['split_perception_ms_per_frame_ratio']:.2f}x; target 30 fps, RTF 1 "
          f"and CPU < 1x; images written to DDS over shared memory: "
          f"{s['split_shm_dds_writes']:.0f}")
    return summary


def _summary(runs: dict[str, list[dict[str, float]]],
             med: Callable[[str, str], float]) -> dict[str, float]:
    """The figures of the bus, robot and render measures, printed."""
    summary = {
        "bus_hz": med("bus", "bus_hz"),
        "bus_failures": sum(r["failures"] for r in runs["bus"]),
        "pty_echo_hz": med("bus", "echo_hz"),
        "bus_cpu_hz": med("bus", "bus_cpu_hz"),
        "bus_fast_hz": med("bus_fast", "bus_hz"),
        "bus_fast_cpu_hz": med("bus_fast", "bus_cpu_hz"),
        "bus_fast_failures": sum(r["failures"] for r in runs["bus_fast"]),
        "pty_echo_fast_hz": med("bus_fast", "echo_hz"),
        # The ratio of each run's pair (run together, under the same load), then the median.
        "bus_fast_ratio": statistics.median(
            f["bus_hz"] / p["bus_hz"] for f, p in zip(runs["bus_fast"], runs["bus"], strict=True)),
        **{f"{k}_work_us": med("bus_work", f"{k}_emulator_us") + med("bus_work", f"{k}_sdk_us")
           for k in ("sync", "fast")},
        **{f"{k}_{side}_us": med("bus_work", f"{k}_{side}_us")
           for k in ("sync", "fast") for side in ("emulator", "sdk")},
        "bus_fast_cpu_ratio": statistics.median(
            f["bus_cpu_hz"] / p["bus_cpu_hz"]
            for f, p in zip(runs["bus_fast"], runs["bus"], strict=True)),
        "lockstep_rtf": med("lockstep", "rtf"),
        "lockstep_tracking_p95_deg": med("lockstep", "tracking_p95_deg"),
        "realtime_rtf": med("realtime", "rtf"),
        "realtime_camera_fps": med("realtime", "camera_fps_wall"),
        "realtime_cpu_share": med("realtime", "cpu_share"),
        "realtime_latency_median_ms": med("realtime", "latency_median_ms"),
        "realtime_tracking_p95_deg": med("realtime", "tracking_p95_deg"),
        "render_ms_in_pipeline": med("realtime", "render_ms"),
        "render_only_fps": med("render", "render_fps"),
    }
    s = summary
    for label, key, echo, fast in (("sync read", "bus", "pty_echo", False),
                                   ("fast sync read", "bus_fast", "pty_echo_fast", True)):
        print(f"bus, 20 servos {label:>14} + sync write: {s[key + '_hz']:8.0f} Hz  = "
              f"{s[key + '_hz'] / TARGET_BUS_HZ:5.2f}x the 200 Hz target "
              f"({s[key + '_failures']} failed transfers; {s[key + '_cpu_hz']:.0f} cycles per "
              f"CPU second; bare pty round trip {s[echo + '_hz']:.0f} Hz, bus/pty "
              f"{s[key + '_hz'] / s[echo + '_hz']:.2f}; on a 1 Mbps wire a cycle would take "
              f"at least {wire_ms(fast):.2f} ms)")
    print(f"fast sync read / sync read: {s['bus_fast_ratio']:.2f}x the bus cycle rate, "
          f"{s['bus_fast_cpu_ratio']:.2f}x per CPU second (each the median of the runs' pairs)")
    print(f"one read of 20 servos, Python work without the pty: sync read "
          f"{s['sync_work_us']:.0f} us (emulator {s['sync_emulator_us']:.0f}, dynamixel-sdk "
          f"{s['sync_sdk_us']:.0f}), fast sync read {s['fast_work_us']:.0f} us (emulator "
          f"{s['fast_emulator_us']:.0f}, dynamixel-sdk {s['fast_sdk_us']:.0f}): "
          f"{s['sync_work_us'] / s['fast_work_us']:.2f}x less work")
    print(f"whole robot, lockstep as fast as possible: RTF {s['lockstep_rtf']:5.2f} "
          f"= {s['lockstep_rtf'] / TARGET_RTF:.2f}x the 1.0 target "
          f"(tracking p95 {s['lockstep_tracking_p95_deg']:.2f}°)")
    print(f"whole robot, real time: RTF {s['realtime_rtf']:.2f}, camera "
          f"{s['realtime_camera_fps']:.1f} fps of 30, CPU {100 * s['realtime_cpu_share']:.0f} % "
          f"of one core, image->command latency median {s['realtime_latency_median_ms']:.1f} ms,"
          f" tracking p95 {s['realtime_tracking_p95_deg']:.2f}°")
    print(f"camera: {s['render_ms_in_pipeline']:.1f} ms per frame in the pipeline; rendering "
          f"alone {s['render_only_fps']:.0f} fps (camera at 30 fps uses "
          f"{30 / s['render_only_fps'] * 100:.0f} % of that)")
    return summary


if __name__ == "__main__":
    sys.exit(main())
