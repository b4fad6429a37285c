"""Simulated time from another process: ``/clock``, and the lockstep barrier's two ends.

A simulator that runs the robots' software in processes of their own (one per robot, as
separate computers) publishes the simulated time on ``/clock`` (``rosgraph_msgs/Clock``),
as Gazebo and MuJoCo bridges do for ROS nodes with ``use_sim_time``. A container started
with ``sim_time=True`` follows it: its clock is a :class:`~efficient_comm.SimClock`, its
timers fire in simulated time (each at its own deadline, as on a manual clock), and every
handle's ``clock_kind`` is ``"sim"``. Following ``/clock`` alone does not wait for anyone:
a slow robot falls behind the world. Lockstep does not let it.

**The barrier.** A container started with ``lockstep="<participant>"`` is a participant;
the world drives all of them with a :class:`StepCoordinator`. Each step from ``t`` to
``t + dt`` is two rounds, each acknowledged by every expected participant before the next
begins (``std_msgs/Header`` on ``/efficient_comm/lockstep/<participant>``: ``stamp`` the
time, ``frame_id`` the round)::

    world (coordinator)                         every participant
    ------------------------------------------------------------------------------------
    publish /efficient_comm/lockstep/intake t ─▶ take everything DDS holds into the inbox
                                  ◀── "intake" t    (no callback runs)
    publish /clock t + dt ───────────────────▶ deliver the inbox; run every timer due up
                                                to t + dt, each at its deadline, with the
                                                in-process messages it causes; wait until
                                                every reliable DDS reader has acknowledged
                                                what this step wrote (wait_for_all_acked)
                                  ◀── "step" t + dt

**Why two rounds.** Messages between processes must reach their receivers before the next
step starts, and only the messages of the steps before: a receiver that took a message
while the sender already ran the next step would see it one step early or late depending
on the load, and the run would not repeat. The step round's acknowledgement comes after
``wait_for_all_acked`` on every DDS writer of the participant, so when the coordinator has
every "step" acknowledgement, every message of that step is in its readers' DDS caches.
The intake round then moves exactly those into each receiver's inbox; nobody runs (or
publishes) during it, so nothing of the next step can slip in. Messages from other
processes are held from arrival until an intake (as many as the reader's QoS depth keeps),
never delivered mid-step, and an inbox is
delivered topic by topic (sorted by name; each topic's messages in arrival order), so the
order does not depend on which DDS reader the wait set happened to report first. A message
thus crosses a process boundary in exactly one step, like a wire with a unit delay.

What the guarantee covers: reliable topics whose DDS endpoints have matched before the
first step (a volatile writer drops what it writes before discovery; wait for your peers,
then ``spin``: a participant joins when its container first spins). Best-effort topics
are delivered when DDS delivers them (there is nothing to wait for, as on a lossy link).
A topic with several remote publishers gets their messages in arrival order (per publisher
in publication order). Services and parameter requests from outside are not part of the
barrier. The world's own DDS messages (sensors) are covered when the world passes its
container to the coordinator (flushed before each intake, and what the robots sent is taken
after each step).

**One round.** A coordinator with one participant (each robot on a DDS domain of its own,
as in the team match) skips the intake round: the participant takes its inbox when
``/clock`` arrives, before it runs the step. That is exact because nobody else in the
barrier publishes on its domain: the coordinator's process flushed what it wrote before
``/clock``, and there is no second participant that could already be publishing the next
step. It saves a round trip between the processes each step, which on a loaded machine
is a wait for the scheduler on each side. The participant tells the two apart by itself:
a ``/clock`` for a step whose start it has not taken in is a one-round step.

**Links outside DDS.** A participant that also sends on a link of its own (rf_bridge's
Zenoh team link) makes that link's delivery repeat too: it reports how many messages it
has put on the link (:meth:`LockstepParticipant.report`, cumulative counters carried in
its "step" acknowledgement), the coordinators relay every participant's counters after
each step (:data:`COUNTS_TOPIC`, stamped with the step's end, published before the next
``/clock``), and a receiver waits at the start of a step until it holds what the counters
say is due (:meth:`LockstepParticipant.counts_at`, :meth:`LockstepParticipant.at_step_start`).
The barrier then knows what crossed such a link, though only the link carries it.

**Failures.** The coordinator never waits forever: a participant that does not acknowledge
within ``timeout_s`` raises :class:`~efficient_comm.LockstepError` naming it, and one whose
process died is noticed earlier through DDS liveliness on its acknowledgement topic (lease
:data:`LIVELINESS_LEASE_S`) and named as gone.
"""

