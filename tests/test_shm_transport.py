"""The shared-memory transport across real processes (efficient_comm.shm, issue 20).

Each test starts its peers (``tests/_shm_peer.py``) as separate processes on a domain of its
own and reads what they print: which message arrived, over which path, read-only or not.
"""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
import textwrap
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from efficient_comm.testing import isolated_domain_id, ros_env, stop_process_group, unique_topic

PEER = Path(__file__).with_name("_shm_peer.py")
LARGE = 300_000  # above the default threshold (64 KiB)
SMALL = 1_000


class Peer:
    """A peer process; ``lines()`` reads its stdout up to a deadline."""

    def __init__(self, env: dict[str, str], *args: str) -> None:
        self.args = args
        self.proc = subprocess.Popen(
            [sys.executable, str(PEER), *args], env=env, stdin=subprocess.PIPE,
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True,
        )
        self.seen: list[str] = []

    def until(self, predicate: str | int, *, timeout_s: float = 60.0) -> list[str]:
        """Read lines until one starts with ``predicate`` (or ``predicate`` msg lines)."""
        assert self.proc.stdout is not None
        end = time.monotonic() + timeout_s
        while time.monotonic() < end:
            if isinstance(predicate, str) and any(x.startswith(predicate) for x in self.seen):
                return self.seen
            if isinstance(predicate, int) and len(self.messages()) >= predicate:
                return self.seen
            line = self.proc.stdout.readline()
            if not line:
                break
            self.seen.append(line.strip())
        raise AssertionError(f"peer {self.args} did not get to {predicate!r}: "
                             f"{self.seen[-5:]}; stderr: {self.stderr()}")

    def messages(self) -> list[list[str]]:
        return [line.split()[1:] for line in self.seen if line.startswith("msg ")]

    def stderr(self) -> str:
        if self.proc.poll() is None or self.proc.stderr is None or self.proc.stderr.closed:
            return "(running or stopped)"
        return self.proc.stderr.read()[-2000:]

    def kill(self) -> None:
        os.killpg(self.proc.pid, signal.SIGKILL)
        self.proc.wait()

    def stop(self) -> None:
        if self.proc.poll() is None and self.proc.stdin is not None \
                and not self.proc.stdin.closed:
            self.proc.stdin.close()  # the peer's signal to leave
            with contextlib.suppress(subprocess.TimeoutExpired):
                self.proc.wait(timeout=10)
        stop_process_group(self.proc)
        for stream in (self.proc.stdin, self.proc.stdout, self.proc.stderr):
            if stream is not None and not stream.closed:
                stream.close()


@pytest.fixture
def peers() -> Iterator[tuple[dict[str, str], str, list[Peer]]]:
    env = ros_env(isolated_domain_id())
    started: list[Peer] = []
    yield env, unique_topic("shm"), started
    for peer in started:
        peer.stop()


def _start(started: list[Peer], env: dict[str, str], *args: str) -> Peer:
    peer = Peer(env, *args)
    started.append(peer)
    return peer


def test_each_subscriber_gets_each_message_once_in_order(
    peers: tuple[dict[str, str], str, list[Peer]],
) -> None:
    """A subscriber with the transport beside a plain rclpy one: large messages reach the
    first in place (read-only, bytes intact, a kept one untouched by later chunks), small
    ones over DDS, each once and in order, and each compares with ``==`` as a message of
    its type does; the plain one gets every message once."""
    env, topic, started = peers
    count = 12
    sub = _start(started, env, "sub", topic)
    plain = _start(started, env, "plain", topic)
    sub.until("ready")
    plain.until("ready")
    pub = _start(started, env, "pub", topic, "--readers", "2", "--count", str(count),
                 "--sizes", f"{SMALL},{LARGE}")
    pub.until("published")
    got = sub.until(count) and sub.messages()
    plain_got = plain.until(count) and plain.messages()
    assert [int(m[0]) for m in got] == list(range(count))
    for i, (_, via, ro, ok, dropped, kept, equal) in enumerate(got):
        assert (via, ro) == (("shm", "ro") if i % 2 else ("dds", "rw")), got[i]
        assert (ok, dropped, kept) == ("ok", "0", "kept"), got[i]
        assert equal == "eq", f"msg == other does not work for {via}: {got[i]}"
    assert [int(m[0]) for m in plain_got] == list(range(count))
    sub.stop()  # no duplicate that came late
    assert len(sub.messages()) == count


