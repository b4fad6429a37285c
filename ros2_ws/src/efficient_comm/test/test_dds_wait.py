"""One DDS wait of the container's executor takes every sample that is ready, not one.

A robot in the team match has several components subscribed to the IMU that the world
process publishes: each subscription a DDS reader of its own. rclpy's ``spin_once`` runs
the first ready callback of a wait and, called again with another timeout (the executor's
differs every time: the next timer's deadline), waits anew and drops what the last wait
found. The robot heard its IMU at a fraction of its rate.
"""

from __future__ import annotations

import rclpy
from rclpy.context import Context
from rclpy.duration import Duration
from rclpy.qos import QoSProfile, ReliabilityPolicy
from std_msgs.msg import String

from efficient_comm import Container
from efficient_comm.handle import NodeHandle
from efficient_comm.testing import isolated_domain_id, unique_topic

LISTENERS = 4
SAMPLES = 5
QOS = QoSProfile(depth=SAMPLES, reliability=ReliabilityPolicy.RELIABLE)


def test_one_wait_takes_every_ready_sample_of_every_reader() -> None:
    topic = unique_topic("imu")
    domain = isolated_domain_id()

    class Listener:
        def __init__(self, node: NodeHandle) -> None:
            self.heard: list[str] = []
            node.create_subscription(String, topic, lambda m: self.heard.append(m.data), qos=QOS)

    context = Context()  # the remote peer: a participant of its own, as another process
    rclpy.init(context=context, domain_id=domain)
    try:
        peer = rclpy.create_node("peer", context=context)
        pub = peer.create_publisher(String, topic, QOS)
        with Container("c", stats_period_s=0, serve=False, domain_id=domain) as container:
            listeners = [container.add(Listener, name=f"l{i}") for i in range(LISTENERS)]
            assert container.spin_until(lambda: pub.get_subscription_count() == LISTENERS,
                                        timeout_s=30), "the listeners' readers never matched"
            container.spin_for(0.2)  # discovery's own callbacks done before the samples
            for i in range(SAMPLES):
                pub.publish(String(data=str(i)))
            # Acknowledged: every sample is in every reader's history before the wait.
            assert pub.wait_for_all_acked(Duration(seconds=10))
            container.spin_once(timeout_s=5.0)
            heard = [listener.heard for listener in listeners]
            assert heard == [[str(i) for i in range(SAMPLES)]] * LISTENERS, heard
    finally:
        context.try_shutdown()