from __future__ import annotations

import json
import time
from collections import deque
from collections.abc import Callable, Iterable, Mapping, Sequence
from functools import partial
from typing import TYPE_CHECKING, Any, Literal

import rclpy
from rclpy.context import Context
from rclpy.duration import Duration
from rclpy.event_handler import QoSLivelinessChangedInfo, SubscriptionEventCallbacks
from rclpy.executors import ShutdownException, SingleThreadedExecutor, TimeoutException
from rclpy.qos import (
    DurabilityPolicy,
    HistoryPolicy,
    LivelinessPolicy,
    QoSProfile,
    ReliabilityPolicy,
)
from rosgraph_msgs.msg import Clock as ClockMsg
from std_msgs.msg import Header

from ._clock import SimClock, from_msg, to_msg
from ._closing import Closing
from ._qos import latched_qos
from ._reader_wait import ReaderWait
from .dds import prepare_process
from .errors import ConfigError, LockstepError
from .executor import matched_publishers, take_samples

if TYPE_CHECKING:
    from .container import Container

__all__ = [
    "CLOCK_TOPIC",
    "COUNTS_TOPIC",
    "INTAKE_TOPIC",
    "LIVELINESS_LEASE_S",
    "LockstepParticipant",
    "StepCoordinator",
    "ack_topic",
    "advance_together",
    "follow_clock",
]

CLOCK_TOPIC = "/clock"
INTAKE_TOPIC = "/efficient_comm/lockstep/intake"
#: Every participant's counters after a step (``frame_id``: JSON ``{name: count}``).
COUNTS_TOPIC = "/efficient_comm/lockstep/counts"
_ACK_PREFIX = "/efficient_comm/lockstep/"
#: A participant whose process is gone for this long is reported as gone.
LIVELINESS_LEASE_S = 2.0
#: The coordinator looks at its liveliness events at least this often while it waits.
EVENTS_PERIOD_S = 0.25

Round = Literal["ready", "intake", "step"]


def ack_topic(participant: str) -> str:
    """Where ``participant`` acknowledges rounds (one topic each: liveliness names it)."""
    return _ACK_PREFIX + participant


def _step_qos() -> QoSProfile:
    """/clock and intake in lockstep: reliable, and the latest one reaches a late joiner."""
    return latched_qos()


def _ack_qos() -> QoSProfile:
    qos = _step_qos()
    qos.liveliness = LivelinessPolicy.AUTOMATIC
    qos.liveliness_lease_duration = Duration(seconds=LIVELINESS_LEASE_S)
    return qos


#: A follower of /clock without lockstep: best effort, volatile, so it matches any time
#: source (Gazebo's bridge publishes best effort; rclpy's own TimeSource reads it so too).
_FOLLOW_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1,
                         reliability=ReliabilityPolicy.BEST_EFFORT,
                         durability=DurabilityPolicy.VOLATILE)


def check_participant_name(name: str) -> str:
    """A participant name must be one topic-name token (``blue1``, ``world_2``)."""
    if not name or not (name[0].isalpha() and all(c.isalnum() or c == "_" for c in name)):
        raise ConfigError(
            f"lockstep participant name {name!r} must start with a letter and hold only "
            "letters, digits and '_' (it is part of a topic name)"
        )
    return name


def follow_clock(node: Any, clock: SimClock, *, reliable: bool) -> Any:
    """Subscribe ``node`` (an rclpy node) to ``/clock``, feeding ``clock``.

    The callback only records the time: the executor advances to it between callbacks
    (:class:`~efficient_comm.executor.ConsecutiveExecutor`), so timers fire in order.
    """

    def on_clock(msg: ClockMsg) -> None:
        clock.receive(from_msg(msg.clock))

    return node.create_subscription(
        ClockMsg, CLOCK_TOPIC, on_clock, _step_qos() if reliable else _FOLLOW_QOS
    )


