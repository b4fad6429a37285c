"""A simulated team network for the clock-sync exchange, to test it in one process.

Each simulated robot's :class:`~team_clock.sync.ClockSync` is remapped (see
:func:`sim_remappings`) so that its pings and pongs go to its own topics. A
:class:`SimNetwork` component carries them to the robots it is linked with, each message
after its own random delay (so the two directions of a round trip differ, as on a real
radio link) and with a given loss probability. Robots that are not linked never hear each
other: a robot two links away from the reference must synchronise through the one between.

    container = test_container()
    net = container.add(lambda node: SimNetwork(node, links=[("ref", "a"), ("a", "b")],
                                                delay=SimDelay(min_s=0.001, jitter_s=0.002),
                                                loss=0.2, seed=1), name="net")
    for robot, clock in clocks.items():
        container.add(partial(ClockSync, local_clock=clock), name="clock_sync",
                      namespace=f"/{robot}", remappings=sim_remappings(robot),
                      parameters={"reference": "ref"})
    container.advance(30.0)

Delays need the container's executor to run timers, which a manual clock does exactly.
:class:`SimTeam` wires all of this for a dict of robots and their clock skews::

    team = SimTeam({"ref": (0, 0.0), "a": (250_000_000, 50.0)}, reference="ref",
                   links=[("ref", "a")], loss=0.2)
    team.advance(30.0)
    assert abs(team.error_ns("a")) <= team.uncertainty_ns("a")

To test alignment end to end, :meth:`SimTeam.record_flashes` has every robot log, on its
own clock, its clock estimates and "flash" events that all robots see at one true instant
(:class:`SimLogger`); :func:`flash_times` reads the events back from a log or merged log.
"""

from __future__ import annotations

import random
from collections import Counter, defaultdict
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from functools import partial
from pathlib import Path
from typing import Any

from geometry_msgs.msg import PointStamped
from rclpy.serialization import deserialize_message, serialize_message

from efficient_comm import Container, ManualClock, from_msg, to_msg
from efficient_comm.handle import Clock, NodeHandle, Timer
from efficient_comm.testing import TestHandle, test_container
from team_clock_interfaces.msg import ClockOffset, TimeSyncPing, TimeSyncPong

from .bag import BagWriter, LogReader
from .clocks import SkewedClock
from .sync import EXCHANGE_QOS, OFFSET_QOS, OFFSET_TOPIC, PING_TOPIC, PONG_TOPIC, ClockSync

__all__ = ["EVENT_TOPIC", "FLASH_TOPIC", "SimDelay", "SimLogger", "SimNetwork", "SimTeam",
           "flash_times", "sim_remappings"]

#: Where the simulated "flashes" (events every robot sees at once) are published.
FLASH_TOPIC = "/flash"
#: The topic a :class:`SimLogger` logs each flash under, stamped with its robot's clock.
EVENT_TOPIC = "/event"


def sim_remappings(robot: str) -> dict[str, str]:
    """Remappings that put ``robot``'s exchange on the simulated network's topics."""
    return {
        PING_TOPIC: f"/sim_net/{robot}/ping",
        PONG_TOPIC: f"/sim_net/{robot}/pong",
        OFFSET_TOPIC: f"/{robot}{OFFSET_TOPIC}",
    }


@dataclass(frozen=True, slots=True)
class SimDelay:
    """One-way delay: ``min_s`` plus an exponentially distributed queueing delay."""

    min_s: float = 0.001
    jitter_s: float = 0.002

    def draw(self, rng: random.Random) -> float:
        return self.min_s + (rng.expovariate(1.0 / self.jitter_s) if self.jitter_s > 0 else 0.0)


