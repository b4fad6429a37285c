"""``ros2 topic list|info|find|type|echo|hz|bw|pub``, printing what ros2cli prints.

``hz`` and ``bw`` subscribe raw (serialized bytes, never deserialized) so they keep up with
fast and large topics; ``echo`` deserializes only what it prints.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from collections import deque
from typing import Any

from rclpy.duration import Duration
from rclpy.qos import (
    QoSDurabilityPolicy,
    QoSHistoryPolicy,
    QoSPresetProfiles,
    QoSProfile,
    QoSReliabilityPolicy,
)
from rclpy.serialization import deserialize_message

from ._fill import parse_values, read_values, set_message_fields
from ._graph import CliNode, StopSignal, cli_node, resolve_name
from ._main import Commands, add_list_verb, add_spin_time, add_verbs, print_names, verb
from ._messages import import_interface, message_to_csv, message_to_yaml
from ._view import Query, graph_view
from .errors import CliError

HZ_WINDOW = 10000
BW_WINDOW = 100
TRUNCATE_LENGTH = 128
#: Queue depth of echo, hz and bw unless --qos-depth says otherwise (see _subscription_qos).
FOLLOW_DEPTH = 100
#: How long ``topic pub`` waits, after its last message, for matched reliable readers to
#: acknowledge what it sent (see _pub).
ACK_WAIT_S = 5.0


def register(commands: Commands) -> None:
    verbs = add_verbs(commands, "topic", "Various topic related sub-commands")
    add_list_verb(verbs, "topic", _list)
    p = verb(verbs, "info", "Print information about a topic", _info)
    add_spin_time(p)
    p.add_argument("topic_name")
    p.add_argument("-v", "--verbose", action="store_true",
                   help="Print detailed information like QoS of the endpoints")
    p = verb(verbs, "find", "Output a list of available topics of a given type", _find)
    add_spin_time(p)
    p.add_argument("topic_type",
                   help="Name of the ROS topic type to filter for (e.g. 'std_msgs/msg/String')")
    p.add_argument("-c", "--count-topics", dest="count", action="store_true",
                   help="Only display the number of topics discovered")
    p.add_argument("--include-hidden-topics", action="store_true",
                   help="Consider hidden topics as well")
    p.set_defaults(show_types=False)
    p = verb(verbs, "type", "Print a topic's type", _type)
    p.add_argument("topic_name")
    p = verb(verbs, "echo", "Output messages from a topic", _echo)
    p.add_argument("topic_name")
    p.add_argument("message_type", nargs="?",
                   help="Type of the ROS message (e.g. 'std_msgs/msg/String')")
    _add_qos_arguments(p, "sensor_data")
    p.add_argument("--field", help="Echo a selected field of a message ('.' for sub-fields)")
    p.add_argument("--full-length", "-f", action="store_true",
                   help="Output all elements of arrays, bytes and strings")
    p.add_argument("--truncate-length", "-l", type=int, default=TRUNCATE_LENGTH,
                   help=f"The length to truncate arrays, bytes and strings to "
                        f"(default: {TRUNCATE_LENGTH})")
    p.add_argument("--no-arr", action="store_true", help="Don't print array fields")
    p.add_argument("--no-str", action="store_true", help="Don't print string fields")
    p.add_argument("--flow-style", action="store_true", help="Print collections in flow style")
    p.add_argument("--raw", action="store_true", help="Echo the raw binary representation")
    p.add_argument("--csv", action="store_true",
                   help="Output all recursive fields separated by commas (e.g. for plotting)")
    p.add_argument("--filter", dest="filter_expr",
                   help="Python expression to filter messages that are printed. Expression "
                        "can use Python builtins as well as m (the message).")
    p.add_argument("--once", action="store_true",
                   help="Print the first message received and then exit")
    p.add_argument("--timeout", type=float, metavar="N",
                   help="Stop after N seconds (also while waiting for the topic)")
    p = verb(verbs, "hz", "Print the average publishing rate to screen", _hz)
    p.add_argument("topic_name")
    p.add_argument("--window", "-w", type=int, default=HZ_WINDOW, metavar="WINDOW",
                   help=f"window size, in # of messages, for calculating rate "
                        f"(default: {HZ_WINDOW})")
    p.add_argument("--wall-time", action="store_true",
                   help="accepted for compatibility: rates are always measured in wall time")
    _add_qos_arguments(p, "sensor_data")
    p = verb(verbs, "bw", "Display bandwidth used by topic", _bw)
    p.add_argument("topic")
    p.add_argument("--window", "-w", type=int, default=BW_WINDOW, metavar="WINDOW",
                   help=f"maximum window size, in # of messages (default: {BW_WINDOW})")
    _add_qos_arguments(p, "sensor_data")
    p = verb(verbs, "pub", "Publish a message to a topic", _pub)
    p.add_argument("topic_name")
    p.add_argument("message_type", help="Type of the ROS message (e.g. 'std_msgs/String')")
    p.add_argument("values", nargs="?", default=None,
                   help="Values to fill the message with in YAML format, e.g. 'data: Hello' "
                        "('header: auto' and 'stamp: now' put the time of each publish)")
    p.add_argument("--stdin", action="store_true", help="Read values from standard input")
    _add_qos_arguments(p, "default")
    p.add_argument("-r", "--rate", type=float, default=1.0, metavar="N",
                   help="Publishing rate in Hz (default: 1)")
    p.add_argument("-p", "--print", type=int, default=1, metavar="N",
                   help="Only print every N-th published message (default: 1)")
    once = p.add_mutually_exclusive_group()
    once.add_argument("-1", "--once", action="store_true", help="Publish one message and exit")
    once.add_argument("-t", "--times", type=int, default=0,
                      help="Publish this number of times and then exit")
    p.add_argument("-w", "--wait-matching-subscriptions", type=int, default=None,
                   help="Wait until finding the specified number of matching subscriptions "
                        "(default: 1 with --once or --times, else 0)")
    p.add_argument("--max-wait-time-secs", type=float, default=None,
                   help="Longest time to wait for matching subscriptions")
    p.add_argument("--keep-alive", type=float, default=0.1, metavar="N",
                   help="Keep publishing node alive for N seconds after the last message")
    p.add_argument("-n", "--node-name", help="Name of the created publishing node")


def _add_qos_arguments(parser: argparse.ArgumentParser, default_profile: str) -> None:
    parser.add_argument("--qos-profile", choices=QoSPresetProfiles.short_keys(),
                        default=default_profile,
                        help=f"Quality of service preset profile (default: {default_profile})")
    parser.add_argument("--qos-depth", type=int, metavar="N", help="Queue size setting")
    parser.add_argument("--qos-history", choices=QoSHistoryPolicy.short_keys())
    parser.add_argument("--qos-reliability", choices=QoSReliabilityPolicy.short_keys())
    parser.add_argument("--qos-durability", choices=QoSDurabilityPolicy.short_keys())


def _qos(args: argparse.Namespace) -> tuple[QoSProfile, bool]:
    """The profile asked for, and whether any policy was given explicitly."""
    profile = QoSPresetProfiles.get_from_short_key(args.qos_profile)
    explicit = False
    if args.qos_history is not None:
        profile.history = QoSHistoryPolicy.get_from_short_key(args.qos_history)
        explicit = True
    if args.qos_reliability is not None:
        profile.reliability = QoSReliabilityPolicy.get_from_short_key(args.qos_reliability)
        explicit = True
    if args.qos_durability is not None:
        profile.durability = QoSDurabilityPolicy.get_from_short_key(args.qos_durability)
        explicit = True
    if args.qos_depth is not None:
        profile.depth = args.qos_depth
        explicit = True
    return profile, explicit


def _is_hidden(name: str) -> bool:
    return any(part.startswith("_") for part in name.split("/"))


def _list(args: argparse.Namespace) -> int:
    topics = graph_view(args, Query()).topics
    return print_names([t for t in topics if args.include_hidden or not _is_hidden(t[0])], args)


def _find(args: argparse.Namespace) -> int:
    """ros2cli's ``topic find``: the topics with exactly this type among their types."""
    topics = graph_view(args, Query()).topics
    return print_names([(name, types) for name, types in topics if args.topic_type in types
                        and (args.include_hidden_topics or not _is_hidden(name))], args)


