"""Throttling at the publisher vs. dropping at the subscriber vs. a relay, across a link.

A robot and a monitoring PC are two network namespaces joined by a veth pair; Fast DDS runs
with UDP only (no shared memory), so every byte a subscriber gets crosses the link. The
robot publishes a 30 Hz 640x480 RGB image; the PC has three subscribers: full rate, 5 Hz,
every 10th. Three ways to serve them:

* ``throttled``: a ThrottledPublisher; the 5 Hz and every-10th subscribers ask for it;
* ``plain``: a plain publisher; all three get 30 Hz and two of them drop what they don't
  want (what ROS users do today);
* ``relay``: a plain publisher plus a topic_tools-style throttle relay process on the
  robot, one relayed topic per rate (the PC's slow subscribers read those).

Printed per mode: messages and bytes each subscriber received, the publisher's own
per-subscriber counters, the bytes that left the robot on the veth (interface counters),
and the CPU time of the robot's processes. Then: CPU time of an expensive output (8 ms per
sample) with nobody, one 1 Hz, and one full-rate subscriber.

Needs root (ip netns). Run: ``source scripts/env.sh && python bench/throttle_bench.py``.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

RATE_HZ = 30.0
WIDTH, HEIGHT = 640, 480
TOPIC = "/robot/camera/image"
KINDS = ("full", "rate5", "nth10")
SHARE = {"full": 1.0, "rate5": 5.0 / RATE_HZ, "nth10": 0.1}
EXPENSIVE_S = 0.008
PROFILE = """<?xml version="1.0" encoding="UTF-8"?>
<profiles xmlns="http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles">
  <transport_descriptors>
    <transport_descriptor>
      <transport_id>udp_only</transport_id>
      <type>UDPv4</type>
      <sendBufferSize>8388608</sendBufferSize>
      <receiveBufferSize>8388608</receiveBufferSize>
    </transport_descriptor>
  </transport_descriptors>
  <participant profile_name="udp_only" is_default_profile="true">
    <rtps>
      <userTransports><transport_id>udp_only</transport_id></userTransports>
      <useBuiltinTransports>false</useBuiltinTransports>
    </rtps>
  </participant>
</profiles>
"""


# -- the processes --------------------------------------------------------------------------


def _image() -> Any:
    from sensor_msgs.msg import Image

    return Image(height=HEIGHT, width=WIDTH, encoding="rgb8", step=WIDTH * 3,
                 data=bytes(WIDTH * HEIGHT * 3))


def _qos() -> Any:
    from rclpy.qos import QoSProfile, ReliabilityPolicy

    return QoSProfile(depth=5, reliability=ReliabilityPolicy.BEST_EFFORT)


def _busy(seconds: float) -> None:
    end = time.process_time() + seconds
    while time.process_time() < end:
        pass


def role_pub(mode: str) -> None:
    """The robot's camera: composed, throttled or plain; expensive_* modes compute first."""
    from efficient_comm import Container
    from efficient_comm.handle import NodeHandle
    from throttle_publisher import ThrottledPublisher

    msg = _image()
    expensive = mode.startswith("expensive")

    class Camera:
        def __init__(self, node: NodeHandle) -> None:
            self.node = node
            self.computed = 0
            if mode == "plain" or mode == "relay":
                self.pub: Any = node.create_publisher(type(msg), TOPIC, qos=_qos())
                self.throttled = None
            else:
                self.throttled = ThrottledPublisher(node, type(msg), TOPIC, qos=_qos(),
                                                    count_bytes=True)
                self.pub = self.throttled
            node.create_timer(1.0 / RATE_HZ, self.tick)

        def tick(self) -> None:
            if self.throttled is not None and expensive and not self.throttled.wants():
                self.throttled.skip()
                return
            if expensive:
                _busy(EXPENSIVE_S)
            self.computed += 1
            self.pub.publish(msg)

    with Container("robot", serve=False) as container:
        camera = container.add(Camera, name="camera")
        _serve_commands(container, lambda: {
            "computed": camera.computed,
            "per_subscriber": {
                str(s.options): {"sent": s.sent, "bytes": s.sent_bytes}
                for s in (camera.throttled.stats().values() if camera.throttled else [])
            },
        })


