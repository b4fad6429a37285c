"""A wait on a few DDS subscriptions with one wait set kept for its life (the lockstep
barrier's two ends wait on it every round).

rclpy's executor builds a new wait set on every wait, in Python, from every entity of its
nodes: each subscription with its QoS event handlers, each guard condition, its own guards,
an ExitStack entry per handle. For the barrier's small node that is about 0.23 ms a wait on
the project's two-core machine, several times a step; in a profile of a lockstep team match
it was a third of each robot's main-thread CPU, and as much of the world's. Here the wait
set is made once (rebuilt only when a subscription is added), each wait puts the same
handles in again (rcl empties a wait set on every wait) and takes every sample of each ready
subscription at once, running its callback on the calling thread.

QoS events (liveliness) are not waited on: their owner still spins its rclpy executor now
and then for them (:class:`~efficient_comm.simtime.StepCoordinator` does when a wait brought
nothing). Ctrl-C ends a wait at once: the wait set holds a guard condition rclpy's signal
handler triggers, as its executors' do.
"""

from __future__ import annotations

import contextlib
from typing import Any

from rclpy.context import Context
from rclpy.exceptions import InvalidHandle
from rclpy.executors import ExternalShutdownException
from rclpy.guard_condition import GuardCondition
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.signals import SignalHandlerGuardCondition
from rclpy.subscription import Subscription

from .executor import take_samples

__all__ = ["ReaderWait"]


class ReaderWait:
    """Wait for samples on ``subscriptions`` (more with :meth:`add`) or for ``guard`` to be
    triggered (another thread's wake-up), and run the callbacks of what came. Not
    thread-safe: one thread waits (another may trigger ``guard``)."""

    def __init__(self, context: Context, subscriptions: tuple[Subscription, ...] = (), *,
                 guard: GuardCondition | None = None) -> None:
        self._context = context
        self._sigint = SignalHandlerGuardCondition(context)
        self._guards = (self._sigint,) if guard is None else (guard, self._sigint)
        self._subs: list[Subscription] = list(subscriptions)
        self._set: Any = None  # made on the first wait after a change

    def add(self, subscription: Subscription) -> None:
        self._subs.append(subscription)
        self._set = None

    def wait(self, timeout_s: float) -> int:
        """Wait up to ``timeout_s`` (0: only look), then take every sample each ready
        subscription holds and run its callback; returns how many ran. Raises rclpy's
        ExternalShutdownException once the context is shut down, as its executors do."""
        if not self._context.ok():
            raise ExternalShutdownException()
        subs = self._subs
        with contextlib.ExitStack() as held:  # no handle is destroyed while waited on
            try:
                for entity in (*subs, *self._guards):
                    held.enter_context(entity.handle)
            except InvalidHandle:  # a subscription destroyed meanwhile: drop it
                self._subs = [s for s in subs if _valid(s)]
                self._set = None
                return 0
            context = self._context.handle
            if context is None:  # shut down (rclpy gives no handle then)
                raise ExternalShutdownException()
            held.enter_context(context)
            if self._set is None:
                self._set = _rclpy.WaitSet(len(subs), len(self._guards), 0, 0, 0, 0, context)
            wait_set = self._set
            wait_set.clear_entities()
            for sub in subs:
                wait_set.add_subscription(sub.handle)
            for guard in self._guards:
                wait_set.add_guard_condition(guard.handle)
            wait_set.wait(max(0, round(timeout_s * 1e9)))
            ready = wait_set.get_ready_entities("subscription")
            ready_subs = [sub for sub in subs if sub.handle.pointer in ready]
        if not self._context.ok():
            raise ExternalShutdownException()
        return sum(take_samples(sub) for sub in ready_subs)

    def close(self) -> None:
        with contextlib.suppress(InvalidHandle, ValueError):
            self._sigint.destroy()
        self._set = None


def _valid(sub: Subscription) -> bool:
    try:
        with sub.handle:
            return True
    except InvalidHandle:
        return False
