"""A plain ROS 2 robot for GUI tests: one rclpy node, nothing of ours (no statistics).

``python tests/_gui_plain_robot.py --namespace /plainbot`` runs node ``plain_node`` in
``/plainbot`` (``--namespace /``: the root namespace, as a robot alone in its domain
usually runs) with a parameter ``speed`` (1.5) and a topic ``chatter`` (std_msgs/String,
10 Hz). Runs until Ctrl-C or SIGTERM; prints ``ready`` once its publisher exists.
"""

from __future__ import annotations

import argparse
import signal
import sys

import rclpy
from rclpy.context import Context
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from std_msgs.msg import String


def main() -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("--namespace", default="/")
    args = parser.parse_args()
    signal.signal(signal.SIGTERM, lambda *_: (_ for _ in ()).throw(KeyboardInterrupt))
    context = Context()
    rclpy.init(context=context)
    node = Node("plain_node", namespace=args.namespace, context=context)
    node.declare_parameter("speed", 1.5)
    chatter = node.create_publisher(String, "chatter", 10)
    node.create_timer(0.1, lambda: chatter.publish(String(data="plain")))
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    print("ready", flush=True)
    try:
        executor.spin()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        executor.shutdown()
        node.destroy_node()
        context.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
