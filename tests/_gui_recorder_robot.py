"""A light robot with a recorder, for the recorder view's tests: one efficient_comm container.

``python tests/_gui_recorder_robot.py --namespace /r --bag-dir DIR`` composes, in namespace
``/r``, a talker publishing ``<ns>/chatter`` and ``<ns>/counter`` (std_msgs/String, 50 Hz
each; ``counter`` through a ThrottledPublisher, so a recorder may ask for a share of it) and
robot_recorder's Recorder ``<ns>/recorder`` (idle, selection ``chatter``, bags under DIR, a
1 MiB snapshot ring buffer, status every 0.2 s). The container publishes the
robot's statistics on ``<ns>/efficient_comm/stats``, which is how the GUI finds it. Prints
``ready`` once composed; runs until SIGTERM.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from std_msgs.msg import String

from efficient_comm import Container
from efficient_comm.handle import NodeHandle
from robot_recorder import Recorder
from throttle_publisher import ThrottledPublisher


class Talker:
    def __init__(self, node: NodeHandle) -> None:
        self.chatter = node.create_publisher(String, "chatter", qos=10)
        # Throttle-aware, so a recorder may ask for a share of it (every_nth, max_rate_hz).
        self.counter = ThrottledPublisher(node, String, "counter")
        self.i = 0
        node.create_timer(0.02, self.tick)

    def tick(self) -> None:
        self.chatter.publish(String(data=f"chatter {self.i}"))
        if self.counter.wants():
            self.counter.publish(String(data=f"counter {self.i}"))
        else:
            self.counter.skip()
        self.i += 1


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--namespace", default="/robot")
    parser.add_argument("--bag-dir", type=Path, required=True)
    args = parser.parse_args()
    with Container("rec_robot", namespace=args.namespace, stats_namespace=args.namespace,
                   stats_period_s=0.5) as container:
        container.add(Talker, name="talker", namespace=args.namespace)
        container.add(Recorder, name="recorder", namespace=args.namespace, parameters={
            "topics": ["chatter"], "output_dir": str(args.bag_dir),
            "snapshot_bytes": 1 << 20, "snapshot_seconds": 5.0, "status_period_s": 0.2,
            "min_free_bytes": 0,
        })
        print("ready", flush=True)
        container.spin()


if __name__ == "__main__":
    main()
