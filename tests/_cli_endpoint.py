"""Plain rclpy endpoints (no efficient_comm) for the ros2 command's tests.

``python tests/_cli_endpoint.py NODE sub|pub TOPIC:TYPE...`` makes a node NODE with a
subscription (printing ``received on TOPIC: <repr of the message>``) or a publisher
(publishing the type's default message at 10 Hz) for each TOPIC:TYPE, and prints ``ready``.
"""

from __future__ import annotations

import contextlib
import importlib
import sys
from typing import Any

import rclpy
from rclpy.node import Node


def _message_class(name: str) -> Any:
    package, kind, cls = name.split("/")
    return getattr(importlib.import_module(f"{package}.{kind}"), cls)


def main() -> None:
    node_name, role, *endpoints = sys.argv[1:]
    rclpy.init()
    node = Node(node_name)
    publishers = []
    for endpoint in endpoints:
        topic, _, type_name = endpoint.partition(":")
        cls = _message_class(type_name)
        if role == "sub":
            def on_message(msg: Any, topic: str = topic) -> None:
                print(f"received on {topic}: {msg!r}", flush=True)

            node.create_subscription(cls, topic, on_message, 10)
        else:
            publishers.append((node.create_publisher(cls, topic, 10), cls))

    def tick() -> None:
        for pub, cls in publishers:
            pub.publish(cls())

    if publishers:
        node.create_timer(0.1, tick)
    print("ready", flush=True)
    with contextlib.suppress(KeyboardInterrupt):
        rclpy.spin(node)


if __name__ == "__main__":
    main()
