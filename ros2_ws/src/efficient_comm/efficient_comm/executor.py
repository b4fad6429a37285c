"""The consecutive executor: all composed components, one thread, callbacks back to back.

RoboFrame ran the components of a process consecutively in one thread: a published message
is handed to its subscribers right away, with no queue, no wake-up and no lock. This
executor does the same for ROS 2 in Python, with a selectable order:

* ``"depth_first"`` (default): ``publish()`` calls every in-process subscriber before it
  returns, so a pipeline runs to its end inside the publisher's call. Deterministic, and
  the cheapest possible hand-over. Nesting deeper than :data:`MAX_NESTING` (a cycle of
  components) falls back to queuing so the stack cannot overflow.
* ``"breadth_first"``: ``publish()`` queues the message; the executor delivers queued
  messages in publication order once the current callback returns. QoS depth bounds each
  subscriber's queue: when it overflows, the oldest message is dropped (and counted), so
  a subscriber may then see a newer message before another subscriber sees an older one.

Timers run on the executor's clock (real ROS time, a :class:`ManualClock` advanced by
:meth:`ConsecutiveExecutor.advance`, or a :class:`SimClock` that ``/clock`` from another
process moves, stepped the same way: see :mod:`efficient_comm.simtime`, also for lockstep).
DDS entities (subscriptions from other processes, services, clients, graph events) are
waited on through an rclpy executor inside, only when the container talks DDS; a guard
condition in that wait set lets another thread's publish wake it at once (and shared
memory's watch thread, :mod:`efficient_comm.shm`). A callback that raises is logged and
counted; the others go on.
"""

from __future__ import annotations

import heapq
import itertools
import threading
import time
from collections import deque
from collections.abc import Callable, Iterable, Iterator
from typing import TYPE_CHECKING, Any, Literal, Protocol

from ._clock import ManualClock, SimClock, SystemClock
from ._failures import report_failure
from .errors import ExecutorError, MessageMutatedError
from .guard import MutationReport, fingerprint
from .stats import CallbackStats, StatsRegistry, StatsSnapshot

if TYPE_CHECKING:
    from rclpy.executors import Executor as RclpyExecutor

    from ._reader_wait import DdsReady, NodesWait, PolledWait
    from .bus import LocalSubscription
    from .handle import Clock, ClockKind, Logger
    from .simtime import LockstepParticipant

Strategy = Literal["depth_first", "breadth_first"]
#: False, True (log and record each mutation) or "raise" (also raise MessageMutatedError).
GuardMode = bool | Literal["raise"]

#: Depth-first calls nest at most this deep before further deliveries are queued.
MAX_NESTING = 32
#: While callbacks keep the executor busy, DDS is still polled at least this often...
DDS_POLL_INTERVAL_NS = 1_000_000
#: ...but a poll (an rclpy wait-set round over every node's entities, 0.2-0.6 ms) may take
#: at most this share of busy time, so the interval grows with the measured poll cost.
DDS_POLL_SHARE = 0.05
#: A lockstep participant polls the rest of DDS between steps at most this often (services,
#: parameters, QoS events, readers that no publisher was matched with at the intake): the
#: wall-clock share above kept a robot's 5 % busy with it, while its steps need none of it;
#: at 100 ms a 3v3 match's robots (a quarter of real time) paid a poll every other step.
LOCKSTEP_DDS_POLL_NS = 250_000_000
#: Between real-time waits on DDS, its QoS events (publication matched, message lost) are
#: taken this often through rclpy's wait (see ConsecutiveExecutor._dds_wait).
DDS_EVENTS_POLL_NS = 250_000_000
#: Samples taken at most from one ready DDS reader per wait beyond the first (its history
#: bounds what it holds; this bounds a reader that keeps receiving while it is taken).
MAX_TAKES = 64


class _Runnable(Protocol):
    def run_one(self, executor: ConsecutiveExecutor) -> None: ...


class _Task:
    """A one-off call queued on the executor (local service requests and the like)."""

    __slots__ = ("fn",)

    def __init__(self, fn: Callable[[], None]) -> None:
        self.fn = fn

    def run_one(self, executor: ConsecutiveExecutor) -> None:
        executor.call(None, None, "queued call", self.fn)


