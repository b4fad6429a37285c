"""A publisher that makes DDS lose reliable messages, as heavy traffic does on a robot.

``python tests/_burst_peer.py TOPIC COUNT``: std_msgs/String on TOPIC (reliable, KEEP_LAST
depth 1, each with 64 KiB of padding), numbered ``0 ...``. It waits for one subscriber,
prints ``ready``, then on a line ``go`` on stdin publishes COUNT messages back to back (the
writer drops each one not yet acknowledged when the next comes, so many never arrive), prints
``published COUNT`` and stays until stdin closes.
"""

from __future__ import annotations

import sys
import time

import rclpy
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from std_msgs.msg import String


def main() -> None:
    topic, count = sys.argv[1], int(sys.argv[2])
    rclpy.init()
    node = Node("burst_peer")
    pub = node.create_publisher(String, topic,
                                QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE))
    while pub.get_subscription_count() < 1:
        rclpy.spin_once(node, timeout_sec=0.05)
    print("ready", flush=True)
    if sys.stdin.readline().strip() != "go":
        return
    pad = "x" * 65536
    for i in range(count):
        pub.publish(String(data=f"{i} {pad}"))
    print(f"published {count}", flush=True)
    end = time.monotonic() + 600
    while sys.stdin.readline() and time.monotonic() < end:  # until stdin closes
        pass
    node.destroy_node()
    rclpy.shutdown()


if __name__ == "__main__":
    main()
