"""``ros2 topic info`` counts every endpoint of a topic, whichever process it lives in.

Without a daemon the command discovers the graph itself, and each process's DDS participant
announces itself on its own schedule: the first endpoint seen says nothing about the others.
Several subscriber processes make answering too early (as soon as the topic appears) show.
"""

from __future__ import annotations

import sys
from contextlib import ExitStack
from pathlib import Path

from efficient_comm.testing import isolated_domain_id, unique_topic

from ._cli import ROOT, ros2, running

ENDPOINT = ROOT / "tests" / "_cli_endpoint.py"
SUBSCRIBERS = 3


def test_topic_info_counts_endpoints_of_every_process(tmp_path: Path) -> None:
    domain_id = isolated_domain_id()
    topic = unique_topic("info")
    endpoint = f"{topic}:std_msgs/msg/String"
    with ExitStack() as stack:
        peers = [stack.enter_context(running(
            [sys.executable, str(ENDPOINT), f"talker_{i}" if i == 0 else f"listener_{i}",
             "pub" if i == 0 else "sub", endpoint],
            domain_id=domain_id, log=tmp_path / f"peer{i}.log"))
            for i in range(SUBSCRIBERS + 1)]
        for peer in peers:
            peer.wait_for(lambda text: "ready" in text)
        expected = ("Type: std_msgs/msg/String\nPublisher count: 1\n"
                    f"Subscription count: {SUBSCRIBERS}\n")
        answers = [ros2("topic", "info", topic, domain_id=domain_id) for _ in range(5)]
        # A relative name is the same topic (ros2cli resolves it against the root namespace).
        answers.append(ros2("topic", "info", topic.lstrip("/"), domain_id=domain_id))
    assert [a.stdout for a in answers] == [expected] * len(answers), \
        [(a.stdout, a.stderr) for a in answers]
