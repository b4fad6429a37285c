"""A plain rclpy node whose parameter sets the test holds in flight (parameters view tests).

``python tests/_gui_param_node.py --namespace /tn`` runs node ``tuner`` in ``/tn`` with an
integer parameter ``level`` (10, declared with a ParameterDescriptor range 0..100 step 1).
Every set of ``level`` is held in the node's on-set callback until a line arrives on its
standard input: it prints ``holding level N`` when the set arrives and ``level N`` once the
value is in place. So a test sees the GUI's state while a set is in flight, and then lets
it complete. Prints ``ready`` once the parameter exists; runs until SIGTERM.
"""

from __future__ import annotations

import argparse
import signal
import sys
import threading
from typing import Any

import rclpy
from rcl_interfaces.msg import IntegerRange, ParameterDescriptor, SetParametersResult
from rclpy.context import Context
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node


def main() -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("--namespace", default="/tn")
    args = parser.parse_args()
    signal.signal(signal.SIGTERM, lambda *_: (_ for _ in ()).throw(KeyboardInterrupt))
    context = Context()
    rclpy.init(context=context)
    node = Node("tuner", namespace=args.namespace, context=context)
    released = threading.Semaphore(0)

    def release() -> None:
        for _line in sys.stdin:
            released.release()

    threading.Thread(target=release, daemon=True).start()

    def hold(changed: list[Any]) -> SetParametersResult:
        for p in changed:
            if p.name == "level":
                print(f"holding level {p.value}", flush=True)
                released.acquire()
        return SetParametersResult(successful=True)

    node.declare_parameter("level", 10, ParameterDescriptor(
        description="how much",
        integer_range=[IntegerRange(from_value=0, to_value=100, step=1)]))
    def tell(changed: list[Any]) -> None:
        for p in changed:
            print(f"{p.name} {p.value}", flush=True)

    node.add_on_set_parameters_callback(hold)
    node.add_post_set_parameters_callback(tell)
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