def test_a_slow_reader_loses_its_oldest_messages_counted(
    peers: tuple[dict[str, str], str, list[Peer]],
) -> None:
    """A reader slower than the publisher loses messages (the publisher never waits for
    it); each loss is counted (``on_lost`` and the ``dropped`` statistic) and the newest
    message arrives."""
    env, topic, started = peers
    count = 40
    sub = _start(started, env, "sub", topic, "--slow", "0.05")
    sub.until("ready")
    pub = _start(started, env, "pub", topic, "--count", str(count), "--period", "0.005",
                 "--sizes", str(LARGE))
    pub.until("published")
    sub.until(f"msg {count - 1} ")
    got = sub.messages()
    ids = [int(m[0]) for m in got]
    assert ids == sorted(set(ids)) and ids[-1] == count - 1
    assert all(m[1] == "shm" for m in got)
    lost = count - len(ids)
    assert lost > 0, "the reader kept up: no loss to count"
    # the loss count printed with the last message covers every gap before it
    assert int(got[-1][4]) == lost


def _nodes_of(pids: set[int]) -> set[tuple[str, int]]:
    """The iceoryx2 nodes (``Alive`` or ``Dead``, by process id) of these processes: by
    their owners, not by the files in /dev/shm, which other tests' live peers add to."""
    import iceoryx2 as iox2

    found = set()
    for state in iox2.Node.list(iox2.ServiceType.Ipc, iox2.config.global_config()):
        for kind in ("Alive", "Dead"):
            if isinstance(state, getattr(iox2.NodeState, kind)):
                details = state._0.details
                if details is not None and details.process_id in pids:
                    found.add((kind, details.process_id))
    return found


def test_sigkill_of_either_side_blocks_nobody_and_leaks_nothing(
    peers: tuple[dict[str, str], str, list[Peer]],
) -> None:
    """A subscriber killed mid-stream stalls neither the publisher nor the other reader; a
    killed publisher leaves the reader alive for the next publisher; the files the killed
    processes leave in /dev/shm are removed by the next container with the transport."""
    env, topic, started = peers
    count = 30
    survivor = _start(started, env, "sub", topic)
    victim = _start(started, env, "sub", topic, "--slow", "0.02")
    survivor.until("ready")
    victim.until("ready")
    pub = _start(started, env, "pub", topic, "--readers", "2", "--count", str(count),
                 "--sizes", str(LARGE), "--period", "0.03")
    victim.until(1)
    victim.kill()
    pub.until("published")
    assert [int(m[0]) for m in survivor.until(count) and survivor.messages()] == \
        list(range(count))
    pub.kill()
    killed = {victim.proc.pid, pub.proc.pid}
    # Dead, with what they left to clean up (unless another test's container, starting
    # meanwhile, has cleaned it already: any new iceoryx2 node does).
    left = _nodes_of(killed)
    assert all(kind == "Dead" for kind, _ in left), left
    second = _start(started, env, "pub", topic, "--count", "3", "--sizes", str(LARGE))
    second.until("published")
    again = survivor.until(count + 3) and survivor.messages()[count:]
    assert [(m[0], m[1]) for m in again] == [("0", "shm"), ("1", "shm"), ("2", "shm")]
    second.stop()
    survivor.stop()
    # A new container's iceoryx2 node cleans up after dead ones.
    fresh = _start(started, env, "sub", topic)
    fresh.until("ready")
    fresh.stop()
    assert not _nodes_of(killed), _nodes_of(killed)


FALLBACKS = textwrap.dedent("""
    from efficient_comm import Container, latched_qos
    from sensor_msgs.msg import Image
    from std_msgs.msg import String
    from diagnostic_msgs.msg import KeyValue
    from sensor_msgs.msg import JointState
    with Container("fallbacks", shm=True, serve=False, stats_period_s=0) as c:
        def make(node):
            node.create_publisher(Image, "latched", qos=latched_qos())
            node.create_publisher(String, "text")
            node.create_subscription(KeyValue, "pairs", lambda m: None)
            node.create_subscription(JointState, "joints", lambda m: None)
            node.create_publisher(JointState, "joints")
            node.create_publisher(String, "latched_text", qos=latched_qos())
            node.create_publisher(Image, "image")
        c.add(make, name="maker")
    with Container("nodds", shm=True, dds=False, serve=False, stats_period_s=0):
        pass
    import os
    from efficient_comm import Standalone
    os.environ["EFFICIENT_COMM_SHM"] = "1"
    with Standalone(lambda node: None, name="alone", stats_period_s=0):
        pass
""")