class SimNetwork:
    """Carries pings and pongs between linked robots with delay and loss (see module doc)."""

    def __init__(
        self,
        node: NodeHandle,
        *,
        links: Iterable[tuple[str, str]],
        delay: SimDelay | None = None,
        loss: float = 0.0,
        seed: int = 0,
    ) -> None:
        if not 0.0 <= loss < 1.0:
            raise ValueError(f"loss must be in [0, 1), got {loss}")
        self._node = node
        self._delay = delay or SimDelay()
        self._loss = loss
        self._rng = random.Random(seed)
        self.neighbours: dict[str, set[str]] = defaultdict(set)
        for a, b in links:
            self.neighbours[a].add(b)
            self.neighbours[b].add(a)
        #: Messages delivered, dropped (lost on a link), in flight.
        self.counts: Counter[str] = Counter()
        self._pubs: dict[tuple[str, str], Any] = {}
        for robot in self.neighbours:
            for kind, msg_type in (("ping", TimeSyncPing), ("pong", TimeSyncPong)):
                topic = f"/sim_net/{robot}/{kind}"
                self._pubs[robot, kind] = node.create_publisher(msg_type, topic, qos=EXCHANGE_QOS)
                node.create_subscription(msg_type, topic, self._handler(robot, kind),
                                         qos=EXCHANGE_QOS)

    def cut(self, a: str, b: str) -> None:
        """Break the link between ``a`` and ``b`` (messages in flight still arrive)."""
        self.neighbours[a].discard(b)
        self.neighbours[b].discard(a)

    def _handler(self, robot: str, kind: str) -> Callable[[Any], None]:
        return lambda msg: self._on_message(robot, kind, msg)

    def _on_message(self, robot: str, kind: str, msg: Any) -> None:
        sender = msg.client if kind == "ping" else msg.server
        if sender != robot:
            return  # a message this network delivered to `robot`, not one it sent
        for other in sorted(self.neighbours[robot]):
            if self._rng.random() < self._loss:
                self.counts["lost"] += 1
                continue
            self._deliver_later(self._pubs[other, kind], msg, self._delay.draw(self._rng))

    def _deliver_later(self, pub: Any, msg: Any, delay_s: float) -> None:
        self.counts["in_flight"] += 1
        timer: list[Timer] = []

        def fire() -> None:
            self._node.destroy_timer(timer[0])
            self.counts["in_flight"] -= 1
            self.counts["delivered"] += 1
            pub.publish(msg)

        timer.append(self._node.create_timer(delay_s, fire))


class SimTeam:
    """Robots with skewed clocks running :class:`ClockSync` over a :class:`SimNetwork`.

    ``skews`` maps each robot to ``(offset_ns, drift_ppm)`` of its clock against the true
    (simulated) time; the reference robot's clock defines team time, so the truth a robot's
    estimate is checked against is the reference's clock reading, not the true time.
    Everything runs in one test container on a manual clock starting at ``start_ns``.
    """

    def __init__(
        self,
        skews: Mapping[str, tuple[int, float]],
        *,
        reference: str,
        links: Iterable[tuple[str, str]],
        delay: SimDelay | None = None,
        loss: float = 0.0,
        seed: int = 0,
        period_s: float = 0.5,
        start_ns: int = 1_700_000_000_000_000_000,
        container: Container | None = None,
    ) -> None:
        self.container = container or test_container()
        clock = self.container.executor.clock
        if not isinstance(clock, ManualClock):
            raise TypeError("a simulated team needs a container on a ManualClock")
        self.clock = clock
        if clock.now_ns() < start_ns:
            clock.set_ns(start_ns)
        epoch = clock.now_ns()
        self.reference = reference
        self.net: SimNetwork = self.container.add(
            partial(SimNetwork, links=links, delay=delay, loss=loss, seed=seed), name="sim_net"
        )
        self.clocks = {robot: SkewedClock(clock, offset_ns=offset, drift_ppm=drift, epoch_ns=epoch)
                       for robot, (offset, drift) in skews.items()}
        self.syncs: dict[str, ClockSync] = {
            robot: self.container.add(
                partial(ClockSync, local_clock=local), name="clock_sync", namespace=f"/{robot}",
                remappings=sim_remappings(robot),
                parameters={"reference": reference, "period_s": period_s},
            )
            for robot, local in self.clocks.items()
        }

    def advance(self, seconds: float) -> None:
        self.container.advance(seconds)

    def reference_now(self) -> int:
        """Team time now: the reference robot's clock."""
        return self.clocks[self.reference].now_ns()

    def error_ns(self, robot: str) -> int | None:
        """``robot``'s estimated team time minus the true team time now (None: no estimate)."""
        state = self.syncs[robot].state
        if state is None:
            return None
        return state.estimate.to_reference(self.clocks[robot].now_ns()) - self.reference_now()

    def uncertainty_ns(self, robot: str) -> int | None:
        state = self.syncs[robot].state
        if state is None:
            return None
        return state.estimate.uncertainty_at(self.clocks[robot].now_ns())

    def record_flashes(self, directory: Path, *, events: int, seed: int = 0,
                       warm_up_s: float = 10.0) -> tuple[dict[str, Path], dict[str, int]]:
        """Every robot logs to ``directory/log_<robot>`` while ``events`` flashes happen.

        After ``warm_up_s`` (the first estimates), a flash every 0.3-0.7 s; returns the
        logs and each flash's true team time (the reference's clock at that instant).
        """
        paths = {robot: Path(directory) / f"log_{robot}" for robot in self.clocks}
        loggers: list[SimLogger] = [
            self.container.add(partial(SimLogger, clock=self.clocks[robot], robot=robot,
                                       path=path), name="logger", namespace=f"/{robot}")
            for robot, path in paths.items()
        ]
        flash = TestHandle("flash", container=self.container)
        rng = random.Random(seed)
        truth: dict[str, int] = {}
        self.advance(warm_up_s)
        for k in range(events):
            self.advance(0.3 + rng.random() * 0.4)
            msg = PointStamped()
            msg.header.frame_id = f"e{k}"
            flash.inject(FLASH_TOPIC, msg)  # every robot sees it now, at one true instant
            truth[msg.header.frame_id] = self.reference_now()
        self.advance(2.0)
        for logger in loggers:
            logger.writer.close()
        return paths, truth


