"""A plain rclpy node (nobody here wrote it for the GUI) feeding the world, topics and log views.

``python tests/_gui_world_peer.py --namespace /alpha --x 1.5 --token T`` publishes, in its
namespace, ``odom`` (nav_msgs/Odometry, the robot at (x, -1) facing +y) and
``ground_truth/robot`` (the same pose 0.1 m further along x), ``ball/estimate``
(PointStamped: straight ahead, 1 m away) and ``point`` (geometry_msgs/Point whose ``x``
counts up, ``y`` = the given x), logs ``peer T says N`` at INFO every 0.2 s and a
``<ns>/world_peer: battery`` WARN status on /diagnostics; once, latched (transient local),
``motion/state`` (std_msgs/String ``--motion``, default ``walk``), as a motion arbiter says
which motion owns the joints. Prints ``ready``; runs until SIGTERM.
"""

from __future__ import annotations

import argparse
import math
import signal

import rclpy
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node


def main() -> int:
    from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
    from geometry_msgs.msg import Point, PointStamped, PoseStamped
    from nav_msgs.msg import Odometry
    from rclpy.qos import DurabilityPolicy, QoSProfile
    from std_msgs.msg import String

    parser = argparse.ArgumentParser()
    parser.add_argument("--namespace", default="/robot")
    parser.add_argument("--x", type=float, default=0.0)
    parser.add_argument("--token", default="hello")
    parser.add_argument("--motion", default="walk")
    args = parser.parse_args()
    signal.signal(signal.SIGTERM, lambda *_: (_ for _ in ()).throw(KeyboardInterrupt))
    context = Context()
    rclpy.init(context=context)
    node = Node("world_peer", namespace=args.namespace, context=context)
    odom = node.create_publisher(Odometry, "odom", 10)
    truth = node.create_publisher(PoseStamped, "ground_truth/robot", 10)
    ball = node.create_publisher(PointStamped, "ball/estimate", 10)
    point = node.create_publisher(Point, "point", 10)
    diagnostics = node.create_publisher(DiagnosticArray, "/diagnostics", 10)
    motion = node.create_publisher(String, "motion/state", QoSProfile(
        depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL))
    motion.publish(String(data=args.motion))  # once: who looks later gets it all the same
    count = 0
    half = math.sqrt(0.5)

    def tick() -> None:
        nonlocal count
        count += 1
        stamp = node.get_clock().now().to_msg()
        o = Odometry()
        o.header.stamp = stamp
        o.pose.pose.position.x, o.pose.pose.position.y = args.x, -1.0
        o.pose.pose.orientation.z = o.pose.pose.orientation.w = half  # facing +y
        odom.publish(o)
        t = PoseStamped()
        t.header.stamp = stamp
        t.pose.position.x, t.pose.position.y = args.x + 0.1, -1.0
        t.pose.orientation.z = t.pose.orientation.w = half
        truth.publish(t)
        b = PointStamped()
        b.header.stamp = stamp
        b.point.x, b.point.y, b.point.z = 0.0, 0.0, 1.0
        ball.publish(b)
        point.publish(Point(x=float(count), y=args.x))

    def talk() -> None:
        node.get_logger().info(f"peer {args.token} says {count}")
        status = DiagnosticStatus(level=DiagnosticStatus.WARN,
                                  name=f"{node.get_fully_qualified_name()}: battery",
                                  message="battery low", hardware_id="pack",
                                  values=[KeyValue(key="volts", value="10.9")])
        diagnostics.publish(DiagnosticArray(status=[status]))

    node.create_timer(0.05, tick)
    node.create_timer(0.2, talk)
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


if __name__ == "__main__":
    raise SystemExit(main())