class ExecutorTimer:
    """A periodic callback on the executor's clock; the handle's ``create_timer`` result."""

    __slots__ = (
        "_executor",
        "_generation",
        "callback",
        "canceled",
        "closed",
        "logger",
        "next_ns",
        "period_ns",
        "stats",
    )

    def __init__(
        self,
        executor: ConsecutiveExecutor,
        period_ns: int,
        callback: Callable[[], None],
        stats: CallbackStats,
        logger: Logger,
    ) -> None:
        self._executor = executor
        self.period_ns = period_ns
        self.callback = callback
        self.stats = stats
        self.logger = logger
        self.canceled = False
        self.closed = False
        self._generation = 0
        self.next_ns = 0

    @property
    def timer_period_ns(self) -> int:
        return self.period_ns

    def cancel(self) -> None:
        self.canceled = True
        self._generation += 1

    def is_canceled(self) -> bool:
        return self.canceled

    def close(self) -> None:
        """Cancel for good (the component was unloaded)."""
        self.cancel()
        self.closed = True

    def reset(self) -> None:
        """Restart the period from now (and un-cancel), as rclpy's ``Timer.reset``."""
        if self.closed:
            raise ExecutorError("this timer belongs to an unloaded component")
        self.canceled = False
        self._generation += 1
        self._executor._schedule(self, self._executor.clock.now_ns() + self.period_ns)