class SimLogger:
    """What a robot's recorder does, on the robot's own clock: log estimates and flashes.

    The estimates go to ``/team_clock/offset`` (read from the robot's remapped offset
    topic), each flash to ``/event`` as a ``PointStamped`` whose ``frame_id`` names it and
    whose stamp is the robot's clock, as a sensor would stamp it.
    """

    def __init__(self, node: NodeHandle, *, clock: Clock, robot: str, path: Path) -> None:
        self._clock = clock
        self.writer = BagWriter(path, min_free_bytes=0, library="team_clock")
        self._offsets = self.writer.add_topic(OFFSET_TOPIC,
                                              "team_clock_interfaces/msg/ClockOffset")
        self._events = self.writer.add_topic(EVENT_TOPIC, "geometry_msgs/msg/PointStamped")
        node.create_subscription(ClockOffset, f"/{robot}{OFFSET_TOPIC}", self._on_offset,
                                 qos=OFFSET_QOS)
        node.create_subscription(PointStamped, FLASH_TOPIC, self._on_flash)

    def _on_offset(self, msg: ClockOffset) -> None:
        self.writer.write(self._offsets.name, self._offsets.type, serialize_message(msg),
                          self._clock.now_ns())

    def _on_flash(self, flash: PointStamped) -> None:
        now = self._clock.now_ns()
        event = PointStamped()
        event.header.frame_id = flash.header.frame_id
        event.header.stamp = to_msg(now)
        self.writer.write(self._events.name, self._events.type, serialize_message(event), now)


def flash_times(path: Path) -> dict[str, dict[str, tuple[int, int]]]:
    """``{namespace: {flash: (log time, header stamp)}}`` of a log ("" for a robot's own)."""
    out: dict[str, dict[str, tuple[int, int]]] = {}
    for _, channel, message in LogReader(Path(path)).records():
        if channel.topic.endswith(EVENT_TOPIC):
            event = deserialize_message(message.data, PointStamped)
            stamp = from_msg(event.header.stamp)
            namespace = channel.topic.removesuffix(EVENT_TOPIC).strip("/")
            out.setdefault(namespace, {})[event.header.frame_id] = (message.log_time, stamp)
    return out
