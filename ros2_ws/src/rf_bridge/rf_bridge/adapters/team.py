"""The robot-to-robot adapter: selected topics between robots over Zenoh.

Zenoh brings what a team link needs and a home-made protocol would get wrong: peer
discovery, reconnection after an outage, and reliability over TCP or UDP links. This adapter
adds what the bridge needs on top: a compact payload (the ROS 2 CDR bytes, zlib-compressed
when that helps), an attachment with the sending robot's id (loop prevention: a robot never
takes its own samples back) and a per-topic sequence number, so every sample lost on the way
is counted at the receiver (``lost``); what is sent while no peer subscribes (a peer
restarting) is counted at the sender (``no_subscriber``), so a loss is counted on one side
or the other. Throttling happens in the core before anything is sent. Publishers never
block the executor: congestion drops, and is counted by the receiver.
A received sample is decompressed at most to ``max_message_bytes``: a few kilobytes of zlib
can claim gigabytes, so the limit applies to what decompression produces.

The link has a byte budget when ``budget_bytes_per_s`` is set (RoboCup gives a robot a few
kB/s): every sample, payload and attachment, is judged against one token bucket for all the
robot's team topics before it is sent (:mod:`..core.budget`); what does not fit is dropped
and counted (``over_budget``). :meth:`TeamAdapter.usage` tells what crossed either way.

**In lockstep** (:meth:`TeamAdapter.attach_lockstep`, a container stepped by a world with
efficient_comm's barrier) the link is on the wire as ever, but what arrives is held and
handed to the robot at a simulated time fixed by when it was sent: a sample put in the step
ending at ``T`` is delivered at the start of the receiver's step that begins at
``T + latency_s`` (or the first after it). Zenoh is outside the barrier, so the barrier is
told what crossed it: each robot reports in its step acknowledgements how many samples it
has put on each topic (its sequence number), the world relays everyone's counts, and a
receiver starts a step only once it holds, from each of its linked ``peers``, every sample
the counts say is due (at most :data:`LOCKSTEP_WAIT_S` wall seconds: a peer whose sample
never comes, because its process died or the link closed, is named once and the step goes
on without it). A sample's step is found from the counts, so nothing is added on the wire.
Samples from robots not named as peers are not waited for (delivered at the next step's
start). The budget then runs on the node's simulated clock (bytes per simulated second),
so what it admits repeats too; nothing else is lost in lockstep on the one machine.
"""

from __future__ import annotations

import functools
import json
import os
import struct
import threading
import time
import zlib
from collections.abc import Callable, Sequence
from typing import Any, Protocol

from rclpy.qos import ReliabilityPolicy
from rclpy.serialization import deserialize_message, serialize_message

from .._log import Logger, RateLimitedLog
from ..config import TeamOptions
from ..core.adapter import Deliver, Route
from ..core.budget import ByteBudget, LinkUsage, UsageCounter
from ..errors import LinkError

_ATTACHMENT = struct.Struct("<QBI")  # sequence number, flags, boot id; then the robot id
_ZLIB = 1
_COMPRESS_MIN = 64  # smaller payloads are sent as they are
#: Senders (topic, robot, boot) whose last sequence number is remembered; the oldest is
#: forgotten beyond this, so samples with made-up robot ids cannot grow the table forever.
_MAX_SENDERS = 4096
#: Lockstep: how long (wall s) a receiver waits for a sample the counts say was sent.
LOCKSTEP_WAIT_S = 10.0


class StepBarrier(Protocol):
    """What the team link needs of a lockstep participant (efficient_comm's
    ``LockstepParticipant``): counters in its acknowledgements, everyone's counters, a hook
    at each step's start."""

    def report(self, name: str, count: Callable[[], int]) -> Callable[[], None]: ...

    def at_step_start(self, hook: Callable[[int], None]) -> Callable[[], None]: ...

    def counts_at(self, t_ns: int, *, timeout_s: float) -> dict[str, int] | None: ...


def _key(prefix: str, topic: str) -> str:
    return f"{prefix}/{topic.strip('/')}"


