"""rf_bridge latency and throughput ROS 2 -> ROS 1 -> ROS 2, against a direct rospy hop.

Both paths are round trips through the same rospy relay (Debian's ROS 1 on the system
Python), so the relay's cost is common to both and the ratio compares hops:

* ``direct`` (the anchor): a rospy pinger publishes, the relay echoes, the pinger receives:
  two rospy -> rospy hops;
* ``bridge``: a ROS 2 pinger component composed with the bridge in one container (the ROS 2
  side passes references), the bridge's own TCPROS to the relay and back: two hops through
  the bridge.

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
        self.msg: Any
        if kind == "small":
            self.msg = String(data="x" * 16)
        else:
            self.msg = Image(
                height=IMAGE_SIDE, width=IMAGE_SIDE, encoding="mono8", step=IMAGE_SIDE,
                data=bytes(IMAGE_SIDE * IMAGE_SIDE),
            )
        self.pub = node.create_publisher(cls, ping, qos=1000)
        node.create_subscription(cls, pong, self.on_pong, qos=1000)
        self.count = 0
        self.sent_ns = 0
        self.rtts: list[int] = []
        self.remaining = 0

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


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--small-n", type=int, default=500, help="latency samples, small")
    parser.add_argument("--image-n", type=int, default=50, help="latency samples, image")
    parser.add_argument("--small-burst", type=int, default=2000)
    parser.add_argument("--image-burst", type=int, default=50)
    parser.add_argument("--out", type=Path, help="write all runs as JSON")
    args = parser.parse_args()
    plan = {"small": (args.small_n, args.small_burst), "image": (args.image_n, args.image_burst)}
    runs: list[dict[str, Any]] = []
    with Ros1System() as ros1:
        for rep in range(args.repeat):
            for kind, (n_lat, n_burst) in plan.items():
                for path, fn in (("direct", run_direct), ("bridge", run_bridge)):
                    r = fn(ros1, kind, n_lat, n_burst, f"{kind}{rep}")
                    r.update(kind=kind, path=path, rep=rep,
                             rate_hz=r["burst_received"] / r["burst_s"], burst_n=n_burst)
                    runs.append(r)
                    print(f"  run {rep} {kind:5s} {path:6s} rtt {r['rtt_us']:9.1f} us  "
                          f"burst {r['burst_received']}/{n_burst} at {r['rate_hz']:8.1f} msg/s"
                          + (f"  drops {r['drops']}" if r.get("drops") else ""),
                          file=sys.stderr)
    print(f"rf_bridge vs direct rospy, median of {args.repeat} run(s)")
    print(f"{'message':8s} {'direct rtt us':>14s} {'bridge rtt us':>14s} {'ratio':>6s} "
          f"{'direct msg/s':>13s} {'bridge msg/s':>13s} {'ratio':>6s}")
    summary = {}
    for kind in plan:
        med = {}
        for path in ("direct", "bridge"):
            sel = [r for r in runs if r["kind"] == kind and r["path"] == path]
            med[path] = (statistics.median(r["rtt_us"] for r in sel),
                         statistics.median(r["rate_hz"] for r in sel))
        lat_ratio = med["bridge"][0] / med["direct"][0]
        rate_ratio = med["bridge"][1] / med["direct"][1]
        summary[kind] = {"direct": med["direct"], "bridge": med["bridge"],
                         "latency_ratio": lat_ratio, "throughput_ratio": rate_ratio}
        print(f"{kind:8s} {med['direct'][0]:14.1f} {med['bridge'][0]:14.1f} {lat_ratio:6.2f} "
              f"{med['direct'][1]:13.1f} {med['bridge'][1]:13.1f} {rate_ratio:6.2f}")
    target = summary["small"]["latency_ratio"]
    print(f"target: bridge round trip <= 2x the direct one for small messages: "
          f"{target:.2f}x -> {'met' if target <= 2.0 else 'MISSED'}")
    if args.out is not None:
        args.out.write_text(json.dumps({"runs": runs, "summary": summary}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