def role_relay() -> None:
    """topic_tools-style throttle on the robot: plain rclpy, one relayed topic per rate."""
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from sensor_msgs.msg import Image

    rclpy.init()
    node = rclpy.create_node("relay")
    fast = node.create_publisher(Image, TOPIC + "_5hz", _qos())
    nth = node.create_publisher(Image, TOPIC + "_nth10", _qos())
    state = {"last": 0.0, "count": 0}

    def on_image(img: Any) -> None:
        now = time.monotonic()
        if now - state["last"] >= 0.2 - 0.01:
            state["last"] = now
            fast.publish(img)
        if state["count"] % 10 == 0:
            nth.publish(img)
        state["count"] += 1

    node.create_subscription(Image, TOPIC, on_image, _qos())
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    executor.spin()


def role_sub(mode: str, kind: str) -> None:
    """One PC subscriber: prints READY, counts between START and STOP, prints JSON."""
    from rclpy.serialization import serialize_message

    from efficient_comm import Standalone
    from efficient_comm.handle import NodeHandle
    from throttle_publisher import ThrottledSubscription, ThrottleOptions

    size = len(serialize_message(_image()))
    counts = {"received": 0, "kept": 0, "counting": 0}

    def on_image(_img: Any) -> None:
        if not counts["counting"]:
            return
        counts["received"] += 1
        n = counts["received"]
        # Subscriber-side dropping, as a plain subscriber would do.
        keep = kind == "full" or mode != "plain" or (kind == "nth10" and n % 10 == 1) or (
            kind == "rate5" and n % 6 == 1
        )
        counts["kept"] += keep

    class Viewer:
        def __init__(self, node: NodeHandle) -> None:
            msg_type = type(_image())
            if kind == "full" or mode == "plain":
                self.sub: Any = node.create_subscription(msg_type, TOPIC, on_image, qos=_qos())
            elif mode == "relay":
                suffix = "_5hz" if kind == "rate5" else "_nth10"
                self.sub = node.create_subscription(msg_type, TOPIC + suffix, on_image,
                                                    qos=_qos())
            else:
                options = {
                    "rate5": ThrottleOptions(max_rate_hz=5.0),
                    "rate1": ThrottleOptions(max_rate_hz=1.0),
                    "nth10": ThrottleOptions(every_nth=10),
                }[kind]
                self.sub = ThrottledSubscription(node, msg_type, TOPIC, on_image,
                                                 options=options, qos=_qos())

    with Standalone(Viewer, name=f"viewer_{kind}", args=[]) as viewer:
        got_first = time.monotonic() + 30
        counts["counting"] = 1
        while counts["received"] == 0 and time.monotonic() < got_first:
            viewer.spin_once(0.05)
        counts["received"] = counts["kept"] = 0
        print("READY", flush=True)
        _wait_line("START", viewer.spin_once)
        counts["received"] = counts["kept"] = 0
        _wait_line("STOP", viewer.spin_once)
        print(json.dumps({"kind": kind, "received": counts["received"], "kept": counts["kept"],
                          "bytes": counts["received"] * size}), flush=True)


def _wait_line(expected: str, spin: Any) -> None:
    import select

    while True:
        ready, _, _ = select.select([sys.stdin], [], [], 0)
        if ready:
            line = sys.stdin.readline().strip()
            if line == expected:
                return
        spin(0.01)


def _serve_commands(container: Any, stats: Any) -> None:
    """Spin; answer STATS on stdin with a JSON line; stop on EOF."""
    import select

    print("READY", flush=True)
    while True:
        ready, _, _ = select.select([sys.stdin], [], [], 0)
        if ready:
            line = sys.stdin.readline()
            if not line:
                return
            if line.strip() == "STATS":
                print(json.dumps(stats()), flush=True)
        container.spin_once(0.005)


