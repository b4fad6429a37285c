"""A process that writes a known sequence into a bag until it is killed (SIGKILL tests).

``_bag_writer_child.py BAG CHUNK_BYTES``: std_msgs/String "0", "1", ... on ``/seq``, one
every 100 µs of log time; after each flush it prints how many messages the bag holds for
sure (the flush handed them to the operating system), so the test knows a lower bound.
"""

from __future__ import annotations

import sys
from pathlib import Path

from rclpy.serialization import serialize_message
from std_msgs.msg import String

from rosbag2_layout import BagWriter


def main() -> None:
    bag, chunk_bytes = Path(sys.argv[1]), int(sys.argv[2])
    writer = BagWriter(bag, min_free_bytes=0, chunk_bytes=chunk_bytes)
    writer.write("/seq", "std_msgs/msg/String", bytes(serialize_message(String(data="0"))),
                 1_000_000_000)
    writer.flush()  # the file exists from here on
    print("writing", flush=True)
    i = 1
    while True:
        writer.write("/seq", "std_msgs/msg/String", bytes(serialize_message(String(data=str(i)))),
                     1_000_000_000 + i * 100_000)
        i += 1
        if i % 97 == 0:  # and between, chunks close when they reach chunk_bytes
            writer.flush()
            print(i, flush=True)


if __name__ == "__main__":
    main()
