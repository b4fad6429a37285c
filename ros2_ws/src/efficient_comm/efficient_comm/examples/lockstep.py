"""Lockstep across processes: a toy world steps robots, each a container of its own.

    python -m efficient_comm.examples.lockstep robot --name blue1 --peer red1 --seed 1 &
    python -m efficient_comm.examples.lockstep robot --name red1 --peer blue1 --seed 1 &
    python -m efficient_comm.examples.lockstep world --robots blue1 red1 --steps 100
    # or the world starts them itself, each robot hearing the next in a ring:
    python -m efficient_comm.examples.lockstep world --robots blue1 red1 --spawn --seed 1

Each robot runs a :class:`Counter` in a container with ``lockstep=<name>``: every period its
timer mixes its tick count, a seeded random number and the last value heard from its peer
(another process) into a new value, published on ``/<name>/value``. The world is a
:class:`~efficient_comm.simtime.StepCoordinator` plus a container that hears every robot;
it prints each value with its simulated time and the stamp of the peer value it used,
sorted, then ``done``. Two runs with the same seed print the same lines; a peer value is
always from exactly one step before (a message crosses a process boundary in one step).
Stop the robots with Ctrl-C. A robot that dies makes the world exit 1 with one line
naming it.

``robot --counts`` also shows the barrier's counters, what a link outside DDS repeats by
(:meth:`~efficient_comm.simtime.LockstepParticipant.report`): the robot reports its tick
count as ``<name>/ticks`` with every step and prints, at the start of each step, its own
count and its peer's as the coordinator relayed it (``-`` before the first):
``blue1 step T ticks N peer M``. The peer's M is the peer's own N at that step's start.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import random
import subprocess
import sys
from collections.abc import Sequence
from contextlib import ExitStack

from geometry_msgs.msg import PointStamped

from efficient_comm import (
    ConfigError,
    Container,
    EfficientCommError,
    LockstepError,
    ManualClock,
    StepCoordinator,
    advance_together,
    from_msg,
    latched_qos,
    stop_on_sigterm,
    to_msg,
)
from efficient_comm.handle import NodeHandle
from efficient_comm.testing import stop_process_group

#: Values are reduced modulo this prime (exact in a float64's mantissa).
MODULUS = 1_000_003


def value_topic(robot: str) -> str:
    return f"/{robot}/value"


class Counter:
    """Publishes ``PointStamped`` every ``period_s``: ``x`` tick, ``y`` value, ``z`` the
    stamp (s) of the peer value it used (-1 before any), ``header.frame_id`` the robot.
    Latched: reliable (the barrier covers reliable topics), the last value for a late joiner."""

    def __init__(self, node: NodeHandle) -> None:
        self.robot = node.declare_parameter("robot", node.name, read_only=True)
        peer = node.declare_parameter("peer", "", read_only=True)
        seed = node.declare_parameter("seed", 0, read_only=True)
        self._rng = random.Random(f"{seed}/{self.robot}")  # one stream per robot and seed
        period = node.declare_parameter("period_s", 0.01, read_only=True)
        self._node = node
        self._ticks = 0
        self._value = 0
        self._peer: PointStamped | None = None
        self.pub = node.create_publisher(PointStamped, value_topic(self.robot), qos=latched_qos())
        if peer:
            node.create_subscription(PointStamped, value_topic(peer), self._on_peer,
                                     qos=latched_qos())
        node.create_timer(period, self._tick)

    @property
    def ticks(self) -> int:
        return self._ticks

    def _on_peer(self, msg: PointStamped) -> None:
        self._peer = msg

    def _tick(self) -> None:
        self._ticks += 1
        peer_value = int(self._peer.point.y) if self._peer is not None else 0
        self._value = (self._value * 31 + peer_value + self._rng.randrange(1000)) % MODULUS
        msg = PointStamped()
        msg.header.stamp = to_msg(self._node.clock.now_ns())
        msg.header.frame_id = self.robot
        msg.point.x = float(self._ticks)
        msg.point.y = float(self._value)
        msg.point.z = from_msg(self._peer.header.stamp) / 1e9 if self._peer is not None else -1.0
        self.pub.publish(msg)


class Listener:
    """The world's ear: keeps every robot value it hears (parameter ``robots``)."""

    def __init__(self, node: NodeHandle) -> None:
        self.heard: list[PointStamped] = []
        for robot in node.declare_parameter("robots", [""], read_only=True):
            node.create_subscription(PointStamped, value_topic(robot), self.heard.append,
                                     qos=latched_qos())


def robot(args: argparse.Namespace) -> int:
    """One robot: a lockstep participant hosting a Counter; spins until Ctrl-C."""
    with Container(f"{args.name}_container", lockstep=args.name) as container:
        counter: Counter = container.add(
            Counter, name=args.name,
            parameters={"robot": args.name, "peer": args.peer or "", "seed": args.seed,
                        "period_s": args.period},
        )
        # The barrier covers matched endpoints: wait until the world (and the peer) hear us.
        needed = 2 if args.peer else 1
        if not container.spin_until(lambda: counter.pub.get_subscription_count() >= needed,
                                    timeout_s=args.timeout):
            print(f"error: {args.name}: nobody subscribed to {value_topic(args.name)} within "
                  f"{args.timeout:g} s (is the world running on this domain?)", file=sys.stderr)
            return 1
        if args.counts:
            _show_counts(container, counter, args.name, args.peer or "")
        print(f"{args.name}: ready", flush=True)
        container.spin()
    return 0