def topic_types(node: CliNode, topic: str, *, timeout_s: float | None = None) -> list[str]:
    """The types of ``topic`` once it has appeared in the graph; CliError if it does not."""
    found: list[str] = []

    def seen() -> bool:
        found[:] = dict(node.node.get_topic_names_and_types()).get(topic, [])
        return bool(found)

    if not node.wait_for(seen, **({} if timeout_s is None else {"timeout_s": timeout_s})):
        raise CliError(f"Unknown topic '{topic}'")
    return found


def _info(args: argparse.Namespace) -> int:
    topic = resolve_name(args.topic_name)
    # A topic's endpoints live in many processes, each announcing itself on its own
    # schedule: the first one seen says nothing about the others, so a command listening
    # for itself listens as the list verbs do (graph_view: --spin-time, then until stable).
    view = graph_view(args, Query(wait_kind="topic", wait_name=topic, settle_after_wait=True,
                                  topic=topic))
    types = view.topic_types(topic)
    if not types:
        raise CliError(f"Unknown topic '{topic}'")
    end = "\n\n" if args.verbose else "\n"
    print(f"Type: {types[0] if len(types) == 1 else types}", end=end)
    print(f"Publisher count: {view.publisher_count}", end=end)
    if args.verbose:
        for info in view.publishers:
            print(info, end=end)
    print(f"Subscription count: {view.subscription_count}", end=end)
    if args.verbose:
        for info in view.subscriptions:
            print(info, end=end)
    return 0


