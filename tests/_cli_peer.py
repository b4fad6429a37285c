"""A plain rclpy node (no efficient_comm) for the ros2 command's tests.

``python tests/_cli_peer.py TOPIC`` publishes std_msgs/String ``hello N`` on TOPIC at 20 Hz,
subscribes to TOPIC + "_in" and prints what it receives, declares parameters of each kind
(``scratch`` dynamically typed, so it can be deleted), offers a service ``~/check``
(efficient_comm_interfaces/srv/UnloadComponent: success when the id is 7) and prints
``ready`` once all of that exists.
"""

from __future__ import annotations

import contextlib
import sys

import rclpy
from rcl_interfaces.msg import ParameterDescriptor
from rclpy.node import Node
from std_msgs.msg import String

from efficient_comm_interfaces.srv import UnloadComponent


def main() -> None:
    topic = sys.argv[1]
    rclpy.init()
    node = Node("cli_peer")
    node.declare_parameter("count", 5)
    node.declare_parameter("gain", 1.5)
    node.declare_parameter("label", "hello")
    node.declare_parameter("enabled", True)
    node.declare_parameter("ids", [1, 2, 3])
    node.declare_parameter("nested.depth", 2)
    node.declare_parameter("scratch", "x", ParameterDescriptor(dynamic_typing=True))
    pub = node.create_publisher(String, topic, 10)
    sequence = [0]

    def tick() -> None:
        sequence[0] += 1
        pub.publish(String(data=f"hello {sequence[0]}"))

    def on_in(msg: String) -> None:
        print(f"received: {msg.data}", flush=True)

    def check(request: UnloadComponent.Request,
              response: UnloadComponent.Response) -> UnloadComponent.Response:
        response.success = request.unique_id == 7
        response.error_message = f"got {request.unique_id}"
        return response

    node.create_timer(0.05, tick)
    node.create_subscription(String, topic + "_in", on_in, 10)
    node.create_service(UnloadComponent, "~/check", check)
    print("ready", flush=True)
    with contextlib.suppress(KeyboardInterrupt):
        rclpy.spin(node)


if __name__ == "__main__":
    main()