class ConsecutiveExecutor:
    """Runs the callbacks of composed components one after another in a single thread.

    The executor belongs to one thread: the one that created it, or the one that spins it
    (the last one that did, between spins). Publishing from that thread delivers
    depth-first; publishing from any other thread queues the message and wakes the
    executor, so callbacks never run on a foreign thread.
    """

    def __init__(
        self,
        *,
        strategy: Strategy = "depth_first",
        clock: Clock | None = None,
        guard_mutation: GuardMode = False,
        logger: Logger | None = None,
    ) -> None:
        if strategy not in ("depth_first", "breadth_first"):
            raise ExecutorError(f"unknown strategy {strategy!r}")
        self.strategy: Strategy = strategy
        self.clock: Clock = clock or SystemClock()
        # Manual and simulated time alike: no wall-time deadlines, stats stamped in clock time.
        self._manual = isinstance(self.clock, ManualClock | SimClock)
        self._sim = self.clock if isinstance(self.clock, SimClock) else None
        self._lockstep: LockstepParticipant | None = None
        # Lockstep: messages from other processes, held from arrival until an intake round
        # (_held: per reader, bounded by its QoS depth as DDS's own history would be, with
        # an arrival number), then delivered at the start of the next step (_inbox).
        self._held: dict[int, tuple[tuple[LocalSubscription, ...], deque[tuple[int, Any]]]] = {}
        self._arrivals = itertools.count()
        self._inbox: list[tuple[tuple[LocalSubscription, ...], Any]] = []
        self._depth_first = strategy == "depth_first"
        self._guard: GuardMode = guard_mutation
        self._logger = logger
        self._ready: deque[_Runnable] = deque()
        self._timers: list[tuple[int, int, int, ExecutorTimer]] = []
        self._seq = itertools.count()
        self._nesting = 0
        # Time spent in callbacks nested inside the running one (depth-first), so that
        # each callback's statistics show its own cost, not its downstream pipeline's.
        self._nested_ns = 0
        self._thread = threading.get_ident()
        self._spinning = False
        self._stop = False
        self._wake_event = threading.Event()
        self._dds: RclpyExecutor | None = None
        self._dds_wake: Callable[[], None] | None = None
        self._nodes_wait: NodesWait | None = None
        self._polled_wait: PolledWait | None = None
        self._events_due = 0
        self._last_dds_poll = 0
        self._dds_poll_interval = DDS_POLL_INTERVAL_NS
        self.registry = StatsRegistry()
        self.mutations: list[MutationReport] = []
        self._last_report: tuple[int, MutationReport] | None = None
        self._pending_raise: MutationReport | None = None
        # Guard mode: fingerprint of a message after a receiver's reported change, so that
        # later queued receivers do not blame the publisher for it.
        self._known_fp: dict[int, bytes] = {}

    # -- wiring --------------------------------------------------------------------------

    def attach_dds(self, rclpy_executor: RclpyExecutor, *, wake: Callable[[], None]) -> None:
        """Wait on DDS entities through ``rclpy_executor`` (the container adds its nodes).

        ``wake`` must make ``rclpy_executor.spin_once`` return: trigger a guard condition
        with a callback on one of its nodes. The executor's own ``wake()`` is not enough:
        it only makes rclpy rebuild its wait set and wait again for the rest of the timeout,
        so a message published from another thread would wait for the poll timeout.
        """
        self._dds = rclpy_executor
        self._dds_wake = wake

    def detach_dds(self) -> None:
        """Stop waiting on DDS (the container is leaving it); later waits are plain."""
        nodes, self._nodes_wait = self._nodes_wait, None
        if nodes is not None:
            nodes.close()
        self._polled_wait = None
        self._dds_wake = None
        self._dds = None
        self._wake_event.set()

    def _dds_ready(self, timeout_s: float) -> DdsReady | None:
        """Wait up to ``timeout_s`` for DDS and return what is ready without running it
        (None: nothing came), for :meth:`_run_dds_items`.

        The wait is :class:`~efficient_comm._reader_wait.NodesWait`'s, on a wait set kept
        across waits: rclpy's executor builds one per wait from every entity with its QoS
        event handlers, milliseconds of Python that were a third of a real-time world's
        main thread. Every :data:`DDS_EVENTS_POLL_NS` it looks without waiting and
        returns with ``poll_events``, for the poll of what it leaves out (parameter
        services, the other QoS events: message lost, incompatible QoS). Raises rclpy's
        ``ExternalShutdownException`` once DDS is shut down.
        """
        dds = self._dds
        if dds is None:
            return None
        nodes = self._nodes_wait
        if nodes is None:
            from ._reader_wait import NodesWait

            nodes = self._nodes_wait = NodesWait(dds)
        now = time.monotonic_ns()
        deadline = now + round(timeout_s * 1e9)
        while True:
            if now >= self._events_due:
                # The poll's round looks at the DDS wait's entities too: an executor whose
                # polls come further apart than DDS_EVENTS_POLL_NS (a busy one, its poll
                # interval grown with the poll's cost) has a poll due at every round, and
                # a service left out of those rounds was never answered.
                self._events_due = now + DDS_EVENTS_POLL_NS
                ready = nodes.wait(0.0)
                ready.poll_events = True
                return ready
            ready = nodes.wait(max(0, min(deadline, self._events_due) - now) / 1e9)
            if ready:
                return ready
            now = time.monotonic_ns()
            if now >= deadline:
                return None

    def create_timer(
        self, period_s: float, callback: Callable[[], None], *, stats: CallbackStats, logger: Logger
    ) -> ExecutorTimer:
        if not period_s > 0:
            raise ValueError(f"timer period must be positive, got {period_s!r}")
        timer = ExecutorTimer(self, round(period_s * 1e9), callback, stats, logger)
        self._schedule(timer, self.clock.now_ns() + timer.period_ns)
        self._wake()
        return timer

    def _schedule(self, timer: ExecutorTimer, due_ns: int) -> None:
        timer.next_ns = due_ns
        heapq.heappush(self._timers, (due_ns, next(self._seq), timer._generation, timer))

    def attach_lockstep(self, participant: LockstepParticipant) -> None:
        """Run in lockstep (needs a :class:`SimClock`): see :mod:`efficient_comm.simtime`."""
        if self._sim is None:
            raise ExecutorError("lockstep needs an executor on a SimClock")
        self._lockstep = participant

    def detach_lockstep(self) -> None:
        """Stop waiting on the barrier (the container is leaving DDS)."""
        self._lockstep = None

    @property
    def clock_kind(self) -> ClockKind:
        """"manual" on a :class:`ManualClock` (time moves in :meth:`advance`), "sim" on a
        :class:`SimClock` (time moves when /clock says), else "system"."""
        if self._sim is not None:
            return "sim"
        return "manual" if self._manual else "system"

    def next_timer_due_ns(self) -> int | None:
        """When the earliest scheduled timer is due (clock ns), or None without timers.

        Safe to call from any thread, but only a hint there: it reads the top of the timer
        heap without the executor's cooperation, so the answer may belong to a timer that
        was just canceled or rescheduled. A background thread uses it to keep clear of the
        executor around timer deadlines (the recorder's writer does), nothing more.
        """
        try:
            return self._timers[0][0]
        except IndexError:  # no timer (or the last one was just popped by the executor)
            return None

    def post(self, fn: Callable[[], None]) -> None:
        """Run ``fn`` in the executor thread soon; safe to call from any thread."""
        self._ready.append(_Task(fn))
        self._wake()

    def call(
        self,
        stats: CallbackStats | None,
        logger: Logger | None,
        what: str,
        fn: Callable[..., Any],
        *args: Any,
    ) -> tuple[bool, Any]:
        """Run a component callback: timed, and logged and counted if it raises.

        Returns ``(True, result)``, or ``(False, the exception)`` if it raised.
        """
        outer = self._nested_ns
        self._nested_ns = 0
        start = time.perf_counter_ns()
        ok, result = True, None
        try:
            result = fn(*args)
        except Exception as exc:
            ok, result = False, exc
            report_failure(stats, logger or self._logger, what, self._now_ns())
        end = time.perf_counter_ns()
        if stats is not None:
            stamp = self.clock.now_ns() if self._manual else start
            stats.record(stamp, end - start - self._nested_ns)
        self._nested_ns = outer + end - start
        return ok, result

    def _now_ns(self) -> int:
        """Monotonic time for rate limits: the manual clock, so tests can advance it."""
        return self.clock.now_ns() if self._manual else time.monotonic_ns()

    # -- delivery (the hot path) -----------------------------------------------------------

    def receive_remote(self, subs: tuple[LocalSubscription, ...], msg: Any) -> None:
        """A message from another process (a DDS reader's callback, executor thread).

        Delivered now, except in lockstep: held until the next intake round, so that it
        reaches the subscriber at the start of the step after the one it was sent in,
        whatever the load (see :mod:`efficient_comm.simtime`).
        """
        if self._lockstep is not None:
            entry = self._held.get(id(subs))
            if entry is None:
                entry = self._held[id(subs)] = (subs, deque(maxlen=subs[0].queue.maxlen))
            held = entry[1]
            if held.maxlen is not None and len(held) == held.maxlen:
                subs[0].stats.dropped += 1  # KEEP_LAST: the oldest goes, as in DDS
            held.append((next(self._arrivals), msg))
        else:
            self.dispatch(subs, msg, "dds")

    def dispatch(self, subs: tuple[LocalSubscription, ...], msg: Any, origin: str) -> None:
        """Hand ``msg`` to ``subs`` now (depth-first) or queue it (breadth-first)."""
        fp = fingerprint(msg) if self._guard else None
        here = self._thread == threading.get_ident()
        if self._depth_first and here and self._nesting < MAX_NESTING:
            self._nesting += 1
            try:
                for sub in subs:
                    if sub.queue:  # older messages first (late-joiner history, overflow)
                        self._flush(sub)
                    fp = self.deliver(sub, msg, fp)
            finally:
                self._nesting -= 1
            if self._pending_raise is not None and not self._nesting and not self._spinning:
                self._raise_pending()
            return
        for sub in subs:
            self.enqueue(sub, msg, fp, origin=origin)
        if not here:
            self._wake()

    def _flush(self, sub: LocalSubscription) -> None:
        queue = sub.queue
        while queue and sub.active:
            queued, fp, origin = queue.popleft()
            self.deliver(sub, queued, fp, origin)

    def enqueue(
        self, sub: LocalSubscription, msg: Any, fp: bytes | None, *, origin: str = ""
    ) -> None:
        queue = sub.queue
        if queue.maxlen is not None and len(queue) == queue.maxlen:
            sub.stats.dropped += 1
        queue.append((msg, fp, origin))
        self._ready.append(sub)

    def deliver(
        self, sub: LocalSubscription, msg: Any, fp: bytes | None, origin: str = ""
    ) -> bytes | None:
        """Run ``sub``'s callback on ``msg``; returns the fingerprint after it (guard mode)."""
        if fp is not None and origin:
            fp = self._known_fp.get(id(msg), fp)
            if (now := fingerprint(msg)) != fp:
                # Changed while queued: the publisher kept modifying what it had published.
                self._report(
                    MutationReport(sub.topic.name, f"publisher {origin} after publishing"), msg
                )
                fp = self._known_fp[id(msg)] = now
        stats = sub.stats
        outer = self._nested_ns
        self._nested_ns = 0
        start = time.perf_counter_ns()
        try:
            sub.callback(msg)
        except Exception:
            report_failure(stats, sub.logger, f"callback on {sub.topic.name}", self._now_ns())
        end = time.perf_counter_ns()
        stats.record(self.clock.now_ns() if self._manual else start, end - start - self._nested_ns)
        self._nested_ns = outer + end - start
        if fp is not None and (after := fingerprint(msg)) != fp:
            self._report(
                MutationReport(sub.topic.name, f"subscriber {stats.node} ({stats.name})"), msg
            )
            self._known_fp[id(msg)] = after
            return after  # blame the next change on whoever makes it
        return fp

    def _report(self, report: MutationReport, msg: Any) -> None:
        key = (id(msg), report)
        if key == self._last_report:
            return  # the same change, seen again by the next queued receiver
        self._last_report = key
        self.mutations.append(report)
        if self._logger is not None:
            self._logger.error(str(report))
        if self._guard == "raise" and self._pending_raise is None:
            # Raised once the current round is over (see _raise_pending), never inside a
            # publish: there it would be blamed on, and caught by, the upstream callback.
            self._pending_raise = report

    def _raise_pending(self) -> None:
        report, self._pending_raise = self._pending_raise, None
        if report is not None:
            raise MessageMutatedError(str(report))

    def _run_timer(self, timer: ExecutorTimer) -> None:
        # call() inlined: timers are the executor's other hot path.
        stats = timer.stats
        self._nested_ns = 0
        start = time.perf_counter_ns()
        try:
            timer.callback()
        except Exception:
            report_failure(stats, timer.logger, f"timer {stats.name}".rstrip(), self._now_ns())
        end = time.perf_counter_ns()
        stats.record(self.clock.now_ns() if self._manual else start, end - start - self._nested_ns)
        self._nested_ns = 0

    # -- the loop --------------------------------------------------------------------------

    def _run_ready(self) -> bool:
        """Run what was queued when called; what those callbacks queue waits for the next
        round, so a breadth-first cycle cannot starve timers and DDS."""
        ready = self._ready
        if not ready:
            return False
        for _ in range(len(ready)):
            ready.popleft().run_one(self)
        if not ready:
            self._known_fp.clear()
        return True

    def _drain(self) -> None:
        while self._run_ready():
            pass

    def _run_due_timers(self, now_ns: int) -> bool:
        timers = self._timers
        ran = False
        while timers and timers[0][0] <= now_ns:
            due, _, generation, timer = timers[0]
            if generation != timer._generation or timer.canceled:
                heapq.heappop(timers)
                continue
            # Next deadline from the previous one (no drift); skip missed periods.
            nxt = due + timer.period_ns
            if nxt <= now_ns:
                nxt = now_ns + timer.period_ns - (now_ns - due) % timer.period_ns
            timer.next_ns = nxt
            heapq.heapreplace(timers, (nxt, next(self._seq), generation, timer))
            self._run_timer(timer)
            if self._ready:
                self._run_ready()
            ran = True
        return ran

    def _next_deadline(self) -> int | None:
        timers = self._timers
        while timers and (timers[0][2] != timers[0][3]._generation or timers[0][3].canceled):
            heapq.heappop(timers)
        return timers[0][0] if timers else None

    def _wake(self) -> None:
        if self._lockstep is not None and self._lockstep.joined:
            self._lockstep.wake()
        if self._dds_wake is not None:
            self._dds_wake()
        else:
            self._wake_event.set()

    def _wait(self, timeout_s: float) -> None:
        lockstep = self._lockstep
        if lockstep is not None and lockstep.joined and self._dds is not None:
            # The barrier's rounds on their own small wait set; the rest of DDS (services,
            # events; the composed readers are taken at intake) in a poll now and then.
            lockstep.wait(timeout_s)
            if time.monotonic_ns() - self._last_dds_poll > max(self._dds_poll_interval,
                                                                LOCKSTEP_DDS_POLL_NS):
                self._run_dds_ready(self._dds, 0.0)
                self._last_dds_poll = time.monotonic_ns()
            return
        if self._dds is not None:
            self._dds_wait(timeout_s)
            self._last_dds_poll = time.monotonic_ns()
        else:
            self._wake_event.wait(timeout_s)
            self._wake_event.clear()

    def _dds_wait(self, timeout_s: float) -> None:
        """Wait up to ``timeout_s`` on DDS (:meth:`_dds_ready`) and run what came; a round
        for the QoS events that ran nothing goes on waiting until the timeout."""
        deadline = time.monotonic_ns() + round(timeout_s * 1e9)
        while True:
            ready = self._dds_ready(max(0, deadline - time.monotonic_ns()) / 1e9)
            if ready is None:
                return
            # A triggered guard is a wake-up (another thread's publish, a new timer): the
            # caller has work, though no callback ran here. The events round takes guards
            # too, and going on waiting after it lost that wake-up until DDS brought more.
            if self._run_dds_items(ready) or ready.guards or not ready.poll_events:
                return  # something came: the caller looks at its timers first
            if time.monotonic_ns() >= deadline:
                return

    def _run_dds_ready(self, dds: RclpyExecutor, timeout_s: float) -> int:
        """One DDS wait (up to ``timeout_s``), then every callback it found ready, and of
        each ready subscription every sample its reader holds; returns how many ran.

        Not ``rclpy``'s ``spin_once``: that runs the first ready callback only, and its
        next call with another timeout (ours differ every time: the next timer's deadline)
        builds a new wait set and drops what the last one found; and a subscription's
        callback takes one sample, so a reader with k samples needs k waits. A wait set
        over every component's node (their parameter services, events) costs milliseconds
        of Python on a loaded machine: a busy robot took one DDS sample per wait and heard
        its 100 Hz IMU at a fraction of its rate. Uses rclpy's generator of one wait's
        ready callbacks (what ``spin_once`` takes one item of) and a subscription's
        ``take_message`` (what its handler does once).

        A pure poll (``timeout_s`` 0) measures the wait's own cost, callbacks left out, for
        the poll interval (:data:`DDS_POLL_SHARE`).
        """
        from rclpy.executors import ShutdownException, TimeoutException

        ran = 0
        ready: Iterator[Any] = dds._wait_for_ready_callbacks(timeout_sec=timeout_s)
        start = time.monotonic_ns()
        try:
            try:
                first = next(ready)
            finally:
                if not timeout_s:
                    cost = time.monotonic_ns() - start
                    self._dds_poll_interval = max(DDS_POLL_INTERVAL_NS,
                                                  int(cost / DDS_POLL_SHARE))
            ran = self._run_handlers((handler, entity) for handler, entity, _ in
                                     itertools.chain((first,), ready))
        except (StopIteration, TimeoutException, ShutdownException):
            pass
        return ran

    def _run_handlers(self, items: Iterable[tuple[Any, Any]]) -> int:
        """Run ready rclpy handlers, and of each ready subscription every sample its reader
        holds (up to :data:`MAX_TAKES`); returns how many callbacks ran."""
        from rclpy.subscription import Subscription

        ran = 0
        pending = iter(items)
        try:
            for handler, entity in pending:
                handler()
                if (exc := handler.exception()) is not None:
                    raise exc
                ran += 1
                if isinstance(entity, Subscription):
                    ran += take_samples(entity, limit=MAX_TAKES)
        except BaseException:
            # The handlers not run are never awaited: close their coroutines (else Python
            # warns "coroutine ... was never awaited" when the process ends).
            if isinstance(items, list):
                for handler, _ in pending:
                    handler.cancel()
            raise
        return ran

    def _run_dds_items(self, ready: DdsReady) -> int:
        """Run what :meth:`_dds_ready` found (executor thread): the "matched" events, the
        guard conditions' callbacks, every sample each ready subscription's reader holds
        (up to :data:`MAX_TAKES` more), and services, clients, rclpy timers and the other
        QoS events through rclpy's executor; returns how many callbacks ran."""
        for handler, data in ready.events:  # what rclpy's executor does with a ready event
            handler.callback(data)
        ran = len(ready.events)
        for guard in ready.guards:
            if guard.callback is not None:  # rclpy calls a triggered guard's callback
                guard.callback()
        for sub in ready.subs:
            ran += take_samples(sub, limit=MAX_TAKES)
        if self._dds is not None and ready.other:
            ran += self._run_dds_ready(self._dds, 0.0)
        elif self._dds is not None and ready.poll_events:
            ran += self._poll_rest(self._dds)
        return ran

    def _poll_rest(self, dds: RclpyExecutor) -> int:
        """The poll for what the DDS wait leaves out (parameter services, QoS events) on a
        wait set kept for it (:class:`~efficient_comm._reader_wait.PolledWait`); through
        rclpy's executor while it has tasks of its own (they run in its wait) or where
        that cannot serve a node's waitables."""
        if dds._tasks:  # rclpy's own tasks (a client's response, awaited) run in its wait
            return self._run_dds_ready(dds, 0.0)
        polled = self._polled_wait
        if polled is None:
            from ._reader_wait import PolledWait

            polled = self._polled_wait = PolledWait(dds)
        ran = polled.poll()
        return self._run_dds_ready(dds, 0.0) if ran is None else ran

    def _poll_dds(self) -> None:
        """Take what DDS has for us without waiting, at most once per poll interval: a
        busy executor (timers always due, or a manual clock advanced as fast as the
        machine allows) must still hear remote peers, their throttle requests and
        service calls, without paying a wait-set poll on every callback."""
        if (
            self._dds is not None
            and time.monotonic_ns() - self._last_dds_poll > self._dds_poll_interval
        ):
            self._wait(0.0)
            self._run_ready()

    def spin_once(self, timeout_s: float | None = None) -> None:
        """Run what is ready and due; if nothing was, wait up to ``timeout_s`` for work."""
        with self._owning():
            self._spin_once(timeout_s)
        if self._pending_raise is not None:
            self._raise_pending()

    def _spin_once(self, timeout_s: float | None) -> None:
        did = self._run_ready()
        if self._sim is not None:
            did = self._sim_work(self._sim) or did
        elif not self._manual:
            did = self._run_due_timers(self.clock.now_ns()) or did
        if did:
            self._poll_dds()
            return
        wait = 3600.0 if timeout_s is None else timeout_s
        deadline = None if self._manual else self._next_deadline()
        if deadline is not None:
            wait = min(wait, max(0.0, (deadline - self.clock.now_ns()) / 1e9))
        self._wait(wait)
        self._run_ready()

    def spin(self) -> None:
        """Run until :meth:`shutdown` (from a callback or another thread) or Ctrl-C."""
        self._stop = False
        with self._owning():  # own the thread between rounds too (see dispatch)
            while not self._stop:
                self._spin_once(0.1)
                if self._pending_raise is not None:
                    self._raise_pending()

    def spin_until(self, predicate: Callable[[], bool], *, timeout_s: float) -> bool:
        """Spin until ``predicate()`` holds; False if ``timeout_s`` passed first."""
        end = time.monotonic() + timeout_s
        with self._owning():
            while not predicate():
                left = end - time.monotonic()
                if left <= 0:
                    return False
                self._spin_once(min(left, 0.05))
                if self._pending_raise is not None:
                    self._raise_pending()
        return True

    def spin_for(self, duration_s: float) -> None:
        end = time.monotonic() + duration_s
        with self._owning():
            while (left := end - time.monotonic()) > 0 and not self._stop:
                self._spin_once(left)
                if self._pending_raise is not None:
                    self._raise_pending()

    def advance(self, duration_s: float) -> None:
        """Move a manual clock forward, running every timer that falls due on the way."""
        clock = self.clock
        if not isinstance(clock, ManualClock):
            raise ExecutorError(
                "advance() needs an executor on a ManualClock"
                + (" (a SimClock moves when /clock says)" if self._sim is not None else "")
            )
        with self._owning():
            # With DDS, this is exact only among the container's own components: what
            # remote peers send arrives whenever the wall clock brings it (lockstep across
            # processes is efficient_comm.simtime's).
            self._advance_to(clock, clock.now_ns() + round(duration_s * 1e9), poll=True)
        self._raise_pending()

    def _advance_to(self, clock: ManualClock | SimClock, target: int, *, poll: bool) -> None:
        self._drain()
        while (deadline := self._next_deadline()) is not None and deadline <= target:
            clock.set_ns(max(deadline, clock.now_ns()))
            # The clock's time, not the deadline: after a jump (set_ns far ahead of a
            # timer's deadline) missed periods are skipped, not run one by one.
            self._run_due_timers(clock.now_ns())
            self._drain()
            if poll:
                self._poll_dds()
        clock.set_ns(target)
        self._drain()
        if poll:
            self._poll_dds()

    def _sim_work(self, clock: SimClock) -> bool:
        """Follow /clock: advance to the latest time received; in lockstep, also do the
        barrier's rounds (intake, step) and acknowledge them. True if anything ran."""
        lockstep = self._lockstep
        if lockstep is None:
            if clock.target_ns <= clock.now_ns():
                return False
            self._advance_to(clock, clock.target_ns, poll=True)
            return True
        if not lockstep.joined:
            return False
        did = False
        if lockstep.intake_due is not None:
            t, lockstep.intake_due = lockstep.intake_due, None
            self._intake(lockstep, t)
            lockstep.done_intake(t)
            did = True
        target = clock.target_ns
        if target > clock.now_ns():
            if lockstep.last_intake_ns < clock.now_ns():
                # One round (the coordinator's only participant): /clock is the intake too.
                self._intake(lockstep, clock.now_ns())
            inbox, self._inbox = self._inbox, []
            for subs, msg in inbox:
                if subs[0].active:  # not unsubscribed meanwhile
                    self.dispatch(subs, msg, "dds")
            lockstep.step_started(clock.now_ns())  # links outside DDS (simtime)
            # No DDS poll inside a step: what other participants send now is the next's.
            self._advance_to(clock, target, poll=False)
            lockstep.done_step(target)
            did = True
        return did

    def _intake(self, lockstep: LockstepParticipant, t_ns: int) -> None:
        """The intake round: every step's message is in a DDS cache by now: take it, and
        put what was held into the inbox, topic by topic (by name), each topic's messages
        in arrival order."""
        lockstep.take()
        batch = sorted(
            (subs[0].topic.name, seq, subs, msg)
            for subs, held in self._held.values() for seq, msg in held
        )
        self._held.clear()
        self._inbox.extend((subs, msg) for _, _, subs, msg in batch)
        lockstep.last_intake_ns = t_ns

    def take_dds(self) -> int:
        """Run every DDS callback that is ready now, without waiting; returns how many.

        Unlike a poll (one callback per ready entity), this goes on until DDS has nothing
        left: a reader with several samples is ready again after each take.
        """
        from rclpy.executors import ShutdownException, TimeoutException

        dds = self._dds
        if dds is None:
            return 0
        ran = 0
        with self._owning():
            while True:
                try:
                    handler, _, _ = dds.wait_for_ready_callbacks(0.0)
                except (TimeoutException, ShutdownException):
                    break
                handler()
                if (exc := handler.exception()) is not None:
                    raise exc
                ran += 1
            self._drain()
        return ran

    def shutdown(self) -> None:
        self._stop = True
        self._wake()

    def stats(self) -> list[StatsSnapshot]:
        """Execution time and frequency of every callback (see :mod:`efficient_comm.stats`)."""
        return self.registry.snapshot()

    def _owning(self) -> _Owner:
        return _Owner(self)