# -- the orchestrator -----------------------------------------------------------------------


class Link:
    """Two namespaces and a veth pair; removed on exit."""

    def __init__(self) -> None:
        tag = os.getpid() % 10000
        self.robot, self.pc = f"ecrobot{tag}", f"ecpc{tag}"
        self.dev_robot, self.dev_pc = f"ecr{tag}", f"ecp{tag}"
        subnet = f"10.231.{tag % 250}"
        cmds = [
            f"ip netns add {self.robot}", f"ip netns add {self.pc}",
            f"ip link add {self.dev_robot} type veth peer name {self.dev_pc}",
            f"ip link set {self.dev_robot} netns {self.robot}",
            f"ip link set {self.dev_pc} netns {self.pc}",
            f"ip -n {self.robot} addr add {subnet}.1/24 dev {self.dev_robot}",
            f"ip -n {self.pc} addr add {subnet}.2/24 dev {self.dev_pc}",
        ]
        for ns, dev in ((self.robot, self.dev_robot), (self.pc, self.dev_pc)):
            cmds += [f"ip -n {ns} link set lo up", f"ip -n {ns} link set {dev} up",
                     f"ip -n {ns} route add 224.0.0.0/4 dev {dev}"]
        for cmd in cmds:
            subprocess.run(cmd.split(), check=True)

    def tx_bytes(self) -> int:
        out = subprocess.run(["ip", "-n", self.robot, "-j", "-s", "link", "show",
                              self.dev_robot], check=True, capture_output=True, text=True)
        return int(json.loads(out.stdout)[0]["stats64"]["tx"]["bytes"])

    def close(self) -> None:
        for ns in (self.robot, self.pc):
            subprocess.run(["ip", "netns", "del", ns], check=False)


