"""The clock-sync component: this robot's offset and drift to the team reference clock.

Every ``period_s`` the component publishes a :class:`TimeSyncPing` on ``/team_clock/ping``
addressed to nobody in particular. Every robot that knows the reference time (the reference
itself, and any robot holding a valid estimate) answers with a :class:`TimeSyncPong` whose
server timestamps are in reference time, its own uncertainty and hop count, and the path of
robots its estimate came through. Topics, not services: one reference answers a whole team
over a lossy or multicast link, and a lost ping or pong only costs one sample.

The client keeps one :class:`~team_clock.estimator.OffsetEstimator` per answering robot and
follows the one with the lowest uncertainty, so a robot that cannot hear the reference
synchronises through a neighbour (hops + 1, uncertainties adding up). A pong whose path
already contains this robot is ignored, which keeps loops out of the tree. A robot with no
answering neighbour for ``stale_after_s`` has no estimate and says so (``valid = false``)
instead of carrying an old one forward.

The estimate goes out on ``/team_clock/offset`` (:class:`ClockOffset`, transient local, so
a recorder that starts later still gets the current one), once per period.

"Local time" is read through a clock object (:mod:`team_clock.clocks`): the node's clock by
default, skewed by the ``sim_offset_ns`` / ``sim_drift_ppm`` parameters or replaced by the
``local_clock`` argument in simulations where several robots share one process.
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Mapping
from dataclasses import dataclass

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from efficient_comm import ParameterError, latched_qos, standalone_main, to_msg
from efficient_comm.handle import Clock, NodeHandle
from team_clock_interfaces.msg import ClockOffset, TimeSyncPing, TimeSyncPong

from .clocks import SkewedClock
from .estimator import Estimate, OffsetEstimator, Sample

__all__ = ["OFFSET_TOPIC", "PING_TOPIC", "PONG_TOPIC", "ClockSync", "SyncState", "main"]

PING_TOPIC = "/team_clock/ping"
PONG_TOPIC = "/team_clock/pong"
OFFSET_TOPIC = "/team_clock/offset"

#: Pings and pongs: best effort, since a retransmitted exchange only yields a bad sample.
EXCHANGE_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=20,
    reliability=ReliabilityPolicy.BEST_EFFORT,
    durability=DurabilityPolicy.VOLATILE,
)
#: Estimates: the latest one reaches late subscribers (a recorder started afterwards).
OFFSET_QOS = latched_qos()


@dataclass(frozen=True, slots=True)
class SyncState:
    """This robot's current view of the reference time."""

    estimate: Estimate
    #: Robot the estimate was measured against (this robot itself on the reference).
    source: str
    #: Robots from the reference down to this one.
    path: tuple[str, ...]

    @property
    def hops(self) -> int:
        return len(self.path) - 1


@dataclass
class _Source:
    estimator: OffsetEstimator
    path: tuple[str, ...] = ()


