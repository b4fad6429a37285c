"""A bag whose writer was killed with SIGKILL at any moment opens in every reader with every
message written before the kill: ``ros2 bag info``, rosbags, mcap's seeking reader.

The writer runs in a child process writing a known sequence and says after each flush how
many messages the bag holds for sure; the test kills it at seeded random moments (during
flushes, chunk writes and growth alike) and reads the bag with readers we do not control.
"""

from __future__ import annotations

import os
import random
import re
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

import pytest
from mcap.reader import make_reader
from rosbags.highlevel import AnyReader
from rosbags.rosbag2 import Reader as Rosbag2Reader

from efficient_comm.testing import isolated_domain_id

from ._cli import cli_env, ros2

CHILD = Path(__file__).with_name("_bag_writer_child.py")


def _kill_at(bag: Path, delay_s: float, chunk_bytes: int) -> int:
    """Run the child, SIGKILL it ``delay_s`` after it started writing; the count it had
    flushed by then (a lower bound of what the bag must hold)."""
    proc = subprocess.Popen([sys.executable, str(CHILD), str(bag), str(chunk_bytes)],
                            env=cli_env(0), stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                            text=True, start_new_session=True)
    assert proc.stdout is not None
    lines: list[str] = []
    started = threading.Event()

    def read() -> None:
        assert proc.stdout is not None
        for line in proc.stdout:
            lines.append(line.strip())
            started.set()

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    try:
        assert started.wait(30), "the child never started writing"
        assert lines[0] == "writing", lines
        # The moment of the kill is the point of the test: a timed wait, not a sync.
        time.sleep(delay_s)
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait(10)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    reader.join(10)
    proc.stdout.close()
    counts = [int(line) for line in lines[1:] if line.isdigit()]
    return counts[-1] if counts else 0


def _sequence(texts: list[str]) -> int:
    """The length of the sequence ``texts`` is, asserting it is "0", "1", ... in order."""
    assert texts == [str(i) for i in range(len(texts))], texts[:5]
    return len(texts)


@pytest.mark.parametrize("chunk_bytes", [4096, 1 << 20])
def test_a_bag_killed_at_random_moments_opens_everywhere_with_what_was_written(
        tmp_path: Path, chunk_bytes: int) -> None:
    rng = random.Random(18 + chunk_bytes)
    domain = isolated_domain_id()
    for k in range(3):
        bag = tmp_path / f"killed{k}"
        flushed = _kill_at(bag, rng.uniform(0.05, 0.6), chunk_bytes)
        (file,) = bag.glob("*.mcap")
        # mcap's seeking reader (falls back to reading in order: the footer has no summary)
        with open(file, "rb") as stream:
            in_mcap = _sequence([m.data[8:-1].decode() for _, _, m in
                                 make_reader(stream).iter_messages(log_time_order=False)])
        assert in_mcap >= flushed
        # rosbags, through metadata.yaml like rosbag2
        with Rosbag2Reader(bag) as reader:
            assert reader.message_count >= flushed  # as of the last flush
            assert [c.topic for c in reader.connections] == ["/seq"]
        with AnyReader([bag]) as any_reader:
            decoded: list[Any] = [any_reader.deserialize(raw, conn.msgtype)
                                  for conn, _, raw in any_reader.messages()]
        texts = [m.data for m in decoded]
        assert _sequence(texts) == in_mcap
        # ros2 bag info as a user types it: every message the file holds
        info = ros2("bag", "info", str(bag), domain_id=domain)
        assert info.returncode == 0, info.stderr
        match = re.search(r"^Messages:\s+(\d+)$", info.stdout, re.MULTILINE)
        assert match and int(match.group(1)) == in_mcap, info.stdout
        assert "Topic: /seq | Type: std_msgs/msg/String" in info.stdout
        # reindex finishes the file where it is
        done = ros2("bag", "reindex", str(bag), domain_id=domain)
        assert done.returncode == 0, done.stderr
        assert sorted(p.name for p in bag.iterdir()) == [file.name, "metadata.yaml"]
        with Rosbag2Reader(bag) as reader:
            assert reader.message_count == in_mcap
        with open(file, "rb") as stream:
            summary = make_reader(stream).get_summary()
        assert summary is not None and summary.statistics is not None
        assert summary.statistics.message_count == in_mcap
