"""Large messages between two processes: efficient_comm's shared memory against DDS.

Two containers in two processes with the transport on (``shm``), two plain rclpy nodes over
Fast DDS (``dds``, the baseline) and a bare iceoryx2 loop with no ROS at all (``bare``, the
floor of the mechanism), in the same run, for sensor_msgs/Image payloads of 64 B, 1 MiB and
6 MiB (1920x1080 rgb8), in two patterns:

* ``ping``: one message in flight; the subscriber acknowledges each (a small message), the
  publisher sends the next on the acknowledgement (over shared memory, a message not
  acknowledged within a second is sent again, counted as ``resent``: at start-up, the
  subscriber's acknowledgement writer may not have matched the publisher's reader yet).
  Latency is publish -> callback (the stamp is taken just before ``publish``, read first
  thing in the callback; CLOCK_MONOTONIC);
* ``rate``: the publisher sends back to back; throughput is what the subscriber received per
  second between its first and last message (a reader that falls behind loses messages:
  counted).

CPU per message is each process's user+system time over the run divided by the messages it
sent or received. The shared-memory container runs with a threshold of 0, so the 64 B
message takes shared memory too (by default it would go over DDS).

    python bench/shm_bench.py                 # full: 3 runs of everything, about 10 min
    python bench/shm_bench.py --quick --out /tmp/shm.json   # 1 run, 64 B and 1 MiB, ~100 s
    python bench/shm_bench.py --smoke --out /tmp/shm.json   # does each backend run? ~15 s

``--smoke`` (tests/test_shm_bench_smoke.py) measures 1 MiB only, 10 messages per pattern,
and runs the six process pairs side by side: it shows that every backend carries messages
and that the ratios come out of one run, not what they are (the pairs share the cores).

Prints a table (medians over the runs) and ratios against DDS and against the bare loop;
``--out`` writes the records as JSON.
"""

from __future__ import annotations

import argparse
import concurrent.futures
import ctypes
import json
import os
import resource
import statistics
import subprocess
import sys
import threading
import time
import uuid
from pathlib import Path
from typing import Any

SIZES = {"64B": 64, "1MiB": 1 << 20, "6MiB": 1920 * 1080 * 3}
#: ping over shared memory: a message unacknowledged this long is sent again (see _ros_child)
_RESEND_S = 1.0
BACKENDS = ("bare", "shm", "dds")
MODES = ("ping", "rate")


def _cpu_s() -> float:
    usage = resource.getrusage(resource.RUSAGE_SELF)
    return usage.ru_utime + usage.ru_stime


def _emit(record: dict[str, Any]) -> None:
    print("RESULT " + json.dumps(record), flush=True)


def _stdin_closed(callback: Any) -> None:
    threading.Thread(target=lambda: (sys.stdin.read(), callback()), daemon=True).start()


# -- the ROS sides (shm: containers; dds: plain rclpy) -----------------------------------


