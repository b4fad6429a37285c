"""rf_bridge latency and throughput ROS 2 -> ROS 1 -> ROS 2, against a direct rospy hop.

Both paths are round trips through the same rospy relay (Debian's ROS 1 on the system
Python), so the relay's cost is common to both and the ratio compares hops:

* ``direct`` (the anchor): a rospy pinger publishes, the relay echoes, the pinger receives:
  two rospy -> rospy hops;
* ``bridge``: a ROS 2 pinger component composed with the bridge in one container (the ROS 2
  side passes references), the bridge's own TCPROS to the relay and back: two hops through
  the bridge;
* ``bridge_dds``: the bridge as its own process (``ros2 run rf_bridge rf_bridge``) and a plain
  rclpy pinger in this one: each way adds a DDS hop (Fast DDS, loopback) to the bridge hop.

For a small message (std_msgs/String, 16 characters) and a 1 MiB sensor_msgs/Image: median
round-trip latency with one message in flight, and throughput of a burst. Each figure is the
median over ``--repeat`` runs; ratios are bridge / direct. Run:
``source scripts/env.sh && python bench/bridge_bench.py`` (needs scripts/setup_ros1.sh).
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from pathlib import Path
from typing import Any

from sensor_msgs.msg import Image
from std_msgs.msg import String

from efficient_comm import Container
from efficient_comm.handle import NodeHandle
from rf_bridge import BridgeNode, parse_config
from rf_bridge.testing import LineReader, Ros1System, wait_for

ROS1_TYPES = {"small": "std_msgs/String", "image": "sensor_msgs/Image"}
ROS2_TYPES = {"small": "std_msgs/msg/String", "image": "sensor_msgs/msg/Image"}
IMAGE_SIDE = 1024  # mono8: 1 MiB
ROOT = Path(__file__).resolve().parents[1]
PATHS = ("direct", "bridge", "bridge_dds")

RELAY = r"""
import importlib, sys, rospy
src, dst, type_name = sys.argv[1:4]
pkg, name = type_name.split("/")
cls = getattr(importlib.import_module(pkg + ".msg"), name)
rospy.init_node("relay", anonymous=True, disable_signals=True)
pub = rospy.Publisher(dst, cls, queue_size=100000, tcp_nodelay=True)
rospy.Subscriber(src, cls, pub.publish, queue_size=None, tcp_nodelay=True)
print("ready", flush=True)
rospy.spin()
"""

PINGER = r"""
import importlib, json, statistics, sys, threading, time, rospy
ping, pong, type_name, kind = sys.argv[1:5]
n_lat, n_burst = int(sys.argv[5]), int(sys.argv[6])
pkg, name = type_name.split("/")
cls = getattr(importlib.import_module(pkg + ".msg"), name)
if kind == "small":
    msg = cls(data="x" * 16)
else:
    msg = cls(height=1024, width=1024, encoding="mono8", step=1024, data=bytes(1024 * 1024))
rospy.init_node("pinger", anonymous=True, disable_signals=True)
got = threading.Event()
count = [0]
def on_pong(m):
    count[0] += 1
    got.set()
pub = rospy.Publisher(ping, cls, queue_size=1000, tcp_nodelay=True)
rospy.Subscriber(pong, cls, on_pong, queue_size=None, tcp_nodelay=True)
while pub.get_num_connections() == 0:
    time.sleep(0.01)
# wait until the whole loop carries messages
while count[0] == 0:
    got.clear(); pub.publish(msg); got.wait(0.2)
time.sleep(0.2)
rtts = []
for i in range(n_lat):
    got.clear()
    t = time.perf_counter_ns()
    pub.publish(msg)
    if not got.wait(5):
        continue
    rtts.append(time.perf_counter_ns() - t)
time.sleep(0.2)
start_count = count[0]
t = time.perf_counter_ns()
for i in range(n_burst):
    pub.publish(msg)
deadline = time.monotonic() + 30
while count[0] - start_count < n_burst and time.monotonic() < deadline:
    time.sleep(0.001)
elapsed = (time.perf_counter_ns() - t) / 1e9
print(json.dumps({"rtt_us": statistics.median(rtts) / 1e3, "lat_n": len(rtts),
                  "burst_received": count[0] - start_count, "burst_s": elapsed}), flush=True)