class ClockSync:
    """Estimates this robot's clock offset to the team reference; see the module docstring.

    Parameters: ``robot`` (default: the node's namespace without slashes, else its name),
    ``reference`` (the team reference robot; required), ``period_s``, ``window_s``,
    ``stale_after_s``, ``max_hops``, ``sim_offset_ns``, ``sim_drift_ppm``.
    """

    def __init__(self, node: NodeHandle, *, local_clock: Clock | None = None) -> None:
        self._node = node
        default_robot = node.namespace.strip("/").replace("/", "_") or node.name
        self.robot = node.declare_parameter("robot", default_robot, read_only=True)
        self.reference = node.declare_parameter(
            "reference", "", description="robot whose clock is the team reference",
            read_only=True,
        )
        if not self.reference:
            raise ParameterError("clock sync needs the 'reference' parameter (a robot name)")
        period = node.declare_parameter("period_s", 1.0, read_only=True)
        window = node.declare_parameter("window_s", 60.0, read_only=True)
        self._stale_ns = round(
            node.declare_parameter("stale_after_s", max(10.0, 10.0 * period), read_only=True) * 1e9
        )
        self._max_hops = node.declare_parameter("max_hops", 8, read_only=True)
        self._reply_timeout_ns = round(min(2.0, 2.0 * period) * 1e9)
        if period <= 0 or window <= 0 or self._stale_ns <= 0:
            raise ParameterError("period_s, window_s and stale_after_s must be positive")
        if self._max_hops < 1:
            raise ParameterError(f"max_hops must be at least 1, got {self._max_hops}")
        sim_offset = node.declare_parameter("sim_offset_ns", 0, read_only=True)
        sim_drift = node.declare_parameter("sim_drift_ppm", 0.0, read_only=True)
        if local_clock is None:
            local_clock = node.clock
            if sim_offset or sim_drift:
                local_clock = SkewedClock(local_clock, offset_ns=sim_offset, drift_ppm=sim_drift,
                                          epoch_ns=local_clock.now_ns())
        self.local_clock = local_clock
        self._window_ns = round(window * 1e9)
        self._window_samples = math.ceil(window / period) + 8  # one per period, and some slack
        self._started_ns = local_clock.now_ns()

        self.is_reference = self.robot == self.reference
        self._sources: dict[str, _Source] = {}
        self._outstanding: dict[int, int] = {}  # seq -> t1
        self._answered: set[tuple[str, int]] = set()  # (server, seq) already used
        self._seq = 0
        self._state: SyncState | None = None
        self._lost_reported = False
        #: Exchange counters: pings sent, pongs used, pongs refused by reason, pings
        #: unanswered, pings answered as a server.
        self.counts: Counter[str] = Counter()

        self._ping_pub = node.create_publisher(TimeSyncPing, PING_TOPIC, qos=EXCHANGE_QOS)
        self._pong_pub = node.create_publisher(TimeSyncPong, PONG_TOPIC, qos=EXCHANGE_QOS)
        self._offset_pub = node.create_publisher(ClockOffset, OFFSET_TOPIC, qos=OFFSET_QOS)
        node.create_subscription(TimeSyncPing, PING_TOPIC, self._on_ping, qos=EXCHANGE_QOS)
        node.create_subscription(TimeSyncPong, PONG_TOPIC, self._on_pong, qos=EXCHANGE_QOS)
        node.create_timer(period, self._tick)
        node.logger.info(
            f"robot {self.robot}: the team's reference clock"
            if self.is_reference else
            f"robot {self.robot}: measuring its clock against robot {self.reference}'s "
            f"(estimates on {OFFSET_TOPIC} once an exchange succeeds)")

    # -- what the robot knows -------------------------------------------------------------

    @property
    def state(self) -> SyncState | None:
        """The current estimate (None: no path to the reference, or not yet)."""
        if self.is_reference:
            now = self.local_clock.now_ns()
            exact = Estimate(stamp_ns=now, offset_ns=0, drift_ppm=0.0, uncertainty_ns=0,
                             samples=0)
            return SyncState(exact, self.robot, (self.robot,))
        return self._state

    @property
    def estimators(self) -> Mapping[str, OffsetEstimator]:
        """One estimator per robot that answered: its samples and refusals, for diagnostics."""
        return {name: source.estimator for name, source in self._sources.items()}

    def to_reference(self, local_ns: int) -> int | None:
        """Reference time at local time ``local_ns``; None without an estimate."""
        state = self.state
        return None if state is None else state.estimate.to_reference(local_ns)

    def offset_message(self) -> ClockOffset:
        """The estimate as published on ``/team_clock/offset`` (``valid = false`` if none)."""
        now = self.local_clock.now_ns()
        msg = ClockOffset(robot=self.robot, reference=self.reference)
        msg.stamp = to_msg(now)
        state = self.state
        if state is not None:
            est = state.estimate
            msg.source = state.source
            msg.offset_ns = est.to_reference(now) - now
            msg.drift_ppm = est.drift_ppm
            msg.uncertainty_ns = est.uncertainty_at(now)
            msg.hops = state.hops
            msg.samples = est.samples
            msg.valid = True
        return msg

    # -- client side ----------------------------------------------------------------------

    def _tick(self) -> None:
        now = self.local_clock.now_ns()
        for seq, t1 in list(self._outstanding.items()):
            if now - t1 > self._reply_timeout_ns:
                del self._outstanding[seq]
                if not any(s == seq for _, s in self._answered):
                    self.counts["unanswered"] += 1
                self._answered = {(r, s) for r, s in self._answered if s != seq}
        if not self.is_reference:
            self._seq = (self._seq + 1) & 0xFFFFFFFF
            t1 = self.local_clock.now_ns()
            self._outstanding[self._seq] = t1
            self._ping_pub.publish(TimeSyncPing(client=self.robot, server="", seq=self._seq,
                                                t1_ns=t1))
            self.counts["pings"] += 1
            self._update(self.local_clock.now_ns())
        self._offset_pub.publish(self.offset_message())

    def _on_pong(self, pong: TimeSyncPong) -> None:
        t4 = self.local_clock.now_ns()  # first: the receive time is what matters
        if pong.client != self.robot or self.is_reference:
            return
        if pong.reference != self.reference:
            self._misconfigured("other_reference", f"{pong.server} is synchronised to "
                                f"{pong.reference!r}, this robot to {self.reference!r}")
            return
        path = tuple(pong.path)
        if self.robot in path:
            self.counts["loop"] += 1
            return
        if pong.hops + 1 > self._max_hops:
            self.counts["too_many_hops"] += 1
            return
        key = (pong.server, pong.seq)
        if self._outstanding.get(pong.seq) != pong.t1_ns or key in self._answered:
            self.counts["stale"] += 1
            return
        self._answered.add(key)
        source = self._sources.get(pong.server)
        if source is None:
            source = _Source(OffsetEstimator(window_ns=self._window_ns,
                                             max_samples=self._window_samples))
            self._sources[pong.server] = source
        source.path = path
        sample = Sample(pong.t1_ns, pong.t2_ns, pong.t3_ns, t4,
                        server_uncertainty_ns=max(0, pong.uncertainty_ns))
        if source.estimator.add(sample):
            self.counts["samples"] += 1
            self._update(t4)
        else:
            self.counts["impossible"] += 1

    def _update(self, now: int) -> None:
        """Follow the fresh source with the lowest uncertainty."""
        best: SyncState | None = None
        for name, source in self._sources.items():
            newest = source.estimator.newest
            if newest is None or now - newest.local_ns > self._stale_ns:
                continue
            est = source.estimator.estimate(now)
            if est is None:
                continue
            if best is None or est.uncertainty_ns < best.estimate.uncertainty_ns:
                best = SyncState(est, name, (*source.path, self.robot))
        self._state = best
        if best is None and not self._lost_reported and now - self._started_ns > self._stale_ns:
            self._node.logger.warning(
                f"{self.robot}: no estimate of the reference clock of {self.reference!r} "
                "(no robot that knows it answers)"
            )
            self._lost_reported = True
        elif best is not None:
            self._lost_reported = False

    def _misconfigured(self, what: str, message: str) -> None:
        """Count a team configuration error; say it once (it repeats every period)."""
        if not self.counts[what]:
            self._node.logger.warning(f"{self.robot}: {message}")
        self.counts[what] += 1

    # -- server side ----------------------------------------------------------------------

    def _on_ping(self, ping: TimeSyncPing) -> None:
        t2_local = self.local_clock.now_ns()
        if ping.client == self.robot:
            if self._outstanding.get(ping.seq) != ping.t1_ns and not self.is_reference:
                self._misconfigured("name_clash", f"another robot also calls itself "
                                    f"{self.robot!r}: its answers would be mixed with ours")
            return
        if ping.server not in ("", self.robot):
            return
        state = self.state
        if state is None:
            return  # knows no reference time: answering would spread a guess
        est = state.estimate
        pong = TimeSyncPong(
            client=ping.client, server=self.robot, reference=self.reference, seq=ping.seq,
            t1_ns=ping.t1_ns, t2_ns=est.to_reference(t2_local),
            hops=min(state.hops, 255), path=list(state.path),
        )
        t3_local = self.local_clock.now_ns()
        pong.t3_ns = est.to_reference(t3_local)
        pong.uncertainty_ns = est.uncertainty_at(t3_local)
        self._pong_pub.publish(pong)
        self.counts["served"] += 1


main = standalone_main(ClockSync, name="clock_sync")