def take_samples(sub: Any, *, limit: int | None = None) -> int:
    """Run ``sub``'s callback on each sample its reader holds now (at most ``limit``);
    returns how many (rclpy's handler takes one a wait). ``sub`` is an ``rclpy``
    Subscription; 0 once it is destroyed. Also the lockstep barrier's intake
    (:mod:`.simtime`), which asks every reader of a container each step, mostly to hear
    it is empty: so this is kept lean (rclpy's names looked up once per process)."""
    invalid, message_only = _rclpy_names()
    whole = sub._callback_type is not message_only
    handle, msg_type, raw, callback = sub.handle, sub.msg_type, sub.raw, sub.callback
    taken = 0
    while limit is None or taken < limit:
        try:
            with handle:
                info = handle.take_message(msg_type, raw)
        except invalid:  # destroyed meanwhile
            return taken
        if info is None:
            return taken
        taken += 1
        if whole:
            callback(*info)
        else:
            callback(info[0])
    return taken


def matched_publishers(sub: Any) -> int:
    """How many publishers DDS has matched with ``sub``'s reader (0 once it is destroyed):
    rclpy's ``get_publisher_count`` without its Python wrapper, a fifth of the cost of
    asking an empty reader for a sample (the lockstep intake asks every reader each step)."""
    invalid, _ = _rclpy_names()
    handle = sub.handle
    try:
        with handle:
            return int(handle.get_publisher_count())
    except invalid:
        return 0


_RCLPY_NAMES: tuple[type[Exception], Any] | None = None


def _rclpy_names() -> tuple[type[Exception], Any]:
    """rclpy's InvalidHandle and MessageOnly callback type, imported on first use (a
    container without DDS never imports rclpy)."""
    global _RCLPY_NAMES
    if _RCLPY_NAMES is None:
        from rclpy.exceptions import InvalidHandle
        from rclpy.subscription import Subscription

        _RCLPY_NAMES = (InvalidHandle, Subscription.CallbackType.MessageOnly)
    return _RCLPY_NAMES


class _Owner:
    """Marks the current thread as the executor's while it spins (and keeps it after)."""

    __slots__ = ("_executor", "_outer")

    def __init__(self, executor: ConsecutiveExecutor) -> None:
        self._executor = executor
        self._outer = False

    def __enter__(self) -> None:
        ex = self._executor
        me = threading.get_ident()
        if ex._spinning and ex._thread != me:
            raise ExecutorError("the executor is already spinning in another thread")
        self._outer = ex._spinning
        ex._thread = me
        ex._spinning = True

    def __exit__(self, *exc: object) -> None:
        self._executor._spinning = self._outer
