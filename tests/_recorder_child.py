"""A process that records its own 200 Hz counter until it is killed (SIGKILL test)."""

from __future__ import annotations

import sys
from pathlib import Path

from std_msgs.msg import String

from efficient_comm import Container
from efficient_comm.handle import NodeHandle
from robot_recorder import Recorder


class Counter:
    def __init__(self, node: NodeHandle, topic: str) -> None:
        self.pub = node.create_publisher(String, topic, qos=100)
        self.i = 0
        node.create_timer(0.005, self.tick)

    def tick(self) -> None:
        self.pub.publish(String(data=str(self.i)))
        self.i += 1


def main() -> None:
    bag, topic = Path(sys.argv[1]), sys.argv[2]
    with Container("child", dds=False, serve=False) as container:
        container.add(lambda n: Counter(n, topic), name="counter")
        recorder = container.add(
            lambda n: Recorder(n, topics=[topic], output_dir=bag.parent), name="recorder")
        recorder.start(bag).result(10)
        print("recording", flush=True)
        container.spin()


if __name__ == "__main__":
    main()
