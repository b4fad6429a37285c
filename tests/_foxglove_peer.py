"""A plain rclpy robot (no efficient_comm) for the Foxglove endpoint's and the parameters
view's tests.

``python tests/_foxglove_peer.py NAMESPACE TOPIC [throttled]`` runs a node ``detector`` in
NAMESPACE that publishes std_msgs/String ``hello N`` on TOPIC (relative: under the
namespace) at 20 Hz (with ``throttled``: through a ThrottledPublisher, only while someone
wants it, printing ``wants True``/``wants False`` as that changes),
publishes ``efficient_comm/stats`` (so the GUI's Hub sees a robot) and, once at the start,
a transient-local (latched) String on TOPIC_latched, declares a double
parameter ``threshold`` (0.5; negative values are vetoed), offers ``~/check``
(efficient_comm_interfaces/srv/UnloadComponent: success when the id is 7), declares
parameters of other kinds with descriptors (``count``: integer 0..10; ``gain``: double
0.0..2.0; ``label``: read-only string; ``enabled``: boolean; ``ids``: integer array;
``mode``: string, ``fast`` or ``slow``, anything else vetoed) and prints, from
the robot's side, what the tests check: ``subscribers N`` whenever the number of
subscriptions to TOPIC changes and ``NAME VALUE`` whenever a parameter changes. It
prints ``ready`` once all of that exists.
"""

from __future__ import annotations

import contextlib
import sys

import rclpy
from rcl_interfaces.msg import (
    FloatingPointRange,
    IntegerRange,
    ParameterDescriptor,
    SetParametersResult,
)
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, QoSProfile
from std_msgs.msg import String

from efficient_comm.standalone import StandaloneHandle
from efficient_comm_interfaces.msg import ExecutorStats
from efficient_comm_interfaces.srv import UnloadComponent
from throttle_publisher import ThrottledPublisher


def main() -> None:
    namespace, topic = sys.argv[1], sys.argv[2]
    rclpy.init()
    node = Node("detector", namespace=namespace)
    node.declare_parameter("threshold", 0.5)
    node.declare_parameter("count", 3, ParameterDescriptor(
        description="how many", integer_range=[IntegerRange(from_value=0, to_value=10, step=1)]))
    node.declare_parameter("gain", 1.0, ParameterDescriptor(
        floating_point_range=[FloatingPointRange(from_value=0.0, to_value=2.0, step=0.0)]))
    node.declare_parameter("label", "peer", ParameterDescriptor(read_only=True))
    node.declare_parameter("enabled", True)
    node.declare_parameter("ids", [1, 2, 3])
    node.declare_parameter("mode", "fast", ParameterDescriptor(
        additional_constraints="fast or slow"))
    throttled = ThrottledPublisher(StandaloneHandle(node), String, topic) \
        if sys.argv[3:] == ["throttled"] else None
    plain = node.create_publisher(String, topic, 10) if throttled is None else None
    wanted: list[bool | None] = [None]
    stats = node.create_publisher(ExecutorStats, "efficient_comm/stats", 10)
    latched = node.create_publisher(String, f"{topic}_latched", QoSProfile(
        depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL))
    latched.publish(String(data="published once, before anyone looked"))
    sequence = [0]
    subscribers = [-1]

    def veto(params: list[Parameter]) -> SetParametersResult:
        for param in params:
            if param.name == "threshold" and float(param.value) < 0:
                return SetParametersResult(successful=False,
                                           reason="threshold must not be negative")
            if param.name == "mode" and param.value not in ("fast", "slow"):
                return SetParametersResult(successful=False,
                                           reason=f"mode {param.value!r} is neither fast nor slow")
        for param in params:
            print(f"{param.name} {param.value}", flush=True)
        return SetParametersResult(successful=True)

    def tick() -> None:
        sequence[0] += 1
        if throttled is not None:
            wants = throttled.wants()
            if wants != wanted[0]:
                wanted[0] = wants
                print(f"wants {wants}", flush=True)
            if wants:  # else nothing is computed, nothing sent
                throttled.publish(String(data=f"hello {sequence[0]}"))
            return
        assert plain is not None
        plain.publish(String(data=f"hello {sequence[0]}"))
        count = plain.get_subscription_count()
        if count != subscribers[0]:
            subscribers[0] = count
            print(f"subscribers {count}", flush=True)

    def check(request: UnloadComponent.Request,
              response: UnloadComponent.Response) -> UnloadComponent.Response:
        response.success = request.unique_id == 7
        response.error_message = f"got {request.unique_id}"
        return response

    node.add_on_set_parameters_callback(veto)
    node.create_timer(0.05, tick)
    node.create_timer(0.5, lambda: stats.publish(ExecutorStats(process_name="foxglove_peer")))
    node.create_service(UnloadComponent, "~/check", check)
    print("ready", flush=True)
    with contextlib.suppress(KeyboardInterrupt):
        rclpy.spin(node)


if __name__ == "__main__":
    main()
