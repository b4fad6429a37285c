"""Peers for the shared-memory transport's tests (tests/test_shm_transport.py).

``python tests/_shm_peer.py pub TOPIC --count N --sizes B[,B...] --readers K [--period S]``:
a container with the transport publishing sensor_msgs/Image number ``i`` (``frame_id`` ``i``,
``data`` filled with ``i % 251``, the sizes taken in turn) once ``K`` DDS readers matched;
prints ``ready``, then ``published N dds D`` (D: how many it also wrote to DDS, ``?``
without the transport), and stays until stdin closes.

``python tests/_shm_peer.py sub TOPIC [--slow S] [--no-shm]``: a container subscribing;
per message a line
``msg <frame_id> <shm|dds> <ro|rw> <ok|bad> <dropped> <kept|overwritten> <eq|neq>``
(``shm`` when the data is an array over shared memory, ``ok`` when every byte is the
expected value, ``dropped`` the subscription's loss count so far, then ``kept`` while the
first message from shared memory, which it keeps, still holds its bytes, ``eq`` when the
message (and its data) equals, both ways, the Image the publisher built and differs from one
with a byte changed; ``neq`` if not or if comparing raised). ``--slow``
spends S seconds of CPU in the callback (a slow reader).

``python tests/_shm_peer.py plain TOPIC``: a plain rclpy node (no efficient_comm), printing
``msg <frame_id> dds``.
"""

from __future__ import annotations

import argparse
import contextlib
import sys
import threading
import time
from typing import Any

import numpy as np
from rclpy.qos import QoSProfile
from sensor_msgs.msg import Image

from efficient_comm import Container, NodeHandle


def _until_stdin_closes(stop: Any) -> None:
    threading.Thread(target=lambda: (sys.stdin.read(), stop()), daemon=True).start()


class _Publisher:
    def __init__(self, node: NodeHandle, args: argparse.Namespace) -> None:
        self._pub = node.create_publisher(Image, args.topic, qos=QoSProfile(depth=10))
        self._args = args
        self._sizes = [int(s) for s in args.sizes.split(",")]
        self._sent = 0
        self._ready = False
        self._timer = node.create_timer(args.period, self._tick)

    def _tick(self) -> None:
        if not self._ready:
            if self._pub.get_subscription_count() < self._args.readers:
                return
            self._ready = True
            print("ready", flush=True)
        if self._sent >= self._args.count:
            return
        i = self._sent
        size = self._sizes[i % len(self._sizes)]
        msg = Image(height=1, width=size, encoding="mono8", step=size)
        msg.header.frame_id = str(i)
        msg.data = np.full(size, i % 251, dtype=np.uint8).tobytes()
        self._pub.publish(msg)
        self._sent += 1
        if self._sent == self._args.count:
            shm = getattr(self._pub, "shm", None)
            dds = "?" if shm is None else shm.dds_writes
            print(f"published {self._sent} dds {dds}", flush=True)


class _Subscriber:
    def __init__(self, node: NodeHandle, args: argparse.Namespace) -> None:
        self._dropped = 0
        self._slow = args.slow
        self._kept: tuple[int, Image] | None = None
        node.create_subscription(Image, args.topic, self._on_image, qos=QoSProfile(depth=10),
                                 on_lost=self._on_lost)

    def _on_lost(self, count: int) -> None:
        self._dropped += count

    def _on_image(self, msg: Image) -> None:
        data = msg.data
        via = "shm" if isinstance(data, np.ndarray) else "dds"
        ro = "ro" if via == "shm" and not data.flags.writeable else "rw"
        i = int(msg.header.frame_id)
        ok = "ok" if len(data) == msg.width and bool(np.all(np.asarray(data) == i % 251)) \
            else "bad"
        if self._slow:
            end = time.perf_counter() + self._slow
            while time.perf_counter() < end:
                pass
        if self._kept is None and via == "shm":
            self._kept = (i, msg)  # held while later chunks come and go
        kept = self._kept is None or bool(np.all(np.asarray(self._kept[1].data)
                                                 == self._kept[0] % 251))
        print(f"msg {i} {via} {ro} {ok} {self._dropped} {'kept' if kept else 'overwritten'} "
              f"{_equality(msg, i)}", flush=True)


def _equality(msg: Image, i: int) -> str:
    """``eq`` when ``msg`` compares as the publisher's message ``i`` (built here as the
    publisher builds it, so its data is the ``array.array`` a DDS message has)."""
    size = len(msg.data)
    same = Image(height=1, width=size, encoding="mono8", step=size)
    same.header.frame_id = str(i)
    same.data = np.full(size, i % 251, dtype=np.uint8).tobytes()
    other = Image(height=1, width=size, encoding="mono8", step=size)
    other.header.frame_id = str(i)
    other.data = np.full(size, i % 251, dtype=np.uint8).tobytes()
    other.data[-1] = (i + 1) % 251
    try:
        equal = msg == same and same == msg and msg.data == same.data
        differ = msg != other and other != msg and msg.data != other.data
    except Exception:  # numpy's element-wise answer in a generated __eq__
        return "neq"
    return "eq" if equal and differ else "neq"


def _plain(topic: str) -> None:
    import rclpy

    rclpy.init()
    node = rclpy.create_node("shm_plain_peer")
    def show(msg: Image) -> None:
        print(f"msg {msg.header.frame_id} dds", flush=True)

    node.create_subscription(Image, topic, show, 10)
    print("ready", flush=True)
    _until_stdin_closes(lambda: rclpy.shutdown())
    with contextlib.suppress(Exception):  # the shutdown ends the spin
        rclpy.spin(node)


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("role", choices=("pub", "sub", "plain"))
    parser.add_argument("topic")
    parser.add_argument("--count", type=int, default=10)
    parser.add_argument("--sizes", default="262144")
    parser.add_argument("--readers", type=int, default=1)
    parser.add_argument("--period", type=float, default=0.02)
    parser.add_argument("--slow", type=float, default=0.0)
    parser.add_argument("--no-shm", action="store_true")
    args = parser.parse_args()
    if args.role == "plain":
        _plain(args.topic)
        return
    with Container(f"shm_{args.role}", shm=not args.no_shm, stats_period_s=0,
                   serve=False) as container:
        if args.role == "pub":
            container.add(lambda node: _Publisher(node, args), name="shm_pub")
        else:
            container.add(lambda node: _Subscriber(node, args), name="shm_sub")
            print("ready", flush=True)
        _until_stdin_closes(lambda: container.executor.post(container.shutdown))
        container.spin()


if __name__ == "__main__":
    main()