def _ros_child(args: argparse.Namespace) -> None:
    import numpy as np
    from rclpy.qos import QoSProfile
    from sensor_msgs.msg import Image
    from std_msgs.msg import UInt64

    qos = QoSProfile(depth=10)
    count = args.count
    state: dict[str, Any] = {"lat": [], "got": 0, "first": 0.0, "last": 0.0, "cpu0": 0.0}

    def on_image(msg: Any, ack: Any) -> None:
        now = time.monotonic_ns()
        if msg.header.frame_id == state.get("last_id"):  # resent (ping): answered, not counted
            ack.publish(UInt64(data=int(msg.header.frame_id)))
            return
        state["last_id"] = msg.header.frame_id
        stamp = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
        _ = np.asarray(msg.data)[:2].sum()  # touch the payload, as a user would
        if state["got"] == 0:
            state["first"], state["cpu0"] = time.monotonic(), _cpu_s()
        state["got"] += 1
        state["last"] = time.monotonic()
        state["lat"].append(now - stamp)
        if args.mode == "ping":
            ack.publish(UInt64(data=int(msg.header.frame_id)))
        if int(msg.header.frame_id) == count - 1:
            finish()

    def sub_record() -> dict[str, Any]:
        got = state["got"]
        return {"side": "sub", "received": got, "lat_ns": state["lat"],
                "span_s": state["last"] - state["first"],
                "cpu_us_per_msg": (_cpu_s() - state["cpu0"]) * 1e6 / max(1, got)}

    image = Image(height=1, width=args.size, encoding="mono8", step=args.size)
    image.data = bytes(args.size)

    def send(i: int, pub: Any) -> None:
        image.header.frame_id = str(i)
        now = time.monotonic_ns()
        image.header.stamp.sec, image.header.stamp.nanosec = divmod(now, 1_000_000_000)
        pub.publish(image)

    done = threading.Event()

    def finish() -> None:
        done.set()

    if args.backend == "shm":
        from efficient_comm import Container

        with Container(f"bench_{args.role}", shm=True, shm_threshold_bytes=0, serve=False,
                       stats_period_s=0) as container:
            holder: dict[str, Any] = {}

            def make(node: Any) -> None:
                if args.role == "sub":
                    ack = node.create_publisher(UInt64, args.topic + "_ack", qos=qos)
                    node.create_subscription(Image, args.topic, lambda m: on_image(m, ack),
                                             qos=qos)
                else:
                    holder["pub"] = node.create_publisher(Image, args.topic, qos=qos)
                    node.create_subscription(UInt64, args.topic + "_ack", on_ack, qos=qos)
                    holder["timer"] = node.create_timer(0.01, start)

            sent: dict[str, Any] = {"n": 0, "cpu0": 0.0, "started": False, "at": 0.0,
                                    "resent": 0}

            def on_ack(msg: Any) -> None:
                # Only the acknowledgement of the last message sent: a resent one's first
                # acknowledgement may still come.
                if args.mode == "ping" and sent["n"] < count and msg.data == sent["n"] - 1:
                    send(sent["n"], holder["pub"])
                    sent["n"] += 1
                    sent["at"] = time.monotonic()

            def start() -> None:
                if sent["started"] or holder["pub"].get_subscription_count() < 1:
                    return
                sent["started"] = True
                holder["timer"].cancel()
                sent["cpu0"] = _cpu_s()
                if args.mode == "ping":
                    send(0, holder["pub"])
                    sent["n"], sent["at"] = 1, time.monotonic()
                else:
                    for i in range(count):
                        send(i, holder["pub"])
                    sent["n"] = count

            container.add(make, name=f"bench_{args.role}_node")
            print("ready", flush=True)
            _stdin_closed(finish)
            while not done.is_set():
                container.spin_once(0.1)
                if args.role == "pub" and sent["n"] >= count:
                    break
                if (args.role == "pub" and args.mode == "ping" and sent["started"]
                        and time.monotonic() - sent["at"] > _RESEND_S):
                    # No acknowledgement: the subscriber's acknowledgement writer had not
                    # matched our reader yet when it answered (DDS discovery is not
                    # symmetric; a composed writer writes only to matched readers), and
                    # one in flight would wait forever. Counted, and printed.
                    send(sent["n"] - 1, holder["pub"])
                    sent["at"] = time.monotonic()
                    sent["resent"] += 1
            if args.role == "sub":
                _emit(sub_record())
            else:
                _emit({"side": "pub", "sent": sent["n"], "resent": sent["resent"],
                       "cpu_us_per_msg": (_cpu_s() - sent["cpu0"]) * 1e6 / max(1, sent["n"])})
                sys.stdin.read()  # stay until the parent is done with the subscriber
        return

    import rclpy

    rclpy.init()
    node = rclpy.create_node(f"bench_{args.role}")
    if args.role == "sub":
        ack = node.create_publisher(UInt64, args.topic + "_ack", qos)
        node.create_subscription(Image, args.topic, lambda m: on_image(m, ack), qos)
        print("ready", flush=True)
        _stdin_closed(finish)
        while not done.is_set():
            rclpy.spin_once(node, timeout_sec=0.1)
        _emit(sub_record())
    else:
        pub = node.create_publisher(Image, args.topic, qos)
        sent = {"n": 0}

        def on_ack(msg: Any) -> None:
            if args.mode == "ping" and sent["n"] < count:
                send(sent["n"], pub)
                sent["n"] += 1

        node.create_subscription(UInt64, args.topic + "_ack", on_ack, qos)
        print("ready", flush=True)
        while pub.get_subscription_count() < 1:
            rclpy.spin_once(node, timeout_sec=0.01)
        time.sleep(0.2)  # the ack reader's match, which the publisher cannot see
        cpu0 = _cpu_s()
        if args.mode == "ping":
            send(0, pub)
            sent["n"] = 1
            while sent["n"] < count:
                rclpy.spin_once(node, timeout_sec=0.5)
        else:
            for i in range(count):
                send(i, pub)
            sent["n"] = count
        _emit({"side": "pub", "sent": sent["n"],
               "cpu_us_per_msg": (_cpu_s() - cpu0) * 1e6 / max(1, sent["n"])})
        sys.stdin.read()
    node.destroy_node()
    rclpy.shutdown()


