"""``ros2 bag record|play|info|reindex``, backed by robot_recorder (MCAP, rosbag2 layout).

rosbag2 is not published as wheels; robot_recorder writes and reads the same layout
(a directory of MCAP files and ``metadata.yaml``), so the bags of one are the bags of the
other. The flags are rosbag2's where they make sense; ``info`` prints rosbag2's summary.
"""

from __future__ import annotations

import argparse
import datetime
import re
import sys
import time
from collections import Counter
from collections.abc import Callable
from pathlib import Path
from typing import Any

import yaml

from efficient_comm import EfficientCommError, Standalone
from robot_recorder import (
    Player,
    Recorder,
    RecorderError,
    TopicSelection,
    mcap_files,
    read_messages,
    reindex,
    unfinished_files,
)

from ._graph import StopSignal
from ._main import Commands, add_verbs, verb
from .errors import CliError, UsageError

_RECORD_START_S = 10.0
_LINGER_S = 0.3
#: ``play``'s default wait for subscribers to acknowledge the last messages (rosbag2 does
#: not wait unless asked, and a reader that matched late then loses them).
_ACK_WAIT_S = 5.0


def register(commands: Commands) -> None:
    verbs = add_verbs(commands, "bag", "Various rosbag related sub-commands "
                      "(MCAP in the rosbag2 layout, by robot_recorder)")
    p = verb(verbs, "record", "Record ROS data to a bag", _record)
    p.add_argument("topics_positional", nargs="*", metavar="topics",
                   help="List of topics to record")
    p.add_argument("--topics", nargs="+", default=[], help="List of topics to record")
    p.add_argument("-a", "--all", "--all-topics", dest="all", action="store_true",
                   help="Record all topics")
    p.add_argument("-e", "--regex", default="",
                   help="Record only topics containing this regular expression")
    p.add_argument("-x", "--exclude-regex", "--exclude", dest="exclude", default="",
                   help="Exclude topics containing this regular expression (on top of "
                        "--all, --topics or --regex)")
    p.add_argument("--exclude-topics", nargs="+", default=[], help="Topics not to record")
    p.add_argument("-o", "--output", help="Destination of the bagfile to create "
                   "(default: rosbag2_YYYY_MM_DD-HH_MM_SS)")
    p.add_argument("-s", "--storage", default="mcap", help="Storage identifier: mcap only")
    p.add_argument("--compression-mode", choices=["none", "file", "message"], default="none",
                   help="none: uncompressed; file or message: MCAP chunks compressed with "
                        "--compression-format (MCAP compresses per chunk)")
    p.add_argument("--compression-format", choices=["zstd", "lz4"], default="zstd")
    p.add_argument("-b", "--max-bag-size", type=int, default=0,
                   help="Maximum size in bytes before the bagfile will be split (0: off)")
    p.add_argument("-d", "--max-bag-duration", type=float, default=0,
                   help="Maximum duration in seconds before the bagfile will be split (0: off)")
    p = verb(verbs, "play", "Play back ROS data from a bag", _play)
    p.add_argument("bag_path")
    p.add_argument("-r", "--rate", type=float, default=1.0, help="Rate at which to play back")
    p.add_argument("-l", "--loop", action="store_true", help="Enable loop playback")
    p.add_argument("--topics", nargs="+", default=None, help="Topics to replay")
    p.add_argument("--remap", "-m", nargs="+", default=[], metavar="FROM:=TO",
                   help="List of topics to be remapped")
    p.add_argument("--start-offset", type=float, default=0.0,
                   help="Start the playback this many seconds into the bag")
    p.add_argument("--start-paused", action="store_true",
                   help="Start paused (resume with the player's ~/control service)")
    p.add_argument("-d", "--delay", type=float, default=0.0,
                   help="Sleep this many seconds before playing")
    p.add_argument("--clock", type=float, nargs="?", const=40.0, default=0.0, metavar="HZ",
                   help="Publish /clock at this frequency (default 40 Hz) with the bag's time")
    p.add_argument("--wait-for-all-acked", type=int, default=int(_ACK_WAIT_S * 1000),
                   metavar="MS", help="At the end, wait at most this many milliseconds for "
                   "every subscriber to acknowledge the last messages (0: no limit, -1: do not "
                   f"wait; default {int(_ACK_WAIT_S * 1000)})")
    p.add_argument("-s", "--storage", default="", help="Storage identifier: mcap or sqlite3 "
                   "(read from the bag)")
    p = verb(verbs, "info", "Print information about a bag to the screen", _info)
    p.add_argument("bag_path")
    p.add_argument("-s", "--storage", default="", help="Storage identifier: mcap or sqlite3 "
                   "(read from the bag)")
    p = verb(verbs, "reindex", "Reconstruct metadata.yaml of a bag from its MCAP files",
             _reindex)
    p.add_argument("bag_path")
    p.add_argument("storage_id", nargs="?", default="mcap", help="mcap only")