def _cpu_s(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def _start(ns: str, args: list[str], env: dict[str, str]) -> subprocess.Popen[str]:
    return subprocess.Popen(
        ["ip", "netns", "exec", ns, sys.executable, __file__, *args],
        stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, env=env,
        start_new_session=True,
    )


def _line(proc: subprocess.Popen[str], timeout_s: float = 60.0) -> str:
    import select

    assert proc.stdout is not None
    ready, _, _ = select.select([proc.stdout], [], [], timeout_s)
    if not ready:
        raise TimeoutError("a benchmark process did not answer")
    line = proc.stdout.readline().strip()
    if not line:
        raise RuntimeError(f"a benchmark process ended (exit {proc.wait()})")
    return line


def _send(proc: subprocess.Popen[str], text: str) -> None:
    assert proc.stdin is not None
    proc.stdin.write(text + "\n")
    proc.stdin.flush()


def run_mode(link: Link, mode: str, seconds: float, env: dict[str, str],
             kinds: tuple[str, ...] = KINDS) -> dict[str, Any]:
    procs: list[subprocess.Popen[str]] = []
    try:
        pub = _start(link.robot, ["--role", "pub", "--mode", mode], env)
        procs.append(pub)
        robot_pids = [pub.pid]
        if mode == "relay":
            relay = _start(link.robot, ["--role", "relay"], env)
            procs.append(relay)
            robot_pids.append(relay.pid)
        assert _line(pub) == "READY"
        subs = []
        for kind in kinds:
            sub = _start(link.pc, ["--role", "sub", "--mode", mode, "--kind", kind], env)
            procs.append(sub)
            subs.append(sub)
        for sub in subs:
            assert _line(sub, 90) == "READY"
        _send(pub, "STATS")
        before = json.loads(_line(pub))
        tx0, cpu0 = link.tx_bytes(), [_cpu_s(p) for p in _children(robot_pids)]
        for sub in subs:
            _send(sub, "START")
        time.sleep(seconds)  # the measurement window itself, not synchronisation
        for sub in subs:
            _send(sub, "STOP")
        tx1, cpu1 = link.tx_bytes(), [_cpu_s(p) for p in _children(robot_pids)]
        _send(pub, "STATS")
        after = json.loads(_line(pub))
        received = [json.loads(_line(sub)) for sub in subs]
        return {
            "mode": mode,
            "seconds": seconds,
            "link_tx_bytes": tx1 - tx0,
            "robot_cpu_s": sum(cpu1) - sum(cpu0),
            "computed": after["computed"] - before["computed"],
            "subscribers": received,
            "publisher_counters": {
                k: {"sent": v["sent"] - before["per_subscriber"].get(k, {}).get("sent", 0),
                    "bytes": v["bytes"] - before["per_subscriber"].get(k, {}).get("bytes", 0)}
                for k, v in after["per_subscriber"].items()
            },
        }
    finally:
        for proc in procs:
            if proc.poll() is None:
                proc.kill()
            proc.wait()


def _children(pids: list[int]) -> list[int]:
    """The python processes under ``ip netns exec`` (it execs, so the pid is the same)."""
    return pids


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--role", choices=["orchestrate", "pub", "sub", "relay"],
                        default="orchestrate")
    parser.add_argument("--mode", default="throttled")
    parser.add_argument("--kind", default="full")
    parser.add_argument("--seconds", type=float, default=10.0)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--out", type=Path,
                        default=Path(__file__).with_name("out") / "throttle_bench.json")
    parser.add_argument("--plot", type=Path, default=Path(__file__).resolve().parents[1]
                        / "docs" / "bench" / "throttle_bytes.png")
    parser.add_argument("--replot", type=Path, help="report and plot an earlier JSON output")
    args = parser.parse_args()
    if args.replot:
        earlier: list[dict[str, Any]] = json.loads(args.replot.read_text())
        report(earlier)
        plot(earlier, args.plot)
        return 0
    if args.role == "pub":
        role_pub(args.mode)
        return 0
    if args.role == "sub":
        role_sub(args.mode, args.kind)
        return 0
    if args.role == "relay":
        role_relay()
        return 0
    if os.geteuid() != 0:
        print("throttle_bench needs root (network namespaces); skipped", file=sys.stderr)
        return 0
    profile = Path(tempfile.mkdtemp()) / "udp_only.xml"
    profile.write_text(PROFILE)
    env = dict(os.environ, FASTRTPS_DEFAULT_PROFILES_FILE=str(profile),
               ROS_AUTOMATIC_DISCOVERY_RANGE="SUBNET", ROS_DOMAIN_ID="7")
    env.pop("_ROS_WHEELS_BOOTSTRAP_COMPLETE", None)
    link = Link()
    results: list[dict[str, Any]] = []
    try:
        for run in range(args.repeat):
            for mode in ("throttled", "plain", "relay"):
                results.append(run_mode(link, mode, args.seconds, env))
                print(f"[run {run + 1}/{args.repeat}] {mode}: ok", file=sys.stderr)
            for mode, kinds in (("expensive_none", ()), ("expensive_1hz", ("rate1",)),
                                ("expensive_full", ("full",))):
                results.append(run_mode(link, mode, args.seconds, env, kinds))
                print(f"[run {run + 1}/{args.repeat}] {mode}: ok", file=sys.stderr)
    finally:
        link.close()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(results, indent=1))
    report(results)
    plot(results, args.plot)
    return 0


