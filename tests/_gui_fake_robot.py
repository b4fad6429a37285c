"""A light robot for GUI tests: a plain rclpy process publishing ExecutorStats.

``python tests/_gui_fake_robot.py --namespace /robot2`` publishes on
``/robot2/efficient_comm/stats`` what an efficient_comm container would: callbacks of
components named after the robot (``robot2_component0``), the last one slower than its
period (to be flagged).
It also offers a plain topic ``<ns>/chatter`` (std_msgs/String, 20 Hz, not throttle-aware),
a throttle-aware one ``<ns>/counter`` (std_msgs/String, 50 Hz, through a ThrottledPublisher;
it prints ``computed N, stats readers M, counter requests [R, ...]`` once a second:
samples it computed because someone wanted them, how many read its statistics, and the
rate each throttled subscriber of ``counter`` asks for) and
a service ``<ns>/fake_robot/slow`` that never answers (rcl_interfaces' ListParameters).
Runs until Ctrl-C or SIGTERM; prints ``ready`` once its publishers exist.
"""

from __future__ import annotations

import argparse
import os
import signal
import socket
import sys
import time

import rclpy
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node


def main() -> int:
    from rcl_interfaces.srv import ListParameters
    from std_msgs.msg import String

    from efficient_comm.standalone import StandaloneHandle
    from efficient_comm_interfaces.msg import CallbackStats, ExecutorStats
    from throttle_publisher import ThrottledPublisher

    parser = argparse.ArgumentParser()
    parser.add_argument("--namespace", default="/robot")
    parser.add_argument("--period", type=float, default=0.5)
    parser.add_argument("--callbacks", type=int, default=3)
    args = parser.parse_args()
    signal.signal(signal.SIGTERM, lambda *_: (_ for _ in ()).throw(KeyboardInterrupt))
    context = Context()
    rclpy.init(context=context)
    node = Node("fake_robot", namespace=args.namespace, context=context)
    stats = node.create_publisher(ExecutorStats, "efficient_comm/stats", 10)
    chatter = node.create_publisher(String, "chatter", 10)
    count = 0
    ns = args.namespace.rstrip("/")
    robot = ns.rsplit("/", 1)[-1] or "root"

    def publish_stats() -> None:
        nonlocal count
        count += 1
        msg = ExecutorStats(process_name="fake_robot", hostname=socket.gethostname(),
                            pid=os.getpid(), window_ns=int(args.period * 1e9))
        for i in range(args.callbacks):
            slow = i == args.callbacks - 1
            msg.callbacks.append(CallbackStats(
                node=f"{ns}/{robot}_component{i}", kind="timer" if slow else "subscription",
                name=f"{ns}/{robot}_topic{i}", calls=count * (i + 1), exceptions=0, drops=0,
                rate_hz=10.0 * (i + 1), mean_ns=(1 + count % 4) * 1_000_000 * (i + 1),
                p95_ns=(60_000_000 if slow else 2_000_000 * (i + 1)),
                max_ns=70_000_000 if slow else 3_000_000 * (i + 1),
                period_ns=50_000_000 if slow else 0,
            ))
        msg.stamp = node.get_clock().now().to_msg()
        stats.publish(msg)

    handle = StandaloneHandle(node)
    counter = ThrottledPublisher(handle, String, "counter")
    computed = 0

    def publish_counter() -> None:
        nonlocal computed
        if counter.wants():
            computed += 1
            counter.publish(String(data=f"{ns} {computed}"))
        else:
            counter.skip()

    node.create_timer(0.02, publish_counter)
    node.create_timer(1.0, lambda: print(
        f"computed {computed}, stats readers {stats.get_subscription_count()}, "
        f"counter requests {sorted(o.max_rate_hz for o in counter.requests().values())}",
        flush=True))
    node.create_service(ListParameters, "~/slow", _never_answer)
    node.create_timer(args.period, publish_stats)
    node.create_timer(0.05, lambda: chatter.publish(String(data=f"{ns} {time.time_ns()}")))
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    print("ready", flush=True)
    try:
        while context.ok():
            executor.spin_once(timeout_sec=0.1)
    except KeyboardInterrupt:
        pass
    finally:
        executor.shutdown()
        node.destroy_node()
        context.try_shutdown()
    return 0


def _never_answer(request: object, response: object) -> object:
    """Blocks this process's executor for a while: the caller times out first."""
    time.sleep(30.0)
    return response


if __name__ == "__main__":
    sys.exit(main())