def _storage(storage: str, *, reading: bool = False) -> None:
    if storage == "mcap" or (reading and storage in ("", "sqlite3")):
        return
    what = "writes mcap only" if not reading else "reads mcap and sqlite3 only"
    raise UsageError(f"storage {storage!r}: this install {what} "
                     "(a regular ROS 2 install (ros2cli) has the other storage plug-ins)")


def _record(args: argparse.Namespace) -> int:
    _storage(args.storage)
    try:
        include = re.compile(args.regex) if args.regex else None
        exclude = re.compile(args.exclude) if args.exclude else None
    except re.error as exc:
        raise UsageError(f"invalid regular expression: {exc}") from exc
    excluded = set(args.exclude_topics)

    def wanted(name: str) -> bool:
        return name not in excluded and not (exclude is not None and exclude.search(name))

    topics = [t for t in [*args.topics_positional, *args.topics] if wanted(t)]
    scan = args.all or include is not None
    if not topics and not scan:
        raise CliError("Need to specify at least one option out of --all, --regex, --topics "
                       "or positional topics")

    def scanned(name: str) -> bool:
        return wanted(name) and (args.all or include is None or bool(include.search(name)))

    out = Path(args.output or datetime.datetime.now().strftime("rosbag2_%Y_%m_%d-%H_%M_%S"))
    if out.exists():
        raise CliError(f"Output folder '{out}' already exists.")
    compression = "none" if args.compression_mode == "none" else args.compression_format
    params = {"compression": compression, "max_file_bytes": args.max_bag_size,
              "max_file_duration_s": float(args.max_bag_duration), "min_free_bytes": 0,
              "status_period_s": 1.0}
    ros_args = ["ros2"]
    ros_args += ["--ros-args", *[a for k, v in params.items() for a in ("-p", f"{k}:={v}")]]

    def make(handle: Any) -> Recorder:
        return Recorder(handle, topics=topics, output_dir=out.parent, autostart=False)

    try:
        # stats_period_s=0: a command line tool is not a robot, and its statistics at the
        # root namespace (/efficient_comm/stats) would be recorded by `record -a` and shown
        # as a robot by debug_gui.
        with Standalone(make, name="rosbag2_recorder", args=ros_args,
                        stats_period_s=0.0) as node:
            recorder = node.component
            recorder.start(out).result(_RECORD_START_S)
            known: dict[str, str] = dict.fromkeys(topics, "")
            next_scan = 0.0
            waiting = {node.node.resolve_topic_name(t) for t in topics}
            if not waiting:  # -a, -e: what appears is recorded as it appears
                print(f"Recording to '{out}' (Ctrl-C stops)", flush=True)
            with StopSignal() as stop:
                while not stop.requested:
                    node.spin_once(0.05)
                    if waiting:
                        waiting = _subscribe_requested(node, recorder, topics, waiting, out)
                    if scan and time.monotonic() >= next_scan:
                        next_scan = time.monotonic() + 0.5
                        known = _record_all(node, recorder, known, scanned)
            recorder.stop().result(_RECORD_START_S)
            states = recorder.topic_states()
    except (EfficientCommError, RecorderError) as exc:
        raise CliError(str(exc)) from exc
    print(f"Recording stopped: '{out}'", flush=True)
    _say_losses(states)
    return 0


def _say_losses(states: dict[str, Any]) -> None:
    """What was published but is not in the bag, per topic and why (stderr, like rosbag2's
    warnings): lost by DDS before it reached the recorder, or dropped by the recorder."""
    for name, state in sorted(states.items()):
        reasons = [f"{n} {why}" for n, why in (
            (state.dds_lost, "lost by DDS before they reached the recorder"),
            (state.queue_drops, "dropped by the recorder (its queue was full)"),
            (state.write_drops, "dropped by the recorder (not writable)")) if n]
        if reasons:
            print(f"Messages of {name} missing from the bag: {'; '.join(reasons)}",
                  file=sys.stderr, flush=True)