# -- the bare iceoryx2 loop -----------------------------------------------------------------


class _Stamp(ctypes.Structure):
    _fields_ = (("seq", ctypes.c_uint64), ("stamp_ns", ctypes.c_uint64))

    @staticmethod
    def type_name() -> str:
        return "shm_bench.Stamp"


def _bare_child(args: argparse.Namespace) -> None:
    import iceoryx2 as iox2
    import numpy as np

    iox2.set_log_level(iox2.LogLevel.Error)
    node = (iox2.NodeBuilder.new().signal_handling_mode(iox2.SignalHandlingMode.Disabled)
            .create(iox2.ServiceType.Ipc))

    def service(name: str) -> tuple[Any, Any]:
        sname = iox2.ServiceName.new(name)
        pubsub = (node.service_builder(sname).publish_subscribe(iox2.Slice[ctypes.c_uint8])
                  .user_header(_Stamp).max_publishers(1).max_subscribers(1)
                  .subscriber_max_buffer_size(2).open_or_create())
        return pubsub, node.service_builder(sname).event().open_or_create()

    data, data_ev = service(args.topic)
    _, ack_ev = service(args.topic + "_ack")
    count = args.count
    timeout = iox2.Duration.from_millis(200)
    if args.role == "sub":
        sub = data.subscriber_builder().buffer_size(2).create()
        listener = data_ev.listener_builder().create()
        acker = ack_ev.notifier_builder().create()
        print("ready", flush=True)
        lat: list[int] = []
        first = last = cpu0 = 0.0
        end = time.monotonic() + 120
        finished = False
        while not finished and time.monotonic() < end:
            listener.timed_wait(timeout)
            while (sample := sub.receive()) is not None:
                now = time.monotonic_ns()
                head = _Stamp.from_address(sample.user_header_ptr)
                n = sample.header.number_of_elements
                view = np.frombuffer(memoryview((ctypes.c_uint8 * n).from_address(
                    sample.payload_ptr)), dtype=np.uint8)
                _ = view[:2].sum()
                if not lat:
                    first, cpu0 = time.monotonic(), _cpu_s()
                last = time.monotonic()
                lat.append(now - head.stamp_ns)
                seq = head.seq
                del view
                sample.delete()
                if args.mode == "ping":
                    acker.notify()
                if seq == count - 1:
                    finished = True
        _emit({"side": "sub", "received": len(lat), "lat_ns": lat, "span_s": last - first,
               "cpu_us_per_msg": (_cpu_s() - cpu0) * 1e6 / max(1, len(lat))})
        return
    pub = data.publisher_builder().initial_max_slice_len(args.size).create()
    notifier = data_ev.notifier_builder().create()
    ack_listener = ack_ev.listener_builder().create()
    source = np.zeros(args.size, dtype=np.uint8)
    print("ready", flush=True)
    while data.dynamic_config.number_of_subscribers < 1:
        time.sleep(0.01)
    time.sleep(0.2)  # the subscriber's first receive connects it

    def send(i: int) -> None:
        sample = pub.loan_slice_uninit(args.size)
        target = np.frombuffer(memoryview((ctypes.c_uint8 * args.size).from_address(
            sample.payload_ptr)), dtype=np.uint8)
        head = _Stamp.from_address(sample.user_header_ptr)
        head.seq, head.stamp_ns = i, time.monotonic_ns()
        target[:] = source
        sample.assume_init().send()
        notifier.notify()

    cpu0 = _cpu_s()
    for i in range(count):
        send(i)
        if args.mode == "ping":
            ack_listener.timed_wait(iox2.Duration.from_millis(1000))
    _emit({"side": "pub", "sent": count, "cpu_us_per_msg": (_cpu_s() - cpu0) * 1e6 / count})
    sys.stdin.read()


# -- the parent -----------------------------------------------------------------------------