def _type(args: argparse.Namespace) -> int:
    topic = resolve_name(args.topic_name)
    types = graph_view(args, Query(wait_kind="topic", wait_name=topic)).topic_types(topic)
    if not types:
        raise CliError(f"Unknown topic '{topic}'")
    for name in types:
        print(name)
    return 0


def _subscription_qos(node: CliNode, topic: str, args: argparse.Namespace) -> QoSProfile:
    """As ros2cli: the preset, made reliable / transient-local when every publisher is."""
    profile, explicit = _qos(args)
    if explicit:
        return profile
    # A deeper queue than the preset's 5, so bursts (a slow terminal, a GC pause) are
    # absorbed instead of dropped.
    profile.depth = FOLLOW_DEPTH
    infos = node.node.get_publishers_info_by_topic(topic)
    if not infos:
        return profile
    if all(i.qos_profile.reliability == QoSReliabilityPolicy.RELIABLE for i in infos):
        profile.reliability = QoSReliabilityPolicy.RELIABLE
    else:
        profile.reliability = QoSReliabilityPolicy.BEST_EFFORT
    if all(i.qos_profile.durability == QoSDurabilityPolicy.TRANSIENT_LOCAL for i in infos):
        profile.durability = QoSDurabilityPolicy.TRANSIENT_LOCAL
    else:
        profile.durability = QoSDurabilityPolicy.VOLATILE
    return profile


def _message_class(node: CliNode, topic: str, given: str | None,
                   timeout_s: float | None = None) -> Any:
    if given:
        return import_interface(given)
    try:
        types = topic_types(node, topic, timeout_s=timeout_s)
    except CliError as exc:
        raise CliError(f"Could not determine the type for the passed topic {topic} "
                       f"(nothing publishes it yet; give the type after the topic name)"
                       ) from exc
    return import_interface(types[0])