class LockstepParticipant:
    """The participant's end of the barrier, inside a container (see the module docstring).

    The container's executor calls :meth:`done_intake` and :meth:`done_step`; the
    container calls :meth:`join` when it first spins (``Container.spin``; a program with a
    loop of its own, ``spin_for`` and printing, calls ``container.lockstep.join()``).
    """

    def __init__(self, container: Container, name: str, *, clock: SimClock,
                 flush_timeout_s: float) -> None:
        if container.context is None:
            raise ConfigError(f"container {container.name}: lockstep needs DDS (dds=True)")
        self.name = check_participant_name(name)
        self._container = container
        self._flush_timeout_s = flush_timeout_s
        # The barrier's own node and wait set (see wait()).
        self._node = rclpy.create_node(f"lockstep_{name}", context=container.context,
                                       enable_rosout=False, start_parameter_services=False)
        node = self._node
        self._ack = node.create_publisher(Header, ack_topic(name), _ack_qos())
        self._intake_sub = node.create_subscription(
            Header, INTAKE_TOPIC, self._on_intake, _step_qos()
        )
        clock_sub = follow_clock(node, clock, reliable=True)
        self._wake = node.create_guard_condition(lambda: None)
        self._waiter = ReaderWait(container.context, (self._intake_sub, clock_sub),
                                  guard=self._wake)
        #: The time of an intake round asked for and not yet done (the executor does it).
        self.intake_due: int | None = None
        #: The time of the last intake done (asked for, or implied by a one-round step).
        self.last_intake_ns = -1
        self._last_intake = -1
        self.joined = False
        self._counters: dict[str, Callable[[], int]] = {}
        self._hooks: list[Callable[[int], None]] = []
        self._counts: deque[tuple[int, dict[str, int]]] = deque(maxlen=10_000)
        self._counts_sub: Any = None
        self._last_step_ns = -1
        self._live: set[Any] = set()  # DDS readers asked at every intake (see take)

    def report(self, name: str, count: Callable[[], int]) -> Callable[[], None]:
        """Carry ``count()`` (messages sent so far on a link outside DDS) in every step
        acknowledgement as ``name``; every participant then reads it in :meth:`counts_at`.
        Returns a function that stops reporting it."""
        self._counters[name] = count
        self._subscribe_counts()

        def remove() -> None:
            self._counters.pop(name, None)

        return remove

    def at_step_start(self, hook: Callable[[int], None]) -> Callable[[], None]:
        """Call ``hook(start_ns)`` on the executor's thread at the start of every step,
        after the DDS inbox is delivered and before any timer runs. Returns its remover."""
        self._hooks.append(hook)
        self._subscribe_counts()

        def remove() -> None:
            if hook in self._hooks:
                self._hooks.remove(hook)

        return remove

    def step_started(self, start_ns: int) -> None:
        for hook in list(self._hooks):
            hook(start_ns)

    def _subscribe_counts(self) -> None:
        if self._counts_sub is None:
            qos = _step_qos()
            qos.depth = 1000
            self._counts_sub = self._node.create_subscription(
                Header, COUNTS_TOPIC, self._on_counts, qos)
            self._waiter.add(self._counts_sub)

    def _on_counts(self, msg: Header) -> None:
        t = from_msg(msg.stamp)
        if not self._counts or t > self._counts[-1][0]:
            self._counts.append((t, json.loads(msg.frame_id)))

    def counts_at(self, t_ns: int, *, timeout_s: float) -> dict[str, int] | None:
        """Every participant's counters as of the end of the latest step that ended by
        ``t_ns`` (empty before the first; call it from a participant that reports counters
        of its own, so that the coordinator relays some after each step); waits (on the
        barrier's own wait set) until the coordinator's counters of a step ending at
        ``t_ns`` or later came. None if they did not within ``timeout_s``."""
        # Counters come for every step this participant acknowledged (it reports some
        # itself): none before the first, none yet for a step it has not run.
        wanted = min(t_ns, self._last_step_ns)
        if wanted < 0:
            return {}
        deadline = time.monotonic() + timeout_s
        while not self._counts or self._counts[-1][0] < wanted:
            left = deadline - time.monotonic()
            if left <= 0:
                return None
            self._waiter.wait(min(left, 0.5))
        best: dict[str, int] = {}
        for t, counts in self._counts:
            if t > t_ns:
                break
            best = counts
        while len(self._counts) > 1 and self._counts[1][0] <= t_ns:
            self._counts.popleft()  # older than what any later step asks for
        return best

    def _on_intake(self, msg: Header) -> None:
        t = from_msg(msg.stamp)
        if t > self._last_intake:  # a transient-local replay of an old round is ignored
            self._last_intake = t
            self.intake_due = t

    def join(self) -> None:
        """Tell the coordinator this participant is ready (idempotent)."""
        if not self.joined:
            self.joined = True
            self._send("ready", self._container.executor.clock.now_ns())

    def wait(self, timeout_s: float) -> None:
        """Wait up to ``timeout_s`` for the coordinator's next round (intake or ``/clock``).

        The barrier's subscriptions have a node and a wait set of their own, kept for the
        participant's life (:class:`~efficient_comm._reader_wait.ReaderWait`): the
        container's wait set holds every component's node (each with its DDS readers,
        parameter services and events), and building it is milliseconds of Python; a step
        waited on it twice and took its inbox through it, so the barrier, not the robot's
        work, was most of a robot's CPU in lockstep. Everything else on DDS is taken
        directly at intake (:meth:`take`) or polled now and then by the executor.
        """
        self._waiter.wait(timeout_s)

    def wake(self) -> None:
        """End a :meth:`wait` early (another thread queued work for the executor)."""
        self._wake.trigger()

    def take(self) -> int:
        """Take every sample the container's DDS readers hold (the intake round), without
        a wait set: each reader of a composed subscription is asked until it is empty, and
        its samples go where its callback puts them (held for the step); then every chunk
        shared memory holds (iceoryx2's send has put it into the reader's queue when it
        returns, so what a peer sent in the step is there). Returns how many DDS samples.

        Most of a container's readers never hear anything: each composed subscription has
        a DDS reader for publishers outside the process (a lockstep robot had 84, 7 of
        them with a publisher), and asking an empty one for a sample costs 14 µs in a busy
        process (rclpy builds and frees a message for it), a fifth of the robot's CPU;
        asking for its matched publishers costs 3 µs. So a reader is taken from once it is
        *live* (a publisher is or was matched with it), and the others are only asked for
        their publishers. A publisher is matched before its first sample arrives, so every
        message of a live peer is taken at the same step as before, and runs repeat. What a
        publisher gone before the reader was asked left in it (``ros2 topic pub --once``)
        is taken by the executor's DDS poll between steps (a wait on every reader) and
        delivered at the next step.
        """
        live = self._live
        readers = self._container.bus.dds_readers()
        if len(live) > len(readers):  # components unloaded: forget their readers
            live.intersection_update(readers)
        taken = 0
        for reader in readers:
            if reader not in live:
                if not matched_publishers(reader):
                    continue
                live.add(reader)
            taken += take_samples(reader)
        if self._container.shm is not None:  # chunks are sent before the step ends too
            self._container.shm.drain()
        return taken

    def done_intake(self, t_ns: int) -> None:
        self._send("intake", t_ns)

    def done_step(self, t_ns: int) -> None:
        """Acknowledge a step once every reliable reader has what it wrote (see above)."""
        late = self._container.flush_dds(timeout_s=self._flush_timeout_s)
        if late:
            self._container.logger.error(
                f"lockstep step to {t_ns / 1e9:.3f} s: DDS readers of {', '.join(late)} did "
                f"not acknowledge within {self._flush_timeout_s:g} s (a peer "
                "gone?); acknowledging the step anyway"
            )
        counters = {name: count() for name, count in self._counters.items()}
        self._last_step_ns = t_ns
        self._send("step", t_ns, counters)

    def _send(self, round_: Round, t_ns: int, counters: Mapping[str, int] | None = None
              ) -> None:
        frame = f"{round_} {json.dumps(counters, sort_keys=True)}" if counters else round_
        self._ack.publish(Header(stamp=to_msg(t_ns), frame_id=frame))

    def close(self) -> None:
        self._waiter.close()
        self._node.destroy_node()