def _spawn(args: list[str], env: dict[str, str]) -> subprocess.Popen[str]:
    return subprocess.Popen([sys.executable, __file__, *args], env=env, text=True,
                            stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                            stderr=subprocess.DEVNULL, start_new_session=True)


def _result(proc: subprocess.Popen[str], *, timeout_s: float,
            nudge_after_s: float | None = None) -> dict[str, Any] | None:
    """The child's RESULT record; with ``nudge_after_s``, its stdin is closed if it has not
    reported by then (a subscriber waiting for a message that was lost reports at once)."""
    assert proc.stdout is not None
    box: list[dict[str, Any]] = []

    def read() -> None:
        assert proc.stdout is not None
        for line in proc.stdout:
            if line.startswith("RESULT "):
                box.append(json.loads(line[7:]))
                return

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    if nudge_after_s is not None:
        reader.join(nudge_after_s)
        if not box and proc.stdin is not None:
            proc.stdin.close()
    reader.join(timeout_s)
    return box[0] if box else None


def _ready(proc: subprocess.Popen[str]) -> None:
    assert proc.stdout is not None
    line = proc.stdout.readline()
    if line.strip() != "ready":
        raise RuntimeError(f"a bench child did not start: {line!r}")


def _stop(proc: subprocess.Popen[str]) -> None:
    for stream in (proc.stdin, proc.stdout):
        if stream is not None and not stream.closed:
            stream.close()
    try:
        proc.wait(timeout=10)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, 9)
        proc.wait()