def _echo(args: argparse.Namespace) -> int:
    fields = [f for f in (args.field or "").split(".") if f]
    if args.field is not None and not fields:
        raise CliError(f"Invalid field value '{args.field}'")
    truncate = None if args.full_length else args.truncate_length
    keep = _message_filter(args.filter_expr)
    deadline = time.monotonic() + args.timeout if args.timeout else None
    with cli_node() as node:
        topic = node.resolve(args.topic_name)
        wait = None if deadline is None else max(0.0, deadline - time.monotonic())
        msg_class = _message_class(node, topic, args.message_type, wait)
        # Publishers of a topic are often discovered a little after the topic itself.
        node.wait_for(lambda: node.node.count_publishers(topic) > 0, timeout_s=0.5)
        qos = _subscription_qos(node, topic, args)
        done = False
        out = sys.stdout

        def on_message(data: bytes) -> None:
            nonlocal done
            if done:
                return
            value: Any = data
            if not args.raw:
                value = deserialize_message(data, msg_class)
                for field in fields:
                    try:
                        value = getattr(value, field)
                    except AttributeError as exc:
                        raise CliError(f"Invalid field '{args.field}': {exc}") from exc
            if keep is not None and not keep(value):
                return
            if args.raw:
                out.write(f"{data!r}\n---\n")
            else:
                if args.csv and hasattr(value, "get_fields_and_field_types"):
                    out.write(message_to_csv(value, truncate_length=truncate,
                                             no_arr=args.no_arr, no_str=args.no_str) + "\n")
                elif hasattr(value, "get_fields_and_field_types"):
                    out.write(message_to_yaml(value, truncate_length=truncate,
                                              no_arr=args.no_arr, no_str=args.no_str,
                                              flow_style=args.flow_style) + "---\n")
                else:  # a field's value, printed as ros2cli does
                    out.write(f"{value}\n---\n")
            out.flush()
            if args.once:
                done = True

        node.node.create_subscription(msg_class, topic, on_message, qos, raw=True)
        with StopSignal() as stop:
            while not (done or stop.requested) and (deadline is None
                                                    or time.monotonic() < deadline):
                node.spin_once(0.1)
    return 0


def _message_filter(expression: str | None) -> Any:
    """ros2cli's ``--filter``: a Python expression of ``m`` (the message, or the field given
    with ``--field``); a message is printed when it is true. Compiled once, so a syntax error
    is one line before anything is received."""
    if expression is None:
        return None
    try:
        code = compile(expression, "--filter", "eval")
    except SyntaxError as exc:
        raise CliError(f"Invalid --filter expression {expression!r}: {exc.msg}") from exc

    def keep(m: Any) -> bool:
        try:
            return bool(eval(code, {"m": m}))  # the user's own expression, as ros2cli
        except Exception as exc:
            raise CliError(f"--filter {expression!r} failed on a message: {exc!r}") from exc

    return keep


class _Rate:
    """ros2cli's ROSTopicHz for one topic: inter-arrival times over a window of messages."""

    def __init__(self, window: int) -> None:
        self.times: deque[int] = deque(maxlen=window)
        self.msg_tn = 0
        self.last_printed_tn = 0

    def on_message(self, _data: bytes) -> None:
        now = time.monotonic_ns()
        if self.msg_tn:
            self.times.append(now - self.msg_tn)
        self.msg_tn = now

    def report(self) -> str | None:
        if not self.times:
            return None
        if self.last_printed_tn == 0:
            self.last_printed_tn = self.msg_tn
            return None
        if self.msg_tn < self.last_printed_tn + 1_000_000_000:
            return None
        n = len(self.times)
        mean = sum(self.times) / n
        rate = 1e9 / mean if mean > 0 else 0.0
        std_dev = math.sqrt(sum((x - mean) ** 2 for x in self.times) / n)
        self.last_printed_tn = self.msg_tn
        return (f"average rate: {rate:.3f}\n\tmin: {min(self.times) * 1e-9:.3f}s "
                f"max: {max(self.times) * 1e-9:.3f}s std dev: {std_dev * 1e-9:.5f}s "
                f"window: {n}")


def _raw_monitor(args: argparse.Namespace, topic: str, on_message: Any, report: Any) -> int:
    """Subscribe raw to ``topic`` (waiting for it to appear) and print ``report()`` each second."""
    with cli_node() as node:
        topic = node.resolve(topic)
        msg_class = None
        warned = False
        while msg_class is None:
            try:
                msg_class = _message_class(node, topic, None, timeout_s=1.0)
            except CliError:
                if not warned:
                    print(f"WARNING: topic [{topic}] does not appear to be published yet",
                          flush=True)
                    warned = True
        # Reliable when every publisher is (as echo): best effort would lose the fragments of
        # large messages and report a rate lower than what is published.
        node.wait_for(lambda: node.node.count_publishers(topic) > 0, timeout_s=0.5)
        qos = _subscription_qos(node, topic, args)
        node.node.create_subscription(msg_class, topic, on_message, qos, raw=True)
        next_report = time.monotonic() + 1.0
        with StopSignal() as stop:
            while not stop.requested:
                node.spin_once(min(0.1, max(0.0, next_report - time.monotonic())))
                if time.monotonic() >= next_report:
                    next_report += 1.0
                    text = report()
                    if text:
                        print(text, flush=True)
    return 0


