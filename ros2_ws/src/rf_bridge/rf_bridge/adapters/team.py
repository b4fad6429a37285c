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
"""

from __future__ import annotations

import json
import os
import struct
import threading
import time
import zlib
from collections.abc import Callable, Sequence
from typing import Any

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
        return routes

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
        deliver(route, msg, received, len(payload))

    def close(self) -> None:
        if self._session is None:
            return
        for sub in self._subs:
            sub.undeclare()
        for pub in self._pubs.values():
            pub.undeclare()
        if self._session is not None:
            self._session.close()
            self._session = None