class StepCoordinator(Closing):
    """The world's end of the barrier: :meth:`advance` returns when every participant has
    run the step (see the module docstring for the protocol and its guarantee).

        with StepCoordinator(["blue1", "red1"], domain_id=7) as steps:
            steps.wait_ready(timeout_s=30)
            while playing:
                world.step_physics(dt)          # and publish sensors at steps.now_ns
                steps.advance(dt)               # robots ran up to now + dt

    It has a DDS participant of its own (``domain_id``), so it works beside any world.
    ``container`` is the world's own container, if it has one on the same domain: its
    reliable writers are flushed before each intake (the robots then take what the world
    published) and what the robots sent in a step is taken into it after the step.
    """

    def __init__(
        self,
        participants: Iterable[str],
        *,
        domain_id: int | None = None,
        timeout_s: float = 10.0,
        start_ns: int = 0,
        container: Container | None = None,
        name: str = "lockstep_coordinator",
    ) -> None:
        self.participants = tuple(check_participant_name(p) for p in participants)
        if not self.participants:
            raise ConfigError("a step coordinator needs at least one participant")
        if len(set(self.participants)) != len(self.participants):
            raise ConfigError(f"participant names repeat: {list(self.participants)}")
        if not timeout_s > 0:
            raise ConfigError(f"timeout_s must be positive, got {timeout_s!r}")
        self.timeout_s = timeout_s
        self._now = start_ns
        #: One participant: no intake round (see "One round" in the module docstring).
        self.one_round = len(self.participants) == 1
        #: The world's container (see above); may be set after creating the coordinator,
        #: which is best created first (it prepares the process's DDS: efficient_comm.dds).
        self.container = container
        #: Per participant: the last (round, time) it acknowledged, None before any.
        self.acked: dict[str, tuple[str, int] | None] = dict.fromkeys(self.participants)
        self._alive: dict[str, int] = dict.fromkeys(self.participants, 0)
        self._gone: set[str] = set()
        self.steps = 0
        # The process may compose components too; prompt acknowledgements: efficient_comm.dds.
        prepare_process(prompt_acks=True)
        self.context = Context()
        rclpy.init(context=self.context, domain_id=domain_id)
        try:
            self._node = rclpy.create_node(name, context=self.context, enable_rosout=False,
                                           start_parameter_services=False)
            self._clock_pub = self._node.create_publisher(ClockMsg, CLOCK_TOPIC, _step_qos())
            self._intake_pub = self._node.create_publisher(Header, INTAKE_TOPIC, _step_qos())
            counts_qos = _step_qos()
            counts_qos.depth = 1000
            self._counts_pub = self._node.create_publisher(Header, COUNTS_TOPIC, counts_qos)
            #: Per participant: the counters of its last step acknowledgement (see
            #: "Links outside DDS").
            self.counters: dict[str, dict[str, int]] = {}
            acks = tuple(
                self._node.create_subscription(
                    Header, ack_topic(p), partial(self._on_ack, p), _ack_qos(),
                    event_callbacks=SubscriptionEventCallbacks(
                        liveliness=partial(self._on_liveliness, p)
                    ),
                )
                for p in self.participants
            )
            # Acknowledgements through a wait set of their own (see ReaderWait); the
            # executor only for the liveliness events, when a wait brought nothing.
            self._waiter = ReaderWait(self.context, acks)
            self._events_due = 0.0
            self._executor = SingleThreadedExecutor(context=self.context)
            self._executor.add_node(self._node)
        except BaseException:
            self.context.try_shutdown()
            raise

    @property
    def now_ns(self) -> int:
        """The simulated time every participant has run up to."""
        return self._now

    def _on_ack(self, participant: str, msg: Header) -> None:
        round_, _, counters = msg.frame_id.partition(" ")
        if counters:
            self.counters[participant] = json.loads(counters)
        self.acked[participant] = (round_, from_msg(msg.stamp))

    def _on_liveliness(self, participant: str, info: QoSLivelinessChangedInfo) -> None:
        if info.alive_count > 0:
            self._alive[participant] = info.alive_count
            self._gone.discard(participant)
        elif self._alive[participant]:
            self._gone.add(participant)

    def wait_ready(self, *, timeout_s: float | None = None) -> None:
        """Wait until every participant has joined (its container spins); LockstepError
        naming those that did not within ``timeout_s`` (default: the step timeout)."""
        self._wait(lambda ack: ack is not None, "join",
                   self.timeout_s if timeout_s is None else timeout_s)

    def advance(self, dt_s: float) -> int:
        """Step every participant from :attr:`now_ns` by ``dt_s``; returns the new time.

        Blocks until all acknowledged both rounds (slower than real time, never late);
        raises :class:`LockstepError` naming who did not within ``timeout_s``, or is gone.
        """
        return advance_together([self], dt_s)

    def _flush_world(self) -> None:
        if self.container is not None:
            late = self.container.flush_dds(timeout_s=self.timeout_s)
            if late:
                raise LockstepError(f"lockstep: readers of the world's {', '.join(late)} did "
                                    f"not acknowledge within {self.timeout_s:g} s")

    def _start_intake(self) -> None:
        self._intake_pub.publish(Header(stamp=to_msg(self._now), frame_id="intake"))

    def _wait_intake(self) -> None:
        now = self._now
        self._wait(lambda ack: ack == ("intake", now), f"intake at {now / 1e9:.3f} s",
                   self.timeout_s)

    def _start_step(self, target: int) -> None:
        self._clock_pub.publish(ClockMsg(clock=to_msg(target)))

    def _wait_step(self, target: int) -> None:
        self._wait(lambda ack: ack == ("step", target), f"step to {target / 1e9:.3f} s",
                   self.timeout_s)
        self._now = target
        self.steps += 1
        if self.container is not None:
            self.container.take_dds()

    def _wait(self, done: Any, what: str, timeout_s: float) -> None:
        deadline = time.monotonic() + timeout_s
        while True:
            waiting = [p for p in self.participants if not done(self.acked[p])]
            if not waiting:
                return
            gone = sorted(self._gone.intersection(waiting))
            if gone:
                raise LockstepError(
                    f"lockstep {what}: participant {', '.join(gone)} is gone (its "
                    f"acknowledgements lost liveliness for {LIVELINESS_LEASE_S:g} s: the "
                    f"process ended or its network is down); last acknowledged: "
                    f"{self._describe(gone)}",
                    participants=tuple(gone),
                )
            left = deadline - time.monotonic()
            if left <= 0:
                raise LockstepError(
                    f"lockstep {what}: no acknowledgement from {', '.join(waiting)} within "
                    f"{timeout_s:g} s; last acknowledged: {self._describe(waiting)}",
                    participants=tuple(waiting),
                )
            if not self._waiter.wait(min(left, EVENTS_PERIOD_S)) or (
                    time.monotonic() >= self._events_due):
                self._poll_events()

    def _poll_events(self) -> None:
        """Run the liveliness events (who joined, who is gone) rclpy's executor has ready."""
        self._events_due = time.monotonic() + EVENTS_PERIOD_S
        while True:
            try:
                handler, _, _ = self._executor.wait_for_ready_callbacks(0.0)
            except (TimeoutException, ShutdownException):
                return
            handler()

    def _describe(self, names: Iterable[str]) -> str:
        parts = []
        for p in names:
            ack = self.acked[p]
            parts.append(f"{p}: " + ("nothing (never joined)" if ack is None
                                     else f"{ack[0]} at {ack[1] / 1e9:.3f} s"))
        return "; ".join(parts)

    def close(self) -> None:
        self._waiter.close()
        self._executor.shutdown()
        self._node.destroy_node()
        self.context.try_shutdown()