def _hz(args: argparse.Namespace) -> int:
    if args.window < 1:
        raise CliError("--window must be a positive number of messages")
    rate = _Rate(args.window)
    return _raw_monitor(args, args.topic_name, rate.on_message, rate.report)


def _bw(args: argparse.Namespace) -> int:
    if args.window < 1:
        raise CliError("--window must be a positive number of messages")
    times: deque[int] = deque(maxlen=args.window)
    sizes: deque[int] = deque(maxlen=args.window)

    def on_message(data: bytes) -> None:
        times.append(time.monotonic_ns())
        sizes.append(len(data))

    def report() -> str | None:
        if len(times) < 2:
            return None
        elapsed = (time.monotonic_ns() - times[0]) * 1e-9
        total = sum(sizes)
        per_s, n = total / elapsed, len(sizes)
        values = (per_s, total / n, min(sizes), max(sizes))
        if per_s < 1000:
            bw, mean, lo, hi = (f"{v:.0f} B" for v in values)
        elif per_s < 1_000_000:
            bw, mean, lo, hi = (f"{v / 1000:.2f} KB" for v in values)
        else:
            bw, mean, lo, hi = (f"{v / 1e6:.2f} MB" for v in values)
        return f"{bw}/s from {n} messages\n\tMessage size mean: {mean} min: {lo} max: {hi}"

    print(f"Subscribed to [{args.topic}]", flush=True)
    return _raw_monitor(args, args.topic, on_message, report)


def _pub(args: argparse.Namespace) -> int:
    msg_class = import_interface(args.message_type)
    values = parse_values(read_values(args))
    msg = msg_class()
    stamps = set_message_fields(msg, values, expand_stamps=True)
    if not args.rate > 0:
        raise CliError("--rate must be > 0")
    times = 1 if args.once else args.times
    wanted = (args.wait_matching_subscriptions if args.wait_matching_subscriptions is not None
              else int(times != 0))
    if wanted == 0 and args.max_wait_time_secs is not None:
        raise CliError("--max-wait-time-secs option is only effective with "
                       "--wait-matching-subscriptions, --once or --times")
    qos, _ = _qos(args)
    with cli_node(name=args.node_name) as node:
        pub = node.node.create_publisher(msg_class, args.topic_name, qos)
        if pub.get_subscription_count() < wanted:
            print(f"Waiting for at least {wanted} matching subscription(s)...", flush=True)
            timeout = args.max_wait_time_secs
            if not node.wait_for(lambda: pub.get_subscription_count() >= wanted,
                                 timeout_s=math.inf if timeout is None else timeout):
                raise CliError(f"Timed out waiting for subscribers: Expected {wanted} "
                               f"subcribers but only got {pub.get_subscription_count()} "
                               "subscribers")
        print("publisher: beginning loop", flush=True)
        count = 0
        period = 1.0 / args.rate
        next_at = time.monotonic()
        with StopSignal() as stop:
            while (times == 0 or count < times) and not stop.requested:
                now = time.monotonic()
                if now < next_at:
                    node.spin_once(min(0.1, next_at - now))
                    continue
                next_at += period
                count += 1
                if stamps:
                    now = node.node.get_clock().now().to_msg()
                    for set_stamp in stamps:
                        set_stamp(now)
                if args.print and count % args.print == 0:
                    print(f"publishing #{count}: {msg!r}\n", flush=True)
                pub.publish(msg)
        # A reliable writer that has matched a reader may still be unknown to that reader
        # (discovery is not symmetric in time): the reader takes the sample only when the
        # writer repeats it, so exiting at once (--once) could lose it. Wait for the
        # matched readers' acknowledgements, bounded (a best-effort writer returns at once).
        pub.wait_for_all_acked(Duration(seconds=ACK_WAIT_S))
        end = time.monotonic() + args.keep_alive
        while time.monotonic() < end:
            node.spin_once(end - time.monotonic())
    return 0
