"""Test doubles for components: a node handle with no DDS, on a manual clock.

Write tests of your components without launch_testing, DDS or sleeps::

    from efficient_comm.testing import TestHandle

    def test_talker_publishes_at_its_rate():
        node = TestHandle("talker", parameters={"rate_hz": 10.0})
        Talker(node)
        node.advance(1.0)                      # fires the timer ten times
        assert len(node.published("chatter")) == 10

    def test_echo():
        node = TestHandle("echo")
        Echo(node)
        node.inject("in", String(data="hi"))   # delivered at once (depth-first)
        assert node.published("out")[0].data == "hi"

A :class:`TestHandle` is a composed handle on a container without DDS, so components
behave exactly as in a real container (by-reference delivery, QoS depth, transient local,
parameters, services). Several handles can share one container (``container=``) to test
components together. The mutation guard is on and raises, so a component that modifies a
message it received fails its test.

:func:`unique_topic` and :func:`isolated_domain_id` keep tests that do use DDS apart.
"""

from __future__ import annotations

import contextlib
import itertools
import os
import random
import signal
import subprocess
import uuid
from collections import deque
from collections.abc import Mapping
from typing import Any

from ._clock import ManualClock
from ._qos import latched_qos
from .bus import LocalPublisher
from .composed import ComposedHandle, RecordingLogger
from .container import Container
from .dds import _MARK, PROFILES_ENV, remove_stale_shm_ports
from .executor import GuardMode, Strategy
from .handle import QoSLike
from .stats import CallbackStats
from .stats_publisher import DEFAULT_STATS_PERIOD_S

__all__ = [
    "ManualClock",
    "TestHandle",
    "isolated_domain_id",
    "ros_env",
    "stop_process_group",
    "test_container",
    "unique_topic",
]

#: How many ids domain_coordinator hands out (1..100).
DOMAIN_IDS = 100
_INJECT_QOS = latched_qos()


def test_container(
    *,
    strategy: Strategy = "depth_first",
    guard_mutation: GuardMode = "raise",
    stats_period_s: float = DEFAULT_STATS_PERIOD_S,
    stats_namespace: str = "/",
) -> Container:
    """A container with no DDS on a :class:`ManualClock` starting at t = 0.

    Like every container it publishes its callback statistics (``stats_period_s``, 0 turns
    that off), so a test can subscribe to ``<stats_namespace>/efficient_comm/stats``.
    """
    return Container(
        f"test_{uuid.uuid4().hex[:8]}",
        dds=False,
        clock=ManualClock(),
        strategy=strategy,
        guard_mutation=guard_mutation,
        serve=False,
        stats_period_s=stats_period_s,
        stats_namespace=stats_namespace,
    )


test_container.__test__ = False  # type: ignore[attr-defined]  # not a pytest test


class TestHandle(ComposedHandle):
    """A node handle for unit tests: inject messages, advance time, read what was published."""

    __test__ = False  # not a pytest test class

    def __init__(
        self,
        name: str = "node_under_test",
        *,
        namespace: str = "/",
        parameters: Mapping[str, Any] | None = None,
        remappings: Mapping[str, str] | None = None,
        container: Container | None = None,
    ) -> None:
        super().__init__(
            container or test_container(),
            name=name,
            namespace=namespace,
            remappings=remappings or {},
            parameters=parameters or {},
        )
        self._recorded: dict[str, list[Any]] = {}
        self._injectors: dict[str, LocalPublisher] = {}

    @property
    def records(self) -> list[tuple[str, str]]:
        """``(level, message)`` of everything this node logged."""
        assert isinstance(self.logger, RecordingLogger)
        return list(self.logger.records)

    def create_publisher(
        self, msg_type: type, topic: str, *, qos: QoSLike = 10
    ) -> LocalPublisher:
        pub = super().create_publisher(msg_type, topic, qos=qos)
        self._tap(pub.topic_name, msg_type)
        return pub

    def _tap(self, name: str, msg_type: type) -> None:
        if name in self._recorded:
            return
        store: list[Any] = []
        self._recorded[name] = store
        self.container.bus.add_observer(
            name,
            msg_type,
            store.append,
            stats=CallbackStats("<test>", "subscription", name),
            logger=self.logger,
        )

    def published(self, topic: str) -> list[Any]:
        """Every message published on ``topic`` (resolved like the node's own names).

        Only topics this handle created a publisher on are recorded; asking for another
        raises LookupError rather than answering an empty list that would pass a test.
        """
        name = self.resolve_topic_name(topic)
        if name not in self._recorded:
            raise LookupError(
                f"{self.fully_qualified_name} has no publisher on {name}; it publishes on "
                f"{sorted(self._recorded) or 'nothing'}"
            )
        return list(self._recorded[name])

    def clear_published(self) -> None:
        for store in self._recorded.values():
            store.clear()

    def inject(self, topic: str, *msgs: Any) -> None:
        """Publish ``msgs`` on ``topic`` as if from another node, then run what is ready."""
        name = self.resolve_topic_name(topic)
        injector = self._injectors.get(name)
        if injector is None:
            msg_type = type(msgs[0])
            injector = self.container.bus.add_publisher(
                name, msg_type, _INJECT_QOS, owner="<test>"
            )
            self._injectors[name] = injector
        for msg in msgs:
            injector.publish(msg)
        self.spin_some()

    def spin_some(self) -> None:
        """Run every queued callback (what breadth-first delivery left behind)."""
        self.container.executor.advance(0.0)

    def advance(self, seconds: float) -> None:
        """Move the manual clock, firing every timer that falls due."""
        self.container.executor.advance(seconds)

    def now_ns(self) -> int:
        return self.container.executor.clock.now_ns()


