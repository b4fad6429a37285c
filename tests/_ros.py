"""Helpers for suites that run ROS 2 processes: a peer node, child processes, waiting."""

from __future__ import annotations

import subprocess
import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path

import rclpy
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node

from efficient_comm.testing import ros_env, stop_process_group

INSTALL = Path(__file__).resolve().parents[1] / "ros2_ws" / "install"


#: A Fast DDS participant that announces a 2 s lease: once killed, every other participant
#: drops it (and its endpoints) after 2 s instead of the default 20 s.
SHORT_LEASE_XML = """<?xml version="1.0" encoding="UTF-8" ?>
<profiles xmlns="http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles">
  <participant profile_name="short_lease" is_default_profile="true">
    <rtps><builtin><discovery_config>
      <leaseDuration><sec>2</sec></leaseDuration>
      <leaseAnnouncement><sec>0</sec><nanosec>500000000</nanosec></leaseAnnouncement>
    </discovery_config></builtin></rtps>
  </participant>
</profiles>
"""


def short_lease_profile(folder: Path) -> Path:
    """Write :data:`SHORT_LEASE_XML` into ``folder``; the path, for a child process's
    ``FASTRTPS_DEFAULT_PROFILES_FILE`` (a test of a killed peer need not wait 20 s)."""
    path = folder / "short_lease.xml"
    path.write_text(SHORT_LEASE_XML)
    return path


def executable(package: str, name: str) -> Path:
    """Where ``ros2 run package name`` finds its program."""
    path = INSTALL / package / "lib" / package / name
    assert path.exists(), f"{path} missing: build the workspace (scripts/setup.sh)"
    return path


class Peer:
    """A plain rclpy node in a context of its own: another DDS participant."""

    def __init__(self, domain_id: int, name: str = "peer") -> None:
        self.context = Context()
        rclpy.init(context=self.context, domain_id=domain_id)
        self.node = Node(name, context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)

    def wait_for(
        self,
        predicate: Callable[[], bool],
        timeout_s: float = 15.0,
        *,
        also: Callable[[float], None] | None = None,
    ) -> bool:
        """Spin this peer (and ``also``, e.g. a container's spin_once) until ``predicate``."""
        end = time.monotonic() + timeout_s
        while not predicate():
            if time.monotonic() > end:
                return False
            self.executor.spin_once(timeout_sec=0.01)
            if also is not None:
                also(0.005)
        return True

    def close(self) -> None:
        self.executor.shutdown()
        self.node.destroy_node()
        self.context.try_shutdown()


@contextmanager
def peer(domain_id: int, name: str = "peer") -> Iterator[Peer]:
    p = Peer(domain_id, name)
    try:
        yield p
    finally:
        p.close()


@contextmanager
def child(
    args: Sequence[str | Path], *, domain_id: int, log: Path
) -> Iterator[subprocess.Popen[bytes]]:
    """A child process in its own session, killed with its group on exit."""
    with open(log, "wb") as out:
        proc = subprocess.Popen(
            [str(a) for a in args],
            env=ros_env(domain_id),
            stdout=out,
            stderr=subprocess.STDOUT,
            start_new_session=True,
        )
        try:
            yield proc
        finally:
            stop_process_group(proc)


def wait_until(
    predicate: Callable[[], bool], proc: subprocess.Popen[bytes], timeout_s: float = 30.0
) -> bool:
    """Poll ``predicate`` (a line in a child's log, say) until it holds, the child exits or
    ``timeout_s`` passes."""
    end = time.monotonic() + timeout_s
    while not predicate():
        if proc.poll() is not None or time.monotonic() > end:
            return predicate()
        time.sleep(0.02)
    return True