def _subscribe_requested(node: Standalone, recorder: Recorder, topics: list[str],
                         waiting: set[str], out: Path) -> set[str]:
    """Subscribe the requested topics as soon as the graph shows their types, and say
    "Recording to" once all are subscribed, as rosbag2 says "All requested topics are
    subscribed": from then on every message published is recorded. Returns the topics
    still waited for."""
    subscribed = recorder.topic_states()
    if not waiting <= subscribed.keys():
        recorder.set_topics([TopicSelection(name=t) for t in topics])  # looks at the graph
        subscribed = recorder.topic_states()
    for name in sorted(waiting & subscribed.keys()):
        print(f"Subscribed to topic '{name}'", flush=True)
    left = waiting - subscribed.keys()
    if not left:
        print(f"Recording to '{out}' (Ctrl-C stops)", flush=True)
        print("All requested topics are subscribed. Stopping discovery...", flush=True)
    return left


def _record_all(node: Standalone, recorder: Recorder, known: dict[str, str],
                wanted: Callable[[str], bool]) -> dict[str, str]:
    """Add the ``wanted`` topics that appeared since the last look (``-a``, ``-e``), as
    rosbag2 does.

    Types are given from the graph, so the recorder need not find them itself.
    """
    own = node.node.get_fully_qualified_name() + "/"
    graph = {name: types[0] for name, types in node.node.get_topic_names_and_types()
             if types and not name.startswith(own) and wanted(name)}
    if graph.keys() <= known.keys():
        return known
    known = {**graph, **known}
    recorder.set_topics([TopicSelection(name=name, type=known[name]) for name in sorted(known)])
    return known


def _play(args: argparse.Namespace) -> int:
    _storage(args.storage, reading=True)
    if not args.rate > 0:
        raise CliError("--rate must be > 0")
    if args.delay < 0 or args.clock < 0:
        raise CliError("--delay and --clock must be >= 0")
    if args.wait_for_all_acked < -1:
        raise CliError("--wait-for-all-acked must be >= -1 (0: no limit, -1: do not wait)")
    bag = args.bag_path
    if not Path(bag).exists():
        raise CliError(f"Cannot play '{bag}': no such bag")

    def make(handle: Any) -> Player:
        return Player(handle, bag=bag, topics=args.topics, remappings=args.remap,
                      rate=args.rate, loop=args.loop,
                      start_paused=args.start_paused or args.delay > 0)

    try:
        with Standalone(make, name="rosbag2_player", args=["ros2"], stats_period_s=0.0) as node:
            player: Player = node.component
            if args.start_offset > 0:
                player.seek(player.start_ns + int(args.start_offset * 1e9))
            if args.clock:
                _publish_clock(node, player, args.clock)
            resume_at = time.monotonic() + args.delay if args.delay > 0 else None
            with StopSignal() as stop:
                while not (player.finished or stop.requested):
                    node.spin_once(0.05)
                    if resume_at is not None and time.monotonic() >= resume_at:
                        resume_at = None
                        if not args.start_paused:
                            player.resume()
                if player.finished and args.wait_for_all_acked >= 0 and not player.wait_for_acks(
                        timeout_s=args.wait_for_all_acked / 1000):
                    print("Not every subscriber acknowledged the last messages within "
                          f"{args.wait_for_all_acked} ms", file=sys.stderr)
                # A control call that ended playback (resume, step) still has its answer
                # to send: a moment of spinning gets it out before the node goes.
                end = time.monotonic() + _LINGER_S
                while not stop.requested and time.monotonic() < end:
                    node.spin_once(0.05)
    except (EfficientCommError, RecorderError) as exc:
        raise CliError(f"Cannot play '{bag}': {_reason(exc)}") from exc
    return 0


def _reason(exc: BaseException) -> str:
    """The user's reason in one line: the recorder's own error where a constructor's
    failure wraps it (no internal names such as ``_play.<locals>.make``)."""
    cause: BaseException | None = exc
    while cause is not None:
        if isinstance(cause, RecorderError):
            return str(cause).splitlines()[0] if str(cause) else type(cause).__name__
        cause = cause.__cause__
    return str(exc).splitlines()[0]


def _publish_clock(node: Standalone, player: Player, hz: float) -> None:
    """``/clock`` at ``hz`` with the bag's time, as rosbag2's ``--clock`` does."""
    from rosgraph_msgs.msg import Clock

    from efficient_comm import to_msg

    publisher = node.node.create_publisher(Clock, "/clock", 10)

    def tick() -> None:
        publisher.publish(Clock(clock=to_msg(player.bag_time_ns())))

    node.node.create_timer(1.0 / hz, tick)


def _size(num: float) -> str:
    units = ["B", "KiB", "MiB", "GiB", "TiB"]
    index = 0
    while num >= 1024 and index < 4:
        num /= 1024
        index += 1
    return f"{num:.0f} {units[index]}" if index == 0 else f"{num:.1f} {units[index]}"