#: Reservations a process keeps: older ones are released (their tests are long over).
KEEP_RESERVED = 16
_reserved: deque[contextlib.ExitStack] = deque()
# Each process walks the ids from a random start, so an id is not reused right after a
# test's peers left it (a killed DDS participant stays in discovery for its lease time).
_next_candidate = itertools.count(random.randrange(DOMAIN_IDS))


def isolated_domain_id() -> int:
    """A ROS domain id (1..100) reserved for this process, so no concurrent test gets it.

    Reserved through ``domain_coordinator`` (ament_cmake_ros's, what launch_testing uses):
    it holds a local port per id, so every process that reserves this way (every test
    process here, running in parallel or not) gets a different id. Deriving ids from the
    pid, as this did before, let two processes collide. The reservation lasts until this
    process has made :data:`KEEP_RESERVED` newer ones, or ends. The domain comes without the
    half-made shared-memory port segments a killed process may have left in it
    (:func:`efficient_comm.dds.remove_stale_shm_ports`), on which a participant would hang.
    """
    from domain_coordinator import domain_id  # type: ignore[import-untyped]

    stack = contextlib.ExitStack()
    domain = int(stack.enter_context(
        domain_id(selector=lambda: next(_next_candidate) % DOMAIN_IDS + 1)
    ))
    # A peer an earlier test killed may have left a half-made port segment of this domain,
    # on which the next participant would hang (see remove_stale_shm_ports).
    remove_stale_shm_ports(domain)
    _reserved.append(stack)
    while len(_reserved) > KEEP_RESERVED:
        _reserved.popleft().close()
    return domain


def unique_topic(prefix: str = "t") -> str:
    """A fresh absolute topic name, so tests never hear each other."""
    return f"/{prefix}_{uuid.uuid4().hex[:12]}"


def stop_process_group(
    proc: subprocess.Popen[Any], *, sig: int = signal.SIGINT, timeout_s: float = 10.0
) -> int:
    """End a process started with ``start_new_session=True`` and everything it started:
    ``sig`` to its group (SIGINT, so ROS programs shut down as on Ctrl-C), then SIGKILL
    after ``timeout_s`` (rclpy traps SIGTERM; a stuck child must not outlive the test).
    Returns its exit status."""
    if proc.poll() is None:
        os.killpg(proc.pid, sig)
        try:
            proc.wait(timeout=timeout_s)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    return proc.returncode


def ros_env(domain_id: int, base: Mapping[str, str] | None = None) -> dict[str, str]:
    """Environment for a subprocess that must join ``domain_id`` on loopback only."""
    env = dict(os.environ if base is None else base)
    env["ROS_DOMAIN_ID"] = str(domain_id)
    env.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    if _MARK in env.get(PROFILES_ENV, ""):
        del env[PROFILES_ENV]  # the child decides for itself whether it composes
    return env