def test_what_does_not_fit_falls_back_to_dds_with_one_line_why() -> None:
    """A latched image, a type with three arrays, a container without DDS, a standalone node
    with EFFICIENT_COMM_SHM set: one line each (a topic's publisher and subscriber in one
    process share theirs; a latched type with nothing large in it is told at debug level)."""
    env = ros_env(isolated_domain_id())
    done = subprocess.run([sys.executable, "-c", FALLBACKS], env=env, capture_output=True,
                          text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    lines = [line for line in (done.stderr + done.stdout).splitlines()
             if "no shared memory" in line]
    assert any("/latched" in line and "transient local" in line for line in lines), lines
    assert any("/joints" in line and "sensor_msgs/msg/JointState has 3 top-level arrays"
               in line for line in lines), lines
    # Types with nothing large in them are told at debug level only (a robot has many).
    assert not any("/text" in line or "/pairs" in line or "/latched_text" in line
                   for line in lines), lines
    assert not any("/image" in line for line in lines), lines
    assert any("nodds" in line and "no DDS" in line for line in lines), lines
    assert any("alone" in line and "standalone" in line and "container" in line
               for line in lines), lines
    assert len(lines) == 4, lines


ONE_WAIT = textwrap.dedent("""
    import threading
    from efficient_comm import Container
    from sensor_msgs.msg import Image
    from std_msgs.msg import Float32MultiArray
    with Container("onewait", shm=True, serve=False, stats_period_s=0) as c:
        before = threading.active_count()
        def make(node):
            for i in range(3):
                node.create_subscription(Image, f"image{i}", lambda m: None)
            node.create_subscription(Float32MultiArray, "floats", lambda m: None)
        c.add(make, name="subs")
        grown = threading.active_count() - before
        ran = []
        poster = threading.Thread(
            target=lambda: c.executor.post(lambda: ran.append(threading.get_ident())))
        poster.start()
        posted = c.executor.spin_until(lambda: bool(ran), timeout_s=30)
        poster.join()
        c.take_dds()  # the executor takes from DDS itself
        here = posted and ran[0] == threading.get_ident()
        print("threads", grown, "posted", "here" if here else "elsewhere", "took", flush=True)
""")


def test_subscriptions_share_the_executors_one_wait() -> None:
    """Four shared-memory subscriptions add one thread (the watch over their listeners),
    not one each; a call posted from another thread still runs in the executor's thread,
    and a direct DDS take (a lockstep world's) works beside the watch."""
    env = ros_env(isolated_domain_id())
    done = subprocess.run([sys.executable, "-c", ONE_WAIT], env=env, capture_output=True,
                          text=True, timeout=120)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.split() == ["threads", "1", "posted", "here", "took"], done.stdout


def test_a_recorder_in_another_process_records_large_messages_from_shared_memory(
    peers: tuple[dict[str, str], str, list[Peer]], tmp_path: Path,
) -> None:
    """robot_recorder in a container of its own, the transport on through the environment
    (as a user starts it): the images reach it through shared memory (the publisher writes
    none to DDS) and the bag holds every one of them, byte for byte."""
    import yaml

    from robot_recorder.testing import read_rosbags
    from robot_recorder_interfaces.msg import RecorderStatus

    from ._ros import executable, peer

    env, topic, started = peers
    count = 12
    config = tmp_path / "recorder.yaml"
    config.write_text(yaml.safe_dump({"components": [{
        "class": "robot_recorder.recorder:Recorder", "name": "recorder",
        "parameters": {"/recorder": {"ros__parameters": {
            "topics": [topic], "output_dir": str(tmp_path / "logs"), "autostart": True,
            "status_period_s": 0.2}}}}]}))
    log = tmp_path / "recorder.log"
    with open(log, "wb") as out:
        recorder = subprocess.Popen(
            [str(executable("efficient_comm", "container")), "--config", str(config),
             "--name", "rec"],
            env={**env, "EFFICIENT_COMM_SHM": "1"}, stdout=out, stderr=subprocess.STDOUT,
            start_new_session=True)
    try:
        statuses: list[RecorderStatus] = []
        with peer(int(env["ROS_DOMAIN_ID"]), "status_reader") as reader:
            reader.node.create_subscription(RecorderStatus, "/recorder/status",
                                            statuses.append, 10)
            pub = _start(started, env, "pub", topic, "--readers", "1", "--count", str(count),
                         "--sizes", str(LARGE), "--period", "0.1")
            (done,) = [line for line in pub.until("published") if line.startswith("published")]
            assert reader.wait_for(
                lambda: bool(statuses) and statuses[-1].messages >= count, timeout_s=60
            ), (done, statuses[-1:] and (statuses[-1].error, statuses[-1].topics),
             log.read_text()[-2000:])
        assert done == f"published {count} dds 0", done  # shared memory served the recorder
        os.killpg(recorder.pid, signal.SIGINT)
        assert recorder.wait(timeout=30) == 0, log.read_text()[-2000:]
    finally:
        stop_process_group(recorder)
    (bag,) = (tmp_path / "logs").iterdir()
    images = [msg for name, msg in read_rosbags(bag) if name == topic]
    assert [int(m.header.frame_id) for m in images] == list(range(count))
    for i, image in enumerate(images):
        assert image.width == LARGE and bytes(image.data) == bytes([i % 251]) * LARGE, i