"""


class Pinger:
    """The ROS 2 pinger: one message in flight, then a burst (composed with the bridge)."""

    def __init__(self, node: NodeHandle, *, kind: str, ping: str, pong: str) -> None:
        cls = String if kind == "small" else Image
        self.msg = self.make(kind)
        self.pub = node.create_publisher(cls, ping, qos=1000)
        node.create_subscription(cls, pong, self.on_pong, qos=1000)
        self.count = 0
        self.sent_ns = 0
        self.rtts: list[int] = []
        self.remaining = 0

    @staticmethod
    def make(kind: str) -> Any:
        if kind == "small":
            return String(data="x" * 16)
        return Image(
            height=IMAGE_SIDE, width=IMAGE_SIDE, encoding="mono8", step=IMAGE_SIDE,
            data=bytes(IMAGE_SIDE * IMAGE_SIDE),
        )

    def ping(self) -> None:
        self.sent_ns = time.perf_counter_ns()
        self.pub.publish(self.msg)

    def on_pong(self, msg: Any) -> None:
        now = time.perf_counter_ns()
        self.count += 1
        if self.remaining > 0:
            self.rtts.append(now - self.sent_ns)
            self.remaining -= 1
            if self.remaining:
                self.ping()


def run_direct(ros1: Ros1System, kind: str, n_lat: int, n_burst: int, tag: str) -> dict[str, Any]:
    ping, pong = f"/direct_{tag}_ping", f"/direct_{tag}_pong"
    relay = ros1.python(RELAY, ping, pong, ROS1_TYPES[kind], log=f"relay_{tag}")
    assert LineReader(relay).next(30) == "ready"
    pinger = ros1.python(PINGER, ping, pong, ROS1_TYPES[kind], kind, str(n_lat), str(n_burst),
                         log=f"pinger_{tag}")
    result = json.loads(LineReader(pinger).next(120))
    Ros1System.kill(pinger)
    Ros1System.kill(relay)
    return dict(result)


def run_bridge(ros1: Ros1System, kind: str, n_lat: int, n_burst: int, tag: str) -> dict[str, Any]:
    ping, pong = f"/bridge_{tag}_ping", f"/bridge_{tag}_pong"
    relay = ros1.python(RELAY, ping, pong, ROS1_TYPES[kind], log=f"relay_{tag}")
    assert LineReader(relay).next(30) == "ready"
    config = parse_config({
        "ros1": {"master_uri": ros1.master_uri, "node_name": f"/rf_bridge_{tag}",
                 "queue_size": 1000},
        "topics": [
            {"ros2": ping, "type": ROS2_TYPES[kind], "qos": 1000},
            {"ros2": pong, "type": ROS2_TYPES[kind], "direction": "from_peer", "qos": 1000},
        ],
    })
    holder: dict[str, Any] = {}
    with Container(f"bench_{tag}", dds=False) as container:
        container.add(lambda n: holder.setdefault("p", Pinger(n, kind=kind, ping=ping, pong=pong)),
                      name="pinger")
        container.add(lambda n: holder.setdefault("b", BridgeNode(n, config=config)),
                      name="rf_bridge")
        pinger: Pinger = holder["p"]
        bridge: BridgeNode = holder["b"]
        adapter: Any = bridge.adapters["ros1"]
        ex = container.executor
        try:
            assert wait_for(lambda: bool(adapter._pubs[ping].connections), 30)
            # until the whole loop carries messages
            deadline = time.monotonic() + 30
            while pinger.count == 0 and time.monotonic() < deadline:
                pinger.ping()
                ex.spin_until(lambda: pinger.count > 0, timeout_s=0.2)
            ex.spin_for(0.2)
            pinger.rtts.clear()
            pinger.remaining = n_lat
            pinger.ping()
            ex.spin_until(lambda: pinger.remaining == 0, timeout_s=120)
            rtts = list(pinger.rtts)
            ex.spin_for(0.2)
            start_count = pinger.count
            t = time.perf_counter_ns()
            for _ in range(n_burst):
                pinger.pub.publish(pinger.msg)
            ex.spin_until(lambda: pinger.count - start_count >= n_burst, timeout_s=30)
            elapsed = (time.perf_counter_ns() - t) / 1e9
            drops = {f"{s.topic} {s.direction}": s.drops for s in bridge.stats() if s.drops}
        finally:
            bridge.close()
    Ros1System.kill(relay)
    return {"rtt_us": statistics.median(rtts) / 1e3, "lat_n": len(rtts),
            "burst_received": pinger.count - start_count, "burst_s": elapsed, "drops": drops}


def run_bridge_dds(
    ros1: Ros1System, kind: str, n_lat: int, n_burst: int, tag: str
) -> dict[str, Any]:
    import os
    import subprocess

    import rclpy
    import yaml
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node

    from efficient_comm.testing import isolated_domain_id, ros_env

    ping, pong = f"/dds_{tag}_ping", f"/dds_{tag}_pong"
    relay = ros1.python(RELAY, ping, pong, ROS1_TYPES[kind], log=f"relay_{tag}")
    assert LineReader(relay).next(30) == "ready"
    depth = max(n_burst, 10)
    config = ros1.workdir / f"bridge_{tag}.yaml"  # removed with the ROS 1 system
    config.write_text(yaml.safe_dump({
        "ros1": {"master_uri": ros1.master_uri, "node_name": f"/rf_bridge_{tag}",
                 "queue_size": depth},
        "topics": [
            {"ros2": ping, "type": ROS2_TYPES[kind], "qos": depth},
            {"ros2": pong, "type": ROS2_TYPES[kind], "direction": "from_peer", "qos": depth},
        ],
    }))
    domain = isolated_domain_id()
    program = ROOT / "ros2_ws" / "install" / "rf_bridge" / "lib" / "rf_bridge" / "rf_bridge"
    bridge = subprocess.Popen([str(program), "--ros-args", "-p", f"config:={config}"],
                              env=ros_env(domain), start_new_session=True,
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    context = Context()
    rclpy.init(context=context, domain_id=domain)
    node = Node(f"pinger_{tag}", context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    cls = String if kind == "small" else Image
    msg: Any = Pinger.make(kind)
    count = [0]
    pub = node.create_publisher(cls, ping, depth)

    def on_pong(_: Any) -> None:
        count[0] += 1

    node.create_subscription(cls, pong, on_pong, depth)

    def spin_until(pred: Any, timeout_s: float) -> bool:
        end = time.monotonic() + timeout_s
        while not pred() and time.monotonic() < end:
            executor.spin_once(timeout_sec=0.01)
        return bool(pred())

    try:
        deadline = time.monotonic() + 60
        while count[0] == 0 and time.monotonic() < deadline:
            pub.publish(msg)
            spin_until(lambda: count[0] > 0, 0.3)
        spin_until(lambda: False, 0.2)
        rtts = []
        for _ in range(n_lat):
            before = count[0]
            t = time.perf_counter_ns()
            pub.publish(msg)
            if spin_until(lambda b=before: count[0] > b, 5):
                rtts.append(time.perf_counter_ns() - t)
        spin_until(lambda: False, 0.2)
        start_count = count[0]
        t = time.perf_counter_ns()
        for _ in range(n_burst):
            pub.publish(msg)
        spin_until(lambda: count[0] - start_count >= n_burst, 30)
        elapsed = (time.perf_counter_ns() - t) / 1e9
    finally:
        executor.shutdown()
        node.destroy_node()
        context.try_shutdown()
        os.killpg(bridge.pid, 9)
        bridge.wait()
        Ros1System.kill(relay)
    return {"rtt_us": statistics.median(rtts) / 1e3, "lat_n": len(rtts),
            "burst_received": count[0] - start_count, "burst_s": elapsed}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--small-n", type=int, default=500, help="latency samples, small")
    parser.add_argument("--image-n", type=int, default=50, help="latency samples, image")
    parser.add_argument("--small-burst", type=int, default=2000)
    parser.add_argument("--image-burst", type=int, default=50)
    parser.add_argument("--out", type=Path, default=ROOT / "bench" / "out" / "bridge_bench.json",
                        help="where to write all runs and the summary as JSON")
    args = parser.parse_args()
    plan = {"small": (args.small_n, args.small_burst), "image": (args.image_n, args.image_burst)}
    runs: list[dict[str, Any]] = []
    with Ros1System() as ros1:
        for rep in range(args.repeat):
            for kind, (n_lat, n_burst) in plan.items():
                for path, fn in (("direct", run_direct), ("bridge", run_bridge),
                                 ("bridge_dds", run_bridge_dds)):
                    r = fn(ros1, kind, n_lat, n_burst, f"{kind}{rep}")
                    r.update(kind=kind, path=path, rep=rep,
                             rate_hz=r["burst_received"] / r["burst_s"], burst_n=n_burst)
                    runs.append(r)
                    print(f"  run {rep} {kind:5s} {path:6s} rtt {r['rtt_us']:9.1f} us  "
                          f"burst {r['burst_received']}/{n_burst} at {r['rate_hz']:8.1f} msg/s"
                          + (f"  drops {r['drops']}" if r.get("drops") else ""),
                          file=sys.stderr)
    print(f"rf_bridge vs direct rospy, median of {args.repeat} run(s); ratio = path / direct")
    print(f"{'message':8s} {'path':11s} {'rtt us':>10s} {'ratio':>6s} {'msg/s':>9s} {'ratio':>6s}")
    summary: dict[str, Any] = {}
    for kind in plan:
        med = {}
        for path in PATHS:
            sel = [r for r in runs if r["kind"] == kind and r["path"] == path]
            med[path] = (statistics.median(r["rtt_us"] for r in sel),
                         statistics.median(r["rate_hz"] for r in sel))
        summary[kind] = {}
        for path in PATHS:
            lat_ratio = med[path][0] / med["direct"][0]
            rate_ratio = med[path][1] / med["direct"][1]
            summary[kind][path] = {"rtt_us": med[path][0], "rate_hz": med[path][1],
                                   "latency_ratio": lat_ratio, "throughput_ratio": rate_ratio}
            print(f"{kind:8s} {path:11s} {med[path][0]:10.1f} {lat_ratio:6.2f} "
                  f"{med[path][1]:9.1f} {rate_ratio:6.2f}")
    target = summary["small"]["bridge"]["latency_ratio"]
    print(f"target: composed bridge round trip <= 2x the direct one for small messages: "
          f"{target:.2f}x -> {'met' if target <= 2.0 else 'MISSED'}")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({"runs": runs, "summary": summary}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