def advance_together(coordinators: Sequence[StepCoordinator], dt_s: float) -> int:
    """Step the participants of several coordinators as one barrier; returns the new time.

    One coordinator has one DDS domain; robots that each have a domain of their own (as
    separate computers on separate networks would) get one coordinator each, and this runs
    every round on all of them before the next round, so the robots run each step side by
    side instead of one domain after the other. All must stand at the same time.
    """
    dt_ns = round(dt_s * 1e9)
    if dt_ns <= 0:
        raise ValueError(f"a step must be positive, got {dt_s!r} s")
    times = {c.now_ns for c in coordinators}
    if len(times) != 1:
        raise ConfigError(f"coordinators stepped together must stand at one time, not at "
                          f"{sorted(times)} ns")
    target = times.pop() + dt_ns
    for c in coordinators:
        c._flush_world()
    two_rounds = [c for c in coordinators if not c.one_round]
    for c in two_rounds:
        c._start_intake()
    for c in two_rounds:
        c._wait_intake()
    for c in coordinators:
        c._start_step(target)
    for c in coordinators:
        c._wait_step(target)
    counters = {k: v for c in coordinators for p in c.participants
                for k, v in c.counters.get(p, {}).items()}
    if counters:  # links outside DDS: every participant learns what was sent on them
        frame = json.dumps(counters, sort_keys=True)
        for c in coordinators:
            c._counts_pub.publish(Header(stamp=to_msg(target), frame_id=frame))
    return target
