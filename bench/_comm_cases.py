"""The measurements of bench/comm_bench.py; each call runs in a process of its own.

Every function here is one scenario for one backend and returns a list of flat records
(``dict``s of strings and numbers). comm_bench.py starts a fresh Python process per call
(``comm_bench.py --scenario X --backend Y --json``), so that:

* plain rclpy baselines never share a process with efficient_comm's DDS preparation
  (``efficient_comm.dds.prepare_process`` makes a participant ignore its own endpoints, which
  would stop two plain nodes of one context from hearing each other);
* every backend starts from the same heap (allocator state matters for large messages).

Backends:

``single`` / ``multi`` / ``events``
    plain rclpy nodes (default options) in one context, spun by SingleThreadedExecutor,
    MultiThreadedExecutor or rclpy.experimental.EventsExecutor. Publishing always happens in
    a callback on the executor (ping-pong), since EventsExecutor hangs when another thread
    publishes while it spins.
``composed`` / ``composed_bf`` / ``composed_dds``
    components in an efficient_comm Container: dds=False depth_first, dds=False
    breadth_first, dds=True depth_first (its DDS writers see no reader, so nothing is sent).
    The driving publisher is a component timer (period 1 ns, always due) on the consecutive
    executor; the container runs ``spin()`` until a callback calls ``shutdown()``.

Only timestamps taken with ``time.perf_counter_ns`` (``time.monotonic_ns`` across
processes; both CLOCK_MONOTONIC on Linux) are compared.
"""

from __future__ import annotations

import array
import os
import select
import subprocess
import sys
import threading
import time
import uuid
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any, Literal

Record = dict[str, str | int | float]

RCLPY_BACKENDS = ("single", "multi", "events")
COMPOSED_BACKENDS = ("composed", "composed_bf", "composed_dds")
BACKENDS = RCLPY_BACKENDS + COMPOSED_BACKENDS

#: payload name -> bytes of Image.data (None: std_msgs/String "hello world", or Empty).
PAYLOADS: dict[str, int | None] = {
    "string": None,
    "image_64B": 64,
    "image_64KiB": 64 * 1024,
    "image_1MiB": 1024 * 1024,
    "image_8MiB": 8 * 1024 * 1024,
    "empty": None,
}
STRING_DATA = "hello world"

#: A period that is always over: the timer is due whenever the executor looks. (With
#: 1 µs, EventsExecutor really sleeps until the deadline: about 20 µs per callback here.)
TINY_PERIOD_S = 1e-9


# -- messages ------------------------------------------------------------------------------


def msg_type(payload: str) -> type:
    if payload == "string":
        from std_msgs.msg import String

        return String  # type: ignore[no-any-return]
    if payload == "empty":
        from std_msgs.msg import Empty

        return Empty  # type: ignore[no-any-return]
    from sensor_msgs.msg import Image

    return Image  # type: ignore[no-any-return]


def make_msg(payload: str) -> Any:
    cls = msg_type(payload)
    if payload == "string":
        return cls(data=STRING_DATA)
    if payload == "empty":
        return cls()
    size = PAYLOADS[payload]
    assert size is not None
    msg = cls()
    msg.height = 1
    msg.width = size
    msg.encoding = "mono8"
    msg.step = size
    # array.array('B') is what rosidl stores; a bytes value would be checked byte by byte.
    msg.data = array.array("B", bytes(size))
    return msg


def payload_bytes(payload: str) -> int:
    size = PAYLOADS[payload]
    if size is None:
        return len(STRING_DATA) if payload == "string" else 0
    return size


# -- statistics ----------------------------------------------------------------------------


def percentile(sorted_values: Sequence[float], q: float) -> float:
    """Linear-interpolated percentile (q in 0..100) of already sorted values."""
    if not sorted_values:
        raise ValueError("no samples")
    pos = (len(sorted_values) - 1) * q / 100.0
    lo = int(pos)
    hi = min(lo + 1, len(sorted_values) - 1)
    return sorted_values[lo] + (sorted_values[hi] - sorted_values[lo]) * (pos - lo)