class TeamAdapter:
    name = "team"

    def __init__(self, options: TeamOptions, logger: Logger, *,
                 now_ns: Callable[[], int] = time.monotonic_ns) -> None:
        self.options = options
        self._log = RateLimitedLog(logger)
        self._origin = options.robot_id.encode()
        # A robot that restarts counts from 1 again: the boot id keeps its new sequence
        # apart from the old one at the receivers.
        self._boot = int.from_bytes(os.urandom(4), "little")
        self._session: Any = None
        self._pubs: dict[int, Any] = {}
        self._subs: list[Any] = []
        self._seq: dict[int, int] = {}
        self._last_seen: dict[tuple[int, bytes, int], int] = {}
        self._lock = threading.Lock()
        budget = None
        if options.budget_bytes_per_s > 0:
            burst = options.budget_burst_bytes or max(1, round(options.budget_bytes_per_s))
            budget = ByteBudget(options.budget_bytes_per_s, burst, now_ns=now_ns)
        self._usage = UsageCounter("team", options.robot_id, now_ns=now_ns, budget=budget)
        # Lockstep (attach_lockstep): samples put per outbound route, samples held per
        # (route, origin) with the newest sequence number arrived, what each peer owes.
        self._barrier: StepBarrier | None = None
        self._put: dict[int, int] = {}
        self._held: dict[tuple[int, bytes], list[tuple[int, Route, Any, int, int]]] = {}
        self._arrived: dict[tuple[int, bytes], int] = {}
        self._due: dict[str, int] = {}
        self._arrival = threading.Condition(self._lock)
        self._detach: list[Callable[[], None]] = []
        self._routes: list[Route] = []
        self._deliver: Deliver | None = None
        self._peers: list[str] = []
        self._latency_ns = 0

    def usage(self) -> LinkUsage:
        """Bytes and messages sent and received since the start, drops for the budget."""
        return self._usage.snapshot()

    def start(self, routes: Sequence[Route], deliver: Deliver) -> Sequence[Route]:
        import zenoh

        conf = zenoh.Config()
        conf.insert_json5("mode", '"peer"')
        conf.insert_json5("listen/endpoints", json.dumps(list(self.options.listen)))
        conf.insert_json5("connect/endpoints", json.dumps(list(self.options.connect)))
        conf.insert_json5(
            "scouting/multicast/enabled", "true" if self.options.multicast_scouting else "false"
        )
        # A short lease: a dead link is noticed (and re-established) within seconds.
        conf.insert_json5("transport/link/tx/lease", str(int(self.options.lease_s * 1000)))
        try:
            self._session = zenoh.open(conf)
        except Exception as exc:  # zenoh raises its own ZError for bad endpoints
            raise LinkError(f"team link cannot open: {exc}") from None
        for route in routes:
            key = _key(self.options.prefix, route.peer_topic)
            reliable = route.spec.qos.reliability != ReliabilityPolicy.BEST_EFFORT
            if route.spec.outbound:
                self._pubs[id(route)] = self._session.declare_publisher(
                    key,
                    congestion_control=zenoh.CongestionControl.DROP,
                    reliability=zenoh.Reliability.RELIABLE
                    if reliable
                    else zenoh.Reliability.BEST_EFFORT,
                )
                self._seq[id(route)] = 0
            if route.spec.inbound:
                self._subs.append(
                    self._session.declare_subscriber(
                        key, lambda sample, route=route: self._on_sample(route, sample, deliver)
                    )
                )
        self._log.info(f"team link up as {self.options.robot_id}: {len(routes)} topic(s)")
        self._routes, self._deliver = list(routes), deliver
        return routes

    def attach_lockstep(self, barrier: StepBarrier, *, peers: Sequence[str],
                        latency_s: float) -> None:
        """Deliver deterministically in lockstep (see the module docstring): ``peers``
        are the robot ids this robot is linked with (waited for), ``latency_s`` the
        simulated time from a sample's step to its delivery (>= 0). Call after start."""
        if latency_s < 0:
            raise LinkError(f"team link latency must be >= 0 s, got {latency_s!r}")
        self._barrier = barrier
        self._peers = sorted(peers)
        self._latency_ns = round(latency_s * 1e9)
        for route in self._routes:
            if route.spec.outbound:
                self._put[id(route)] = 0
                name = self._counter(route, self.options.robot_id)
                self._detach.append(barrier.report(name, functools.partial(
                    self._put.__getitem__, id(route))))
        self._detach.append(barrier.at_step_start(self._step_started))

    def _here(self, key: tuple[int, bytes], due: int) -> bool:
        return self._arrived.get(key, 0) >= due

    def _counter(self, route: Route, robot: str) -> str:
        return f"{_key(self.options.prefix, route.peer_topic)}@{robot}"

    def _step_started(self, start_ns: int) -> None:
        """Hand over every held sample due by this step, once each linked peer's are here."""
        barrier, deliver = self._barrier, self._deliver
        if barrier is None or deliver is None:
            return
        counts: dict[str, int] | None = {}
        if self._peers:
            counts = barrier.counts_at(start_ns - self._latency_ns, timeout_s=LOCKSTEP_WAIT_S)
            if counts is None:
                self._log.warning("team link in lockstep: no counts from the world within "
                                  f"{LOCKSTEP_WAIT_S:g} s; delivering what is here")
        batch: list[tuple[int, Route, Any, int, int]] = []
        with self._arrival:
            for route in self._routes:
                if not route.spec.inbound:
                    continue
                for peer in self._peers:
                    name = self._counter(route, peer)
                    due = self._due[name] = max(self._due.get(name, 0),
                                                (counts or {}).get(name, 0))
                    key = (id(route), peer.encode())
                    here = functools.partial(self._here, key, due)
                    if not self._arrival.wait_for(here, timeout=LOCKSTEP_WAIT_S):
                        self._log.warning(
                            f"team link in lockstep: sample {due} of {peer} on "
                            f"{route.peer_topic} not here within {LOCKSTEP_WAIT_S:g} s (its "
                            "process or link gone?); going on without it")
                        self._arrived[key] = due
                    held = self._held.get(key, [])
                    batch += [h for h in held if h[0] <= due]
                    self._held[key] = [h for h in held if h[0] > due]
            for key in [k for k in self._held if k[1].decode() not in self._peers]:
                batch += self._held.pop(key)  # not a linked peer: not waited for
        for _, route, msg, received, nbytes in batch:
            deliver(route, msg, received, nbytes)

    def send(self, route: Route, msg: Any, received_ns: int) -> None:
        pub = self._pubs.get(id(route))
        if pub is None:
            route.stats_out.dropped("not_bridged")
            return
        if not pub.matching_status.matching:
            # Nobody listens (a peer restarting, or not there yet): counted here, since a
            # receiver that starts afresh cannot know what it missed. No sequence number is
            # used up, so a receiver that stays never counts these as lost too.
            route.stats_out.dropped("no_subscriber")
            return
        payload = serialize_message(msg)
        flags = 0
        if self.options.compression == "zlib" and len(payload) >= _COMPRESS_MIN:
            packed = zlib.compress(payload, 1)
            if len(packed) < len(payload):
                payload, flags = packed, _ZLIB
        wire = len(payload) + _ATTACHMENT.size + len(self._origin)
        if not self._usage.admit(wire):
            route.stats_out.dropped("over_budget")  # no sequence number used up
            return
        with self._lock:
            seq = self._seq[id(route)] = self._seq[id(route)] + 1
        try:
            pub.put(payload, attachment=_ATTACHMENT.pack(seq, flags, self._boot) + self._origin)
        except Exception as exc:
            route.stats_out.dropped("send_failed")
            self._log.warning(f"team link: cannot send on {route.peer_topic}: {exc}")
            return
        self._usage.sent(wire)
        if id(route) in self._put:
            self._put[id(route)] = seq  # lockstep: what the barrier is told was put
        route.stats_out.delivered(len(payload), time.perf_counter_ns() - received_ns)

    def _on_sample(self, route: Route, sample: Any, deliver: Deliver) -> None:
        received = time.perf_counter_ns()
        try:
            attachment = sample.attachment.to_bytes() if sample.attachment is not None else b""
            seq, flags, boot = _ATTACHMENT.unpack_from(attachment)
            origin = attachment[_ATTACHMENT.size :]
        except (struct.error, AttributeError):
            route.stats_in.dropped("malformed")
            self._log.warning(f"team link: sample without a valid attachment on {route.peer_topic}")
            return
        if origin == self._origin:
            return  # our own sample: never bridged back
        key = (id(route), origin, boot)
        with self._lock:
            last = self._last_seen.pop(key, None)
            self._last_seen[key] = max(seq, last or 0)  # re-inserted: newest last
            if len(self._last_seen) > _MAX_SENDERS:
                del self._last_seen[next(iter(self._last_seen))]
        if last is not None:
            if seq <= last:
                route.stats_in.dropped("out_of_order")
                return
            if seq > last + 1:
                route.stats_in.dropped("lost", seq - last - 1)
        payload = sample.payload.to_bytes()
        limit = self.options.max_message_bytes
        if flags & _ZLIB:
            inflate = zlib.decompressobj()
            try:
                data = inflate.decompress(payload, limit)
            except zlib.error as exc:
                route.stats_in.dropped("malformed")
                self._log.warning(f"team link: undecodable sample on {route.peer_topic}: {exc}")
                return
            oversize = bool(inflate.unconsumed_tail)
        else:
            data, oversize = payload, len(payload) > limit
        if oversize:
            route.stats_in.dropped("oversize")
            self._log.warning(
                f"team link: sample on {route.peer_topic} over max_message_bytes ({limit})"
            )
            return
        try:
            msg = deserialize_message(data, route.ros2_cls)
        except Exception as exc:
            route.stats_in.dropped("malformed")
            self._log.warning(f"team link: undecodable sample on {route.peer_topic}: {exc}")
            return
        self._usage.received(len(payload) + len(attachment))
        if self._barrier is not None:  # lockstep: held for the step it is due in
            with self._arrival:
                self._held.setdefault((id(route), origin), []).append(
                    (seq, route, msg, received, len(payload)))
                self._arrived[(id(route), origin)] = seq
                self._arrival.notify_all()
            return
        deliver(route, msg, received, len(payload))

    def close(self) -> None:
        for detach in self._detach:
            detach()
        self._detach.clear()
        self._barrier = None
        if self._session is None:
            return
        for sub in self._subs:
            sub.undeclare()
        for pub in self._pubs.values():
            pub.undeclare()
        if self._session is not None:
            self._session.close()
            self._session = None