def _stamp(ns: int) -> str:
    seconds, frac = divmod(ns, 1_000_000_000)
    local = datetime.datetime.fromtimestamp(seconds)
    day = f"{local.day:2d}"
    return (f"{local.strftime('%b')} {day} {local.year} {local.strftime('%H:%M:%S')}."
            f"{frac:09d} ({seconds}.{frac:09d})")


def _metadata(bag: Path) -> dict[str, Any]:
    """rosbag2's metadata of ``bag``: its metadata.yaml, or computed from the MCAP files."""
    meta = bag / "metadata.yaml"
    if meta.is_file() and not unfinished_files(bag):  # else it may not count the last chunks
        try:
            info: dict[str, Any] = yaml.safe_load(meta.read_text())["rosbag2_bagfile_information"]
            return info
        except (yaml.YAMLError, KeyError, TypeError) as exc:
            raise CliError(f"{meta} is not rosbag2 metadata: {exc}") from exc
    info = _metadata_from_messages(bag)
    info["relative_file_paths"] = [p.name for p in mcap_files(bag)]
    return info


def _info(args: argparse.Namespace) -> int:
    _storage(args.storage, reading=True)
    bag = Path(args.bag_path)
    if not bag.exists():
        raise CliError(f"No bag at '{bag}'")
    try:
        info = _metadata(bag) if bag.is_dir() else _metadata_of_file(bag)
    except RecorderError as exc:
        raise CliError(str(exc)) from exc
    files = list(info.get("relative_file_paths") or [])
    size = sum(p.stat().st_size for p in (bag.iterdir() if bag.is_dir() else [bag])
               if p.is_file())
    start = int(info["starting_time"]["nanoseconds_since_epoch"])
    duration = int(info["duration"]["nanoseconds"])
    pad = " " * 19
    lines = ["", "Files:             " + (f"\n{pad}".join(files))]
    lines += [f"Bag size:          {_size(size)}",
              f"Storage id:        {info.get('storage_identifier', 'mcap')}",
              f"ROS Distro:        {info.get('ros_distro') or 'unknown'}",
              f"Duration:          {duration // 1_000_000_000}."
              f"{duration % 1_000_000_000:09d}s",
              f"Start:             {_stamp(start)}",
              f"End:               {_stamp(start + duration)}",
              f"Messages:          {info.get('message_count', 0)}"]
    topics = [
        f"Topic: {t['topic_metadata']['name']} | Type: {t['topic_metadata']['type']} | "
        f"Count: {t['message_count']} | Serialization Format: "
        f"{t['topic_metadata'].get('serialization_format', 'cdr')}"
        for t in info.get("topics_with_message_count") or []]
    lines.append("Topic information: " + (f"\n{pad}".join(topics)))
    lines += ["Service:           0", "Service information: "]
    print("\n".join(lines))
    return 0


def _metadata_of_file(path: Path) -> dict[str, Any]:
    info = _metadata_from_messages(path)
    info["relative_file_paths"] = [path.name]
    if path.suffix == ".db3":
        info["storage_identifier"] = "sqlite3"
    return info


def _metadata_from_messages(path: Path) -> dict[str, Any]:
    counts: Counter[str] = Counter()
    types: dict[str, str] = {}
    stamps: list[int] = []
    for msg in read_messages(path, problems=[]):
        counts[msg.topic] += 1
        types.setdefault(msg.topic, msg.type)
        stamps.append(msg.log_time_ns)
    start = min(stamps, default=0)
    return {
        "storage_identifier": "mcap",
        "duration": {"nanoseconds": max(stamps, default=0) - start},
        "starting_time": {"nanoseconds_since_epoch": start},
        "message_count": sum(counts.values()),
        "topics_with_message_count": [
            {"topic_metadata": {"name": t, "type": types[t], "serialization_format": "cdr"},
             "message_count": n} for t, n in counts.items()],
    }


def _reindex(args: argparse.Namespace) -> int:
    """Rewrite metadata.yaml from the bag's files, as rosbag2's reindex does.

    Files whose recorder was killed are finished where they are (robot_recorder's
    ``reindex``); no file is renamed, so paths to them stay valid.
    """
    _storage(args.storage_id)
    bag = Path(args.bag_path)
    if not bag.is_dir():
        raise CliError(f"No bag directory at '{bag}'")
    try:
        count = reindex(bag)
    except RecorderError as exc:
        raise CliError(str(exc)) from exc
    print(f"Reindexed '{bag}': {count} messages")
    return 0