def latency_record(samples_ns: Sequence[int], warmup: int, **keys: str | int | float) -> Record:
    # A run cut short by its time budget keeps at least half of its samples.
    kept = sorted(samples_ns[min(warmup, len(samples_ns) // 2) :])
    if not kept:
        raise RuntimeError(f"no samples left after {warmup} warm-up ones ({keys})")
    rec: Record = dict(keys)
    rec.update(
        median_us=percentile(kept, 50) / 1e3,
        p99_us=percentile(kept, 99) / 1e3,
        min_us=kept[0] / 1e3,
        n=len(kept),
    )
    return rec


def warmup_of(n: int) -> int:
    return max(3, n // 10)


# -- plain rclpy rigs ----------------------------------------------------------------------


def set_domain() -> int:
    """A ROS domain id reserved for this process (efficient_comm.testing.isolated_domain_id:
    no concurrent bench or test process gets it) unless the environment chose one."""
    if "ROS_DOMAIN_ID" not in os.environ:
        from efficient_comm.testing import isolated_domain_id

        os.environ["ROS_DOMAIN_ID"] = str(isolated_domain_id())
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    return int(os.environ["ROS_DOMAIN_ID"])


def unique_topic(stem: str) -> str:
    return f"/bench_{stem}_{uuid.uuid4().hex[:10]}"


class RclpyRig:
    """One rclpy context with nodes, spun by the chosen executor."""

    def __init__(self, backend: str) -> None:
        import rclpy
        from rclpy.context import Context

        if backend not in RCLPY_BACKENDS:
            raise ValueError(f"not an rclpy backend: {backend}")
        set_domain()
        self.context = Context()
        rclpy.init(context=self.context)
        self.backend = backend
        self.nodes: list[Any] = []
        self.executor: Any = None

    def node(self, name: str) -> Any:
        from rclpy.node import Node

        node = Node(f"{name}_{uuid.uuid4().hex[:6]}", context=self.context)
        self.nodes.append(node)
        return node

    def _make_executor(self) -> Any:
        from rclpy.executors import MultiThreadedExecutor, SingleThreadedExecutor

        if self.backend == "single":
            return SingleThreadedExecutor(context=self.context)
        if self.backend == "multi":
            return MultiThreadedExecutor(context=self.context)
        from rclpy.experimental.events_executor import EventsExecutor

        return EventsExecutor(context=self.context)

    def kick(self, node: Any, fn: Callable[[], None]) -> None:
        """Call ``fn`` once from the executor (a one-shot timer)."""
        holder: list[Any] = []

        def once() -> None:
            holder[0].cancel()
            fn()

        holder.append(node.create_timer(0.001, once))

    def run(self, done: Any, timeout_s: float) -> None:
        """Spin until the future ``done`` completes; raises on timeout."""
        self.executor = self._make_executor()
        for node in self.nodes:
            self.executor.add_node(node)
        self.executor.spin_until_future_complete(done, timeout_sec=timeout_s)
        if not done.done():
            raise TimeoutError(f"{self.backend}: not done after {timeout_s} s")

    def close(self) -> None:
        if self.executor is not None:
            self.executor.shutdown()
        for node in self.nodes:
            node.destroy_node()
        self.context.try_shutdown()


def future() -> Any:
    from rclpy.task import Future

    return Future()


def reliable(depth: int) -> Any:
    from rclpy.qos import QoSProfile

    return QoSProfile(depth=depth)


# -- composed rigs -------------------------------------------------------------------------


class ComposedRig:
    """An efficient_comm Container; components are added with :meth:`add`."""

    def __init__(self, backend: str) -> None:
        from efficient_comm import Container

        if backend not in COMPOSED_BACKENDS:
            raise ValueError(f"not a composed backend: {backend}")
        dds = backend == "composed_dds"
        domain = set_domain() if dds else None
        strategy: Literal["depth_first", "breadth_first"] = (
            "breadth_first" if backend == "composed_bf" else "depth_first"
        )
        self.container = Container(
            f"bench_{uuid.uuid4().hex[:6]}",
            dds=dds,
            strategy=strategy,
            domain_id=domain,
            serve=False,
        )

    def add(self, factory: Callable[[Any], Any], name: str) -> Any:
        return self.container.add(factory, name=name)

    def run(self, done: Callable[[], bool], timeout_s: float) -> None:
        """``spin()`` until a callback calls :meth:`stop`; a watchdog ends it on timeout."""
        watchdog = threading.Timer(timeout_s, self.container.shutdown)
        watchdog.daemon = True
        watchdog.start()
        try:
            self.container.spin()
        finally:
            watchdog.cancel()
        if not done():
            raise TimeoutError(f"composed: not done after {timeout_s} s")

    def stop(self) -> None:
        self.container.shutdown()

    def close(self) -> None:
        self.container.close()


# -- 1. publish -> callback latency, one message in flight ---------------------------------


@dataclass
class _Lat:
    total: int
    #: perf_counter_ns after which no new message is sent (MultiThreadedExecutor can stall
    #: for tens of milliseconds per message here; this bounds its run time).
    deadline_ns: int = 0
    samples: list[int] = field(default_factory=list)
    t0: int = 0

    def more(self, now_ns: int) -> bool:
        over = self.deadline_ns and now_ns > self.deadline_ns
        return len(self.samples) < self.total and not over


def _per_payload(
    scenario: str,
    backend: str,
    payloads: Sequence[str],
    iterations: dict[str, int],
    budget_s: float,
    rclpy_samples: Callable[[str, str, int, float], list[int]],
    composed_samples: Callable[[str, str, int], list[int]],
) -> list[Record]:
    """One latency record per payload, from the rclpy or the composed sampler."""
    out = []
    for payload in payloads:
        n = iterations[payload]
        warm = warmup_of(n)
        if backend in RCLPY_BACKENDS:
            samples = rclpy_samples(backend, payload, n + warm, budget_s)
        else:
            samples = composed_samples(backend, payload, n + warm)
        out.append(
            latency_record(
                samples,
                warm,
                scenario=scenario,
                backend=backend,
                payload=payload,
                payload_bytes=payload_bytes(payload),
            )
        )
    return out


def latency(
    backend: str, payloads: Sequence[str], iterations: dict[str, int], budget_s: float
) -> list[Record]:
    return _per_payload(
        "latency", backend, payloads, iterations, budget_s, _latency_rclpy, _latency_composed
    )


def _latency_rclpy(backend: str, payload: str, total: int, budget_s: float) -> list[int]:
    """Ping-pong: ping's publish -> pong's callback is timed; pong acks, ack sends the next."""
    from std_msgs.msg import Empty

    rig = RclpyRig(backend)
    try:
        ping, pong = rig.node("ping"), rig.node("pong")
        topic = unique_topic("lat")
        msg, ack = make_msg(payload), Empty()
        pub = ping.create_publisher(type(msg), topic, 10)
        ack_pub = pong.create_publisher(Empty, topic + "_ack", 10)
        st = _Lat(total)
        done = future()
        clock = time.perf_counter_ns

        def send() -> None:
            if not st.deadline_ns:
                st.deadline_ns = clock() + round(budget_s * 1e9)
            st.t0 = clock()
            pub.publish(msg)

        def on_msg(_msg: Any) -> None:
            t1 = clock()
            st.samples.append(t1 - st.t0)
            ack_pub.publish(ack)

        def on_ack(_msg: Any) -> None:
            if st.more(clock()):
                send()
            else:
                done.set_result(True)

        pong.create_subscription(type(msg), topic, on_msg, 10)
        ping.create_subscription(Empty, topic + "_ack", on_ack, 10)
        rig.kick(ping, send)
        rig.run(done, timeout_s=60 + budget_s)
        return st.samples
    finally:
        rig.close()


def _latency_composed(backend: str, payload: str, total: int) -> list[int]:
    """A component timer publishes; the subscriber component's callback is timed."""
    rig = ComposedRig(backend)
    try:
        topic = unique_topic("lat")
        msg = make_msg(payload)
        st = _Lat(total)
        clock = time.perf_counter_ns

        class Sink:
            def __init__(self, node: Any) -> None:
                node.create_subscription(type(msg), topic, self.on_msg, qos=10)

            def on_msg(self, _msg: Any) -> None:
                t1 = clock()
                st.samples.append(t1 - st.t0)

        class Source:
            def __init__(self, node: Any) -> None:
                self.pub = node.create_publisher(type(msg), topic, qos=10)
                node.create_timer(TINY_PERIOD_S, self.tick)

            def tick(self) -> None:
                if len(st.samples) >= st.total:
                    rig.stop()
                    return
                st.t0 = clock()
                self.pub.publish(msg)

        rig.add(Sink, "sink")
        rig.add(Source, "source")
        rig.run(lambda: len(st.samples) >= st.total, timeout_s=60)
        return st.samples
    finally:
        rig.close()


# -- 2./3. throughput (bursts) and per-callback dispatch -----------------------------------

BURST = 100
BURST_QOS_DEPTH = 1000


@dataclass
class _Count:
    total: int
    received: int = 0
    first_ns: int = 0
    last_ns: int = 0


def throughput(
    backend: str, payloads: Sequence[str], messages: int, budget_s: float
) -> list[Record]:
    """Bursts of BURST messages from a callback; the receiver acks each complete burst."""
    out: list[Record] = []
    total = max(BURST, messages // BURST * BURST)
    for payload in payloads:
        # A short warm-up run, then the measured one (same process, fresh endpoints).
        if backend in RCLPY_BACKENDS:
            _throughput_rclpy(backend, payload, 2 * BURST, budget_s)
            c = _throughput_rclpy(backend, payload, total, budget_s)
        else:
            _throughput_composed(backend, payload, 2 * BURST)
            c = _throughput_composed(backend, payload, total)
        elapsed_s = (c.last_ns - c.first_ns) / 1e9
        out.append(
            {
                "scenario": "throughput",
                "backend": backend,
                "payload": payload,
                "msgs_per_s": c.received / elapsed_s,
                "us_per_msg": elapsed_s * 1e6 / c.received,
                "n": c.received,
            }
        )
    return out


def _throughput_rclpy(backend: str, payload: str, total: int, budget_s: float) -> _Count:
    from std_msgs.msg import Empty

    rig = RclpyRig(backend)
    try:
        src, dst = rig.node("src"), rig.node("dst")
        topic = unique_topic("thr")
        msg, ack = make_msg(payload), Empty()
        pub = src.create_publisher(type(msg), topic, reliable(BURST_QOS_DEPTH))
        ack_pub = dst.create_publisher(Empty, topic + "_ack", 10)
        c = _Count(total)
        done = future()
        clock = time.perf_counter_ns

        def burst() -> None:
            if not c.first_ns:
                c.first_ns = clock()
            for _ in range(BURST):
                pub.publish(msg)

        def on_msg(_msg: Any) -> None:
            c.received += 1
            if c.received % BURST == 0:
                c.last_ns = clock()
                ack_pub.publish(ack)

        def on_ack(_msg: Any) -> None:
            if c.received < c.total and clock() - c.first_ns < budget_s * 1e9:
                burst()
            else:
                done.set_result(True)

        dst.create_subscription(type(msg), topic, on_msg, reliable(BURST_QOS_DEPTH))
        src.create_subscription(Empty, topic + "_ack", on_ack, 10)
        rig.kick(src, burst)
        rig.run(done, timeout_s=60 + budget_s)
        return c
    finally:
        rig.close()


def _throughput_composed(backend: str, payload: str, total: int) -> _Count:
    rig = ComposedRig(backend)
    try:
        topic = unique_topic("thr")
        msg = make_msg(payload)
        c = _Count(total)
        clock = time.perf_counter_ns

        class Sink:
            def __init__(self, node: Any) -> None:
                node.create_subscription(type(msg), topic, self.on_msg, qos=BURST_QOS_DEPTH)

            def on_msg(self, _msg: Any) -> None:
                c.received += 1
                if c.received % BURST == 0:
                    c.last_ns = clock()

        class Source:
            def __init__(self, node: Any) -> None:
                self.pub = node.create_publisher(type(msg), topic, qos=BURST_QOS_DEPTH)
                node.create_timer(TINY_PERIOD_S, self.tick)

            def tick(self) -> None:
                if c.received >= c.total:
                    rig.stop()
                    return
                if not c.first_ns:
                    c.first_ns = clock()
                publish = self.pub.publish
                for _ in range(BURST):
                    publish(msg)

        rig.add(Sink, "sink")
        rig.add(Source, "source")
        rig.run(lambda: c.received >= c.total, timeout_s=120)
        return c
    finally:
        rig.close()


def dispatch(backend: str, duration_s: float) -> list[Record]:
    """One timer with a 1 ns period (always due) and a callback that only counts."""
    c = _Count(0)
    clock = time.perf_counter_ns
    stamped = 0
    end_ns = 0
    stop: list[Callable[[], None]] = []

    def tick() -> None:
        nonlocal end_ns, stamped
        c.received += 1
        if c.received == 1:
            c.first_ns = clock()
            end_ns = c.first_ns + round(duration_s * 1e9)
        elif c.received & 63 == 0 and not stamped:
            now = clock()
            if now >= end_ns:
                c.last_ns, stamped = now, c.received
                stop[0]()

    if backend in RCLPY_BACKENDS:
        rig = RclpyRig(backend)
        try:
            done = future()
            timer = rig.node("timer").create_timer(TINY_PERIOD_S, tick)

            def finish() -> None:
                timer.cancel()
                done.set_result(True)

            stop.append(finish)
            rig.run(done, timeout_s=duration_s + 60)
        finally:
            rig.close()
    else:
        crig = ComposedRig(backend)
        try:

            class Ticker:
                def __init__(self, node: Any) -> None:
                    self.timer = node.create_timer(TINY_PERIOD_S, tick)

                def finish(self) -> None:
                    self.timer.cancel()
                    crig.stop()

            stop.append(crig.add(Ticker, "ticker").finish)
            crig.run(lambda: stamped > 0, timeout_s=duration_s + 60)
        finally:
            crig.close()
    intervals = stamped - 1  # callbacks after the first one, up to the last time stamp
    return [
        {
            "scenario": "dispatch",
            "backend": backend,
            "payload": "timer",
            "us_per_callback": (c.last_ns - c.first_ns) / 1e3 / intervals,
            "n": intervals,
        }
    ]


# -- 4. five-component chain ---------------------------------------------------------------

CHAIN = ("a", "b", "c", "d", "e")


def chain(
    backend: str, payloads: Sequence[str], iterations: dict[str, int], budget_s: float
) -> list[Record]:
    return _per_payload(
        "chain", backend, payloads, iterations, budget_s, _chain_rclpy, _chain_composed
    )


def _chain_rclpy(backend: str, payload: str, total: int, budget_s: float) -> list[int]:
    from std_msgs.msg import Empty

    rig = RclpyRig(backend)
    try:
        nodes = [rig.node(f"chain_{x}") for x in CHAIN]
        base = unique_topic("chain")
        topics = [f"{base}_{i}" for i in range(len(CHAIN) - 1)]
        msg, ack = make_msg(payload), Empty()
        cls = type(msg)
        st = _Lat(total)
        done = future()
        clock = time.perf_counter_ns
        pub_a = nodes[0].create_publisher(cls, topics[0], 10)

        def send() -> None:
            if not st.deadline_ns:
                st.deadline_ns = clock() + round(budget_s * 1e9)
            st.t0 = clock()
            pub_a.publish(msg)

        for i in range(1, len(CHAIN) - 1):  # B, C, D relay what they receive
            relay_pub = nodes[i].create_publisher(cls, topics[i], 10)
            nodes[i].create_subscription(cls, topics[i - 1], relay_pub.publish, 10)
        ack_pub = nodes[-1].create_publisher(Empty, base + "_ack", 10)

        def on_last(_msg: Any) -> None:
            t1 = clock()
            st.samples.append(t1 - st.t0)
            ack_pub.publish(ack)

        def on_ack(_msg: Any) -> None:
            if st.more(clock()):
                send()
            else:
                done.set_result(True)

        nodes[-1].create_subscription(cls, topics[-1], on_last, 10)
        nodes[0].create_subscription(Empty, base + "_ack", on_ack, 10)
        rig.kick(nodes[0], send)
        rig.run(done, timeout_s=60 + budget_s)
        return st.samples
    finally:
        rig.close()


def _chain_composed(backend: str, payload: str, total: int) -> list[int]:
    rig = ComposedRig(backend)
    try:
        base = unique_topic("chain")
        topics = [f"{base}_{i}" for i in range(len(CHAIN) - 1)]
        msg = make_msg(payload)
        cls = type(msg)
        st = _Lat(total)
        clock = time.perf_counter_ns

        class Source:
            def __init__(self, node: Any) -> None:
                self.pub = node.create_publisher(cls, topics[0], qos=10)
                node.create_timer(TINY_PERIOD_S, self.tick)

            def tick(self) -> None:
                if len(st.samples) >= st.total:
                    rig.stop()
                    return
                st.t0 = clock()
                self.pub.publish(msg)

        class Relay:
            def __init__(self, node: Any, index: int) -> None:
                pub = node.create_publisher(cls, topics[index], qos=10)
                node.create_subscription(cls, topics[index - 1], pub.publish, qos=10)

        class Sink:
            def __init__(self, node: Any) -> None:
                node.create_subscription(cls, topics[-1], self.on_msg, qos=10)

            def on_msg(self, _msg: Any) -> None:
                t1 = clock()
                st.samples.append(t1 - st.t0)

        def relay(index: int) -> Callable[[Any], Relay]:
            return lambda node: Relay(node, index)

        rig.add(Sink, "chain_e")
        for i in range(len(CHAIN) - 2, 0, -1):
            rig.add(relay(i), f"chain_{CHAIN[i]}")
        rig.add(Source, "chain_a")
        rig.run(lambda: len(st.samples) >= st.total, timeout_s=60)
        return st.samples
    finally:
        rig.close()


# -- 5. external subscriber in another process ---------------------------------------------


class LineReader:
    """Lines from a pipe with a timeout (select on the raw descriptor, own buffering)."""

    def __init__(self, fd: int) -> None:
        self.fd = fd
        self.buf = b""

    def readline(self, timeout_s: float) -> str:
        deadline = time.monotonic() + timeout_s
        while b"\n" not in self.buf:
            left = deadline - time.monotonic()
            if left <= 0:
                raise TimeoutError(f"no line from the external subscriber in {timeout_s} s")
            ready, _, _ = select.select([self.fd], [], [], left)
            if ready:
                chunk = os.read(self.fd, 65536)
                if not chunk:
                    raise EOFError("the external subscriber closed its output")
                self.buf += chunk
        line, self.buf = self.buf.split(b"\n", 1)
        return line.decode()


def external(
    publisher: str, payloads: Sequence[str], iterations: dict[str, int], script: str
) -> list[Record]:
    """Publisher here (plain rclpy or a Container(dds=True) component), subscriber in a child.

    The child (plain rclpy, EventsExecutor) prints ``READY`` once it sees the publisher, then
    one line per message with ``time.monotonic_ns()`` taken at the start of its callback.
    The next message is published only after that line arrived (one message in flight).
    """
    from efficient_comm.testing import ros_env

    domain = set_domain()
    out = []
    for payload in payloads:
        n = iterations[payload]
        warm = warmup_of(n)
        topic = unique_topic("ext")
        proc = subprocess.Popen(
            [
                sys.executable,
                script,
                "--role",
                "ext-sub",
                "--payload",
                payload,
                "--topic",
                topic,
                "--count",
                str(n + warm),
            ],
            stdout=subprocess.PIPE,
            stdin=subprocess.DEVNULL,
            # A plain ROS 2 subscriber, as `ros2 topic echo` would be: without the DDS profile
            # a composing process sets for itself (ros_env strips it).
            env=ros_env(domain),
        )
        assert proc.stdout is not None
        try:
            reader = LineReader(proc.stdout.fileno())
            if publisher == "plain":
                samples = _external_plain(payload, topic, n + warm, reader)
            else:
                samples = _external_composed(payload, topic, n + warm, reader, domain)
        finally:
            try:
                proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
        out.append(
            latency_record(
                samples,
                warm,
                scenario="external",
                backend=publisher,
                payload=payload,
                payload_bytes=payload_bytes(payload),
            )
        )
    return out


def _wait_ready(reader: LineReader, matched: Callable[[], bool], poll: Callable[[], None]) -> None:
    line = reader.readline(30.0)
    if line != "READY":
        raise RuntimeError(f"external subscriber said {line!r}, not READY")
    deadline = time.monotonic() + 30.0
    while not matched():
        if time.monotonic() > deadline:
            raise TimeoutError("the publisher never matched the external subscriber")
        poll()


def _ping_external(
    publish: Callable[[], None], reader: LineReader, total: int, between: Callable[[], None]
) -> list[int]:
    clock = time.monotonic_ns
    samples = []
    for i in range(total):
        t0 = clock()
        publish()
        t1 = int(reader.readline(10.0))
        samples.append(t1 - t0)
        if i % 16 == 15:
            between()
    return samples


def _external_plain(payload: str, topic: str, total: int, reader: LineReader) -> list[int]:
    import rclpy
    from rclpy.context import Context
    from rclpy.node import Node

    context = Context()
    rclpy.init(context=context)
    try:
        node = Node(f"ext_pub_{uuid.uuid4().hex[:6]}", context=context)
        msg = make_msg(payload)
        pub = node.create_publisher(type(msg), topic, 10)
        _wait_ready(reader, lambda: pub.get_subscription_count() > 0, lambda: time.sleep(0.005))
        samples = _ping_external(lambda: pub.publish(msg), reader, total, lambda: None)
        node.destroy_node()
        return samples
    finally:
        context.try_shutdown()


def _external_composed(
    payload: str, topic: str, total: int, reader: LineReader, domain: int
) -> list[int]:
    from efficient_comm import Container

    msg = make_msg(payload)

    class Source:
        def __init__(self, node: Any) -> None:
            self.pub = node.create_publisher(type(msg), topic, qos=10)

    with Container(
        f"ext_pub_{uuid.uuid4().hex[:6]}", dds=True, domain_id=domain, serve=False
    ) as container:
        src = container.add(Source, name="source")
        # The container learns of the match from a DDS event: spin until it has.
        _wait_ready(reader, lambda: src.pub.dds_matched > 0, lambda: container.spin_once(0.005))
        return _ping_external(
            lambda: src.pub.publish(msg), reader, total, lambda: container.spin_once(0.0)
        )


def external_subscriber(payload: str, topic: str, count: int) -> None:
    """The child of :func:`external`: plain rclpy, EventsExecutor, stamps on stdout."""
    import rclpy
    from rclpy.context import Context
    from rclpy.experimental.events_executor import EventsExecutor
    from rclpy.node import Node

    out = sys.stdout
    context = Context()
    rclpy.init(context=context)
    node = Node(f"ext_sub_{uuid.uuid4().hex[:6]}", context=context)
    received = 0
    done = future()
    clock = time.monotonic_ns

    def on_msg(_msg: Any) -> None:
        nonlocal received
        t1 = clock()
        out.write(f"{t1}\n")
        out.flush()
        received += 1
        if received >= count:
            done.set_result(True)

    sub = node.create_subscription(msg_type(payload), topic, on_msg, 10)
    deadline = time.monotonic() + 30.0
    while sub.get_publisher_count() == 0 and time.monotonic() < deadline:
        time.sleep(0.005)
    out.write("READY\n")
    out.flush()
    executor = EventsExecutor(context=context)
    executor.add_node(node)
    executor.spin_until_future_complete(done, timeout_sec=120.0)
    executor.shutdown()
    node.destroy_node()
    context.try_shutdown()


# -- 6. publish from another thread (a driver's read loop, a socket thread) ------------------

#: Backends of the foreign-thread scenario: rclpy's SingleThreadedExecutor (its wait set
#: wakes on the DDS sample) is the baseline; composed ones wake through the executor.
FOREIGN_BACKENDS = ("single", "composed", "composed_dds")
#: The rate scenario: a thread publishes this many messages at 1 kHz, subscriber depth 10.
FOREIGN_RATE_HZ = 1000
FOREIGN_DEPTH = 10


def foreign(backend: str, total: int, burst: int) -> list[Record]:
    """Latency from another thread's publish to the callback (one message in flight, no
    timers anywhere), and how many of ``burst`` messages published at 1 kHz are lost."""
    if backend not in FOREIGN_BACKENDS:
        raise ValueError(f"not a foreign-thread backend: {backend}")
    latency_topic, rate_topic = unique_topic("foreign"), unique_topic("foreign_rate")
    arrived = threading.Event()
    st = _Lat(total)
    received = [0]
    clock = time.perf_counter_ns

    def on_latency(_msg: Any) -> None:
        st.samples.append(clock() - st.t0)
        arrived.set()

    def on_rate(_msg: Any) -> None:
        received[0] += 1

    def drive(publish_latency: Callable[[Any], None], publish_rate: Callable[[Any], None],
              finished: threading.Event) -> None:
        from std_msgs.msg import String

        msg = String(data=STRING_DATA)
        try:
            for _ in range(total):
                arrived.clear()
                st.t0 = clock()
                publish_latency(msg)
                if not arrived.wait(5.0):
                    break
            due = time.monotonic()
            for _ in range(burst):
                # Never a catch-up burst after a hold-up: it would hold the GIL and overflow
                # the queue whatever the executor does.
                due = max(due + 1 / FOREIGN_RATE_HZ, time.monotonic())
                time.sleep(max(0.0, due - time.monotonic()))
                publish_rate(msg)
        finally:
            finished.set()

    finished = threading.Event()
    if backend == "single":
        _foreign_rclpy(on_latency, on_rate, drive, finished, latency_topic, rate_topic)
    else:
        _foreign_composed(backend, on_latency, on_rate, drive, finished, latency_topic,
                          rate_topic, lambda: received[0] >= burst)
    rec = latency_record(st.samples, warmup_of(total), scenario="foreign", backend=backend,
                         payload="string", payload_bytes=payload_bytes("string"))
    rec["lost"] = burst - received[0]
    rec["burst"] = burst
    return [rec]


_Drive = Callable[[Callable[[Any], None], Callable[[Any], None], threading.Event], None]


def _foreign_rclpy(on_latency: Callable[[Any], None], on_rate: Callable[[Any], None],
                   drive: _Drive, finished: threading.Event, latency_topic: str,
                   rate_topic: str) -> None:
    from std_msgs.msg import String

    rig = RclpyRig("single")
    try:
        node = rig.node("foreign")
        pub = node.create_publisher(String, latency_topic, reliable(10))
        rate_pub = node.create_publisher(String, rate_topic, reliable(FOREIGN_DEPTH))
        node.create_subscription(String, latency_topic, on_latency, reliable(10))
        node.create_subscription(String, rate_topic, on_rate, reliable(FOREIGN_DEPTH))
        rig.executor = rig._make_executor()
        rig.executor.add_node(node)
        thread = threading.Thread(target=drive, args=(pub.publish, rate_pub.publish, finished))
        thread.start()
        end = None
        while end is None or time.monotonic() < end:
            rig.executor.spin_once(timeout_sec=0.01)
            if end is None and finished.is_set():
                end = time.monotonic() + 0.5  # what is still in flight
        thread.join()
    finally:
        rig.close()


def _foreign_composed(backend: str, on_latency: Callable[[Any], None],
                      on_rate: Callable[[Any], None], drive: _Drive, finished: threading.Event,
                      latency_topic: str, rate_topic: str, all_in: Callable[[], bool]) -> None:
    from std_msgs.msg import String

    class Sink:
        def __init__(self, node: Any) -> None:
            node.create_subscription(String, latency_topic, on_latency, qos=10)
            node.create_subscription(String, rate_topic, on_rate, qos=FOREIGN_DEPTH)

    class Source:
        def __init__(self, node: Any) -> None:
            self.pub = node.create_publisher(String, latency_topic, qos=10)
            self.rate_pub = node.create_publisher(String, rate_topic, qos=FOREIGN_DEPTH)

    rig = ComposedRig(backend)
    try:
        rig.add(Sink, "sink")
        src = rig.add(Source, "source")
        thread = threading.Thread(target=drive, args=(src.pub.publish, src.rate_pub.publish,
                                                      finished))
        thread.start()
        rig.container.spin_until(finished.is_set, timeout_s=120)
        rig.container.spin_until(all_in, timeout_s=0.5)
        thread.join()
    finally:
        rig.close()