def _show_counts(container: Container, counter: Counter, name: str, peer: str) -> None:
    """Report ``counter``'s ticks to the barrier; at each step start, print them and the
    peer's as relayed (``robot --counts``)."""
    barrier = container.lockstep
    assert barrier is not None  # robot() makes a lockstep container
    barrier.report(f"{name}/ticks", lambda: counter.ticks)

    def at_start(start_ns: int) -> None:
        counts = barrier.counts_at(start_ns, timeout_s=10.0)
        if counts is None:
            print(f"{name} step {start_ns}: no counters from the world within 10 s",
                  flush=True)
            return
        relayed = counts.get(f"{peer}/ticks")
        print(f"{name} step {start_ns} ticks {counter.ticks} "
              f"peer {'-' if relayed is None else relayed}", flush=True)

    barrier.at_step_start(at_start)


def _spawn(stack: ExitStack, robots: Sequence[str], seed: int,
           domains: Sequence[int] | None) -> None:
    """Start each robot as a process of its own (its own session: stopped on exit); on
    domains of their own (then they cannot hear each other: no peers), or in a ring."""
    for i, name in enumerate(robots):
        peer = robots[(i + 1) % len(robots)] if len(robots) > 1 and not domains else ""
        env = dict(os.environ)
        if domains:
            env["ROS_DOMAIN_ID"] = str(domains[i])
        proc = subprocess.Popen(
            [sys.executable, "-m", "efficient_comm.examples.lockstep", "robot", "--name", name,
             "--seed", str(seed), *(["--peer", peer] if peer else [])],
            env=env, start_new_session=True,
        )
        stack.callback(stop_process_group, proc)


def world(args: argparse.Namespace) -> int:
    """The toy world: steps the robots ``--steps`` times and prints what they published."""
    with ExitStack() as stack:
        if args.spawn:
            _spawn(stack, args.robots, args.seed, args.robot_domains)
        return _step_world(args)


def _step_world(args: argparse.Namespace) -> int:
    # Robots on domains of their own (--robot-domains) get a coordinator and an ear each.
    domains: list[int | None] = list(args.robot_domains or [None] * len(args.robots))
    if len(domains) != len(args.robots):
        raise ConfigError(f"--robot-domains lists {len(domains)} domains for "
                          f"{len(args.robots)} robots")
    groups: dict[int | None, list[str]] = {}
    for name, domain in zip(args.robots, domains, strict=True):
        groups.setdefault(domain, []).append(name)
    with ExitStack() as stack:
        # Coordinators first: they prepare the process's DDS for lockstep (efficient_comm.dds).
        coordinators = [
            stack.enter_context(StepCoordinator(names, domain_id=domain, timeout_s=args.timeout))
            for domain, names in groups.items()
        ]
        listeners: list[Listener] = []
        for c, (domain, names) in zip(coordinators, groups.items(), strict=True):
            c.container = stack.enter_context(
                Container(f"toy_world_{domain or 0}", clock=ManualClock(), domain_id=domain)
            )
            listeners.append(c.container.add(Listener, name=f"listener_{domain or 0}",
                                              parameters={"robots": names}))
        for c in coordinators:
            c.wait_ready(timeout_s=args.join_timeout)
        print(f"world: {len(args.robots)} robots joined", flush=True)
        now = 0
        for i in range(args.steps):
            now = advance_together(coordinators, args.dt)
            if args.progress and (i + 1) % args.progress == 0:
                print(f"world: step {i + 1} at {now / 1e9:.3f} s", flush=True)
        lines = sorted(
            (from_msg(m.header.stamp), m.header.frame_id, int(m.point.x), int(m.point.y),
             round(m.point.z * 1e9) if m.point.z >= 0 else -1)
            for listener in listeners for m in listener.heard
        )
        for t, name, tick, value, peer_ns in lines:
            print(f"{t} {name} tick {tick} value {value} peer {peer_ns}")
        print(f"done {coordinators[0].steps} steps to {now} ns", flush=True)
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="lockstep", description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="role", required=True)
    r = sub.add_parser("robot", help="one robot (a lockstep participant)")
    r.add_argument("--name", required=True)
    r.add_argument("--peer", help="the robot whose values this one mixes in")
    r.add_argument("--seed", type=int, default=0)
    r.add_argument("--period", type=float, default=0.01, help="timer period, simulated s")
    r.add_argument("--timeout", type=float, default=30.0, help="s to wait for subscribers")
    r.add_argument("--counts", action="store_true",
                   help="report the tick count to the barrier; print own and peer's per step")
    w = sub.add_parser("world", help="the toy world (the step coordinator)")
    w.add_argument("--robots", nargs="+", required=True)
    w.add_argument("--steps", type=int, default=100)
    w.add_argument("--dt", type=float, default=0.01, help="simulated s per step")
    w.add_argument("--timeout", type=float, default=10.0,
                   help="s a robot may take to acknowledge a step")
    w.add_argument("--join-timeout", type=float, default=60.0,
                   help="s to wait for every robot to join")
    w.add_argument("--progress", type=int, default=0, help="print every N steps (0: never)")
    w.add_argument("--spawn", action="store_true",
                   help="start the robots too (each hears the next, in a ring)")
    w.add_argument("--seed", type=int, default=0, help="the spawned robots' seed")
    w.add_argument("--robot-domains", type=int, nargs="+", metavar="ID",
                   help="each robot's DDS domain, in --robots order (default: this one's)")
    args = parser.parse_args(argv)
    stop_on_sigterm()
    try:
        return robot(args) if args.role == "robot" else world(args)
    except LockstepError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 1
    except EfficientCommError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 0


if __name__ == "__main__":
    with contextlib.suppress(KeyboardInterrupt):
        sys.exit(main())