def run_one(backend: str, size: int, mode: str, count: int, domain: int) -> dict[str, Any]:
    from efficient_comm.testing import ros_env

    env = ros_env(domain)
    topic = f"/shm_bench_{uuid.uuid4().hex[:10]}"
    common = ["--backend", backend, "--size", str(size), "--mode", mode, "--count", str(count),
              "--topic", topic]
    sub = _spawn(["--role", "sub", *common], env)
    pub = None
    try:
        _ready(sub)
        pub = _spawn(["--role", "pub", *common], env)
        _ready(pub)
        pub_rec = _result(pub, timeout_s=120)
        # The subscriber ends by itself on the last message; if that was lost, it is told
        # to report once the messages still on their way (DDS: 1 MiB takes ms) are in.
        sub_rec = _result(sub, timeout_s=30, nudge_after_s=3)
    finally:
        for proc in (pub, sub):
            if proc is not None:
                _stop(proc)
    if pub_rec is None or sub_rec is None:
        # A stalled pair (ping: a message or its acknowledgement lost with one in flight)
        # is a result too: recorded, and the run goes on; main() exits 1 at the end.
        got = sub_rec["received"] if sub_rec is not None else 0
        return {"backend": backend, "size": size, "mode": mode, "sent": None,
                "received": got, "median_us": None, "p99_us": None, "msgs_per_s": None,
                "pub_cpu_us": None, "sub_cpu_us": None, "stalled": True}
    lat = sorted(sub_rec["lat_ns"])
    got = sub_rec["received"]
    return {
        "backend": backend, "size": size, "mode": mode, "sent": pub_rec["sent"], "received": got,
        "resent": pub_rec.get("resent", 0),
        "median_us": lat[len(lat) // 2] / 1e3 if lat else None,
        "p99_us": lat[min(len(lat) - 1, int(len(lat) * 0.99))] / 1e3 if lat else None,
        "msgs_per_s": (got - 1) / sub_rec["span_s"] if got > 1 and sub_rec["span_s"] else None,
        "pub_cpu_us": pub_rec["cpu_us_per_msg"], "sub_cpu_us": sub_rec["cpu_us_per_msg"],
    }


def _median(records: list[dict[str, Any]], key: str) -> float | None:
    values = [r[key] for r in records if r[key] is not None]
    return statistics.median(values) if values else None


def _fmt(value: float | None, spec: str = ".0f") -> str:
    return "-" if value is None else format(value, spec)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="1 run, 64 B and 1 MiB, few msgs")
    parser.add_argument("--smoke", action="store_true",
                        help="1 MiB, 10 msgs, the pairs side by side: runs, not figures")
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--out", type=Path)
    parser.add_argument("--role", choices=("pub", "sub"), help=argparse.SUPPRESS)
    parser.add_argument("--backend", choices=BACKENDS, help=argparse.SUPPRESS)
    parser.add_argument("--size", type=int, help=argparse.SUPPRESS)
    parser.add_argument("--mode", choices=MODES, help=argparse.SUPPRESS)
    parser.add_argument("--count", type=int, help=argparse.SUPPRESS)
    parser.add_argument("--topic", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.role:
        (_bare_child if args.backend == "bare" else _ros_child)(args)
        return
    from efficient_comm.testing import isolated_domain_id

    sizes = ({"1MiB": SIZES["1MiB"]} if args.smoke
             else {k: v for k, v in SIZES.items() if not args.quick or k != "6MiB"})
    repeat = 1 if args.quick or args.smoke else args.repeat
    records: list[dict[str, Any]] = []
    started = time.monotonic()
    load = os.getloadavg()[0]
    domain = isolated_domain_id()
    plan = [(run, label, size, mode, backend) for run in range(repeat)
            for label, size in sizes.items() for mode in MODES for backend in BACKENDS]

    def measure(run: int, label: str, size: int, mode: str, backend: str) -> dict[str, Any]:
        count = (10 if args.smoke else 30 if args.quick
                 else 60 if size > 2 << 20 else 200)
        record = run_one(backend, size, mode, count, domain)
        record.update(run=run, label=label)
        print(f"  run {run} {label:>5} {mode:4} {backend:4}: "
              f"median {_fmt(record['median_us'])} µs, "
              f"{record['received']}/{record['sent']} received"
              + (f", {record['resent']} resent" if record.get("resent") else "")
              + (" STALLED (a side reported nothing)" if record.get("stalled") else ""),
              flush=True)
        return record

    if args.smoke:  # side by side: the startup of six process pairs is what takes time
        with concurrent.futures.ThreadPoolExecutor(len(plan)) as pool:
            records = list(pool.map(lambda step: measure(*step), plan))
    else:
        records = [measure(*step) for step in plan]
    print(f"\nmedian of {repeat} run(s), load average {load:.1f} -> {os.getloadavg()[0]:.1f}, "
          f"{time.monotonic() - started:.0f} s")
    print(f"{'size':>5} {'mode':4} {'backend':7} {'median µs':>9} {'p99 µs':>8} {'msg/s':>7} "
          f"{'MB/s':>7} {'CPU pub µs':>10} {'CPU sub µs':>10}")
    summary: dict[tuple[str, str, str], dict[str, float | None]] = {}
    for label, size in sizes.items():
        for mode in MODES:
            for backend in BACKENDS:
                group = [r for r in records
                         if (r["label"], r["mode"], r["backend"]) == (label, mode, backend)]
                s = {k: _median(group, k) for k in ("median_us", "p99_us", "msgs_per_s",
                                                    "pub_cpu_us", "sub_cpu_us")}
                summary[(label, mode, backend)] = s
                rate = s["msgs_per_s"]
                print(f"{label:>5} {mode:4} {backend:7} {_fmt(s['median_us']):>9} "
                      f"{_fmt(s['p99_us']):>8} {_fmt(rate):>7} "
                      f"{_fmt(rate * size / 1e6 if rate else None, '.1f'):>7} "
                      f"{_fmt(s['pub_cpu_us']):>10} {_fmt(s['sub_cpu_us']):>10}")
    print("\nratios (ping medians; CPU = publisher + subscriber per message):")
    for label in sizes:
        shm, dds, bare = (summary[(label, "ping", b)] for b in ("shm", "dds", "bare"))

        def ratio(a: float | None, b: float | None) -> str:
            return f"{a / b:.2f}x" if a and b else "-"

        cpu = {name: (v["pub_cpu_us"] or 0) + (v["sub_cpu_us"] or 0)
               for name, v in (("shm", shm), ("dds", dds))}
        print(f"  {label:>5}: shm / bare latency {ratio(shm['median_us'], bare['median_us'])}, "
              f"shm / dds latency {ratio(shm['median_us'], dds['median_us'])}, "
              f"shm / dds CPU {ratio(cpu['shm'], cpu['dds'])}")
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(json.dumps({"records": records, "load": load}, indent=1))
    stalled = [r for r in records if r.get("stalled")]
    if stalled:
        print(f"\n{len(stalled)} pair(s) stalled: " + ", ".join(
            f"run {r['run']} {r['label']} {r['mode']} {r['backend']} "
            f"({r['received']} received)" for r in stalled))
        sys.exit(1)


if __name__ == "__main__":
    main()