def report(results: list[dict[str, Any]]) -> None:
    def med(values: list[float]) -> float:
        return statistics.median(values) if values else float("nan")

    frame = WIDTH * HEIGHT * 3
    print(f"\nbytes per second that crossed the link (median of runs; one frame = {frame} B)")
    print(f"{'mode':<12} {'link MB/s':>10} {'robot CPU %':>12}  " + "  ".join(
        f"{k + ' MB/s':>12} {k + ' share':>12}" for k in KINDS))
    full_rate = {}
    for mode in ("throttled", "plain", "relay"):
        runs = [r for r in results if r["mode"] == mode]
        link_rate = med([r["link_tx_bytes"] / r["seconds"] / 1e6 for r in runs])
        cpu = med([100 * r["robot_cpu_s"] / r["seconds"] for r in runs])
        per = {}
        for kind in KINDS:
            per[kind] = med([next(s["bytes"] for s in r["subscribers"] if s["kind"] == kind)
                             / r["seconds"] / 1e6 for r in runs])
        full_rate[mode] = per["full"]
        print(f"{mode:<12} {link_rate:>10.1f} {cpu:>12.1f}  " + "  ".join(
            f"{per[k]:>12.2f} {per[k] / per['full'] if per['full'] else 0:>12.3f}"
            for k in KINDS))
    print("\nrequested shares: " + ", ".join(f"{k} {SHARE[k]:.3f}" for k in KINDS)
          + "  (target: throttled share <= requested + 5 %)")
    print("\nthrottled mode, the publisher's own counters per subscriber (median of runs)")
    runs = [r for r in results if r["mode"] == "throttled"]
    for key in sorted({k for r in runs for k in r["publisher_counters"]}):
        sent = med([r["publisher_counters"][key]["sent"] / r["seconds"] for r in runs])
        rate = med([r["publisher_counters"][key]["bytes"] / r["seconds"] / 1e6 for r in runs])
        print(f"  {key}: {sent:.2f} samples/s, {rate:.2f} MB/s")
    print("\nexpensive output (8 ms per computed sample), robot CPU % and samples computed/s")
    for mode in ("expensive_none", "expensive_1hz", "expensive_full"):
        runs = [r for r in results if r["mode"] == mode]
        print(f"{mode:<16} {med([100 * r['robot_cpu_s'] / r['seconds'] for r in runs]):>8.1f} %"
              f" {med([r['computed'] / r['seconds'] for r in runs]):>8.1f}/s")


def plot(results: list[dict[str, Any]], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    modes = ("throttled", "plain", "relay")
    fig, (ax, ax2) = plt.subplots(1, 2, figsize=(12, 4.5), gridspec_kw={"width_ratios": [2, 1]})
    width = 0.2
    for i, kind in enumerate((*KINDS, "link")):
        values = []
        for mode in modes:
            runs = [r for r in results if r["mode"] == mode]
            if kind == "link":
                per_run = [r["link_tx_bytes"] / r["seconds"] / 1e6 for r in runs]
            else:
                per_run = [next(x["bytes"] for x in r["subscribers"] if x["kind"] == kind)
                           / r["seconds"] / 1e6 for r in runs]
            values.append(statistics.median(per_run))
        xs = [m + (i - 1.5) * width for m in range(len(modes))]
        bars = ax.bar(xs, values, width, label={"full": "full-rate subscriber",
                                                "rate5": "5 Hz subscriber",
                                                "nth10": "every-10th subscriber",
                                                "link": "total on the link"}[kind])
        ax.bar_label(bars, fmt="%.1f", fontsize=8)
    ax.set_xticks(range(len(modes)), ["throttled\n(ThrottledPublisher)",
                                      "plain\n(subscribers drop)", "relay\n(throttle node)"])
    ax.set_ylabel("MB/s received / sent over the veth link")
    ax.set_title("30 Hz 640x480 RGB over a veth link: bytes per subscriber")
    ax.legend(fontsize=8)
    cpu_modes = ("expensive_none", "expensive_1hz", "expensive_full")
    cpu = [statistics.median([100 * r["robot_cpu_s"] / r["seconds"] for r in results
                              if r["mode"] == m]) for m in cpu_modes]
    bars = ax2.bar(["nobody", "one 1 Hz", "one full-rate"], cpu, color="tab:gray")
    ax2.bar_label(bars, fmt="%.1f %%", fontsize=8)
    ax2.set_ylabel("robot CPU %")
    ax2.set_title("8 ms output/sample, by demand")
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    print(f"plot: {path}")


if __name__ == "__main__":
    sys.exit(main())
