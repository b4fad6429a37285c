"""Publishing a bag into a running system: rate, pause, seek, step, loop, topic selection,
remapping, and the header stamps as recorded, aligned to the team clock, or shifted to now.

The player is a component like any other: composed next to live components, its messages
reach them by reference, so a recorded camera stream can replace a live camera as the input
of a live detector (remap the detector's input, or the player's output, to the same topic)
while everything else runs as usual. Time comes from the node's clock, so under test a
manual clock drives playback deterministically.

The selected topics' messages are loaded into memory (serialized) when the player starts;
select topics when playing a long bag.
"""

from __future__ import annotations

import bisect
import sys
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any, Protocol

from rclpy.duration import Duration
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import deserialize_message

from efficient_comm import from_msg, to_msg
from efficient_comm.handle import NodeHandle
from rosbag2_layout import QosDict, UnknownTypeError, import_type

from .bag import BagMessage, offered_qos, read_messages
from .errors import PlaybackError, RecorderConfigError

__all__ = ["STAMP_MODES", "OffsetModel", "Player", "main"]

STAMP_MODES = ("original", "aligned", "shifted")
#: How long the player command waits at the end of the bag for its subscribers to
#: acknowledge the last messages before it exits.
ACK_WAIT_S = 5.0


class OffsetModel(Protocol):
    """Maps a robot's local time to the team reference time (team_clock provides one)."""

    def to_reference(self, local_ns: int, /) -> int: ...


def parse_remaps(items: Iterable[str] | Mapping[str, str]) -> dict[str, str]:
    """``["/from:=/to", ...]`` (or a mapping) as a dict; bad entries raise."""
    if isinstance(items, Mapping):
        return dict(items)
    out: dict[str, str] = {}
    for item in items:
        source, sep, target = item.partition(":=")
        if not sep or not source or not target:
            raise RecorderConfigError(f"remapping must be FROM:=TO, not {item!r}")
        out[source] = target
    return out


class Player:
    """Plays ``bag`` on the node's clock; control it with the methods or ``~/control``.

    Parameters (ROS): ``bag``, ``topics`` (empty: all), ``remappings`` (``FROM:=TO``),
    ``rate``, ``loop``, ``start_paused``, ``stamps`` (original / aligned / shifted),
    ``tick_s`` (how often due messages are published), ``wait_for_subscribers`` and
    ``wait_timeout_s`` (see below). Keyword options override them; ``offset_model``
    (anything with ``to_reference(int) -> int``) is needed for ``aligned`` unless team_clock
    can read one from the bag; ``on_end`` is called once when playback reaches the end of
    the bag (never while looping).

    With ``wait_for_subscribers`` the first message goes out only once every topic has a
    subscriber, or ``wait_timeout_s`` (0: no limit) has passed: a subscriber in another
    process is matched a fraction of a second after the player starts, and what was
    published before that is lost to it.
    """

    def __init__(
        self,
        node: NodeHandle,
        *,
        bag: str | Path | None = None,
        topics: Sequence[str] | None = None,
        remappings: Iterable[str] | Mapping[str, str] | None = None,
        rate: float | None = None,
        loop: bool | None = None,
        start_paused: bool | None = None,
        stamps: str | None = None,
        offset_model: OffsetModel | None = None,
        wait_for_subscribers: bool | None = None,
        wait_timeout_s: float | None = None,
        on_end: Callable[[], None] | None = None,
    ) -> None:
        p = node.declare_parameter
        self._node = node
        path = Path(bag if bag is not None else p("bag", ""))
        if not str(path) or str(path) == ".":
            raise RecorderConfigError("no bag given (parameter 'bag')")
        wanted = list(topics if topics is not None else [t for t in p("topics", [""]) if t])
        self._remap = parse_remaps(remappings if remappings is not None
                                   else [r for r in p("remappings", [""]) if r])
        self.rate = float(rate if rate is not None else p("rate", 1.0))
        if not self.rate > 0:
            raise RecorderConfigError(f"rate must be > 0, not {self.rate}")
        self.loop = bool(loop if loop is not None else p("loop", False))
        self.stamps = stamps if stamps is not None else p("stamps", "original")
        if self.stamps not in STAMP_MODES:
            raise RecorderConfigError(f"stamps must be one of {STAMP_MODES}, not {self.stamps!r}")
        self._model = offset_model
        if self.stamps == "aligned" and self._model is None:
            self._model = _model_from_bag(path)
        self.problems: list[str] = []
        self._messages: list[BagMessage] = list(
            read_messages(path, topics=wanted or None, problems=self.problems))
        if not self._messages:
            raise PlaybackError(f"{path}: no messages to play"
                                + (f" on {wanted}" if wanted else ""))
        self._times = [m.log_time_ns for m in self._messages]
        self._publishers: dict[str, Any] = {}
        self._types: dict[str, type] = {}
        recorded_qos = offered_qos(path)
        for m in self._messages:
            if m.topic not in self._publishers:
                try:
                    msg_type = import_type(m.type)
                except UnknownTypeError as exc:
                    raise PlaybackError(f"{path}: cannot play {m.topic}: {exc}") from exc
                self._types[m.topic] = msg_type
                self._publishers[m.topic] = node.create_publisher(
                    msg_type, self._remap.get(m.topic, m.topic),
                    qos=play_qos(recorded_qos.get(m.topic, [])))
        self.position = 0  # index of the next message
        self.published = 0
        self.finished = False
        self.paused = bool(start_paused if start_paused is not None else p("start_paused", False))
        self.waiting = bool(wait_for_subscribers if wait_for_subscribers is not None
                            else p("wait_for_subscribers", False))
        wait_s = float(wait_timeout_s if wait_timeout_s is not None else p("wait_timeout_s", 0.0))
        if wait_s < 0:
            raise RecorderConfigError(f"wait_timeout_s must be >= 0 (0: no limit), not {wait_s}")
        self._wait_until_ns = node.clock.now_ns() + round(wait_s * 1e9) if wait_s else None
        self._on_end = on_end
        if self.waiting:
            node.logger.info(f"waiting for a subscriber on each of {self._unmatched()} before "
                             "playing (wait_timeout_s limits the wait)")
        self._anchor()
        self._serve(node)
        tick_s = float(p("tick_s", 0.001))
        if not tick_s > 0:
            raise RecorderConfigError(f"tick_s must be > 0, not {tick_s}")
        node.create_timer(tick_s, self._on_timer)

    # -- control ---------------------------------------------------------------------------

    @property
    def start_ns(self) -> int:
        return self._times[0]

    @property
    def end_ns(self) -> int:
        return self._times[-1]

    def wait_for_acks(self, *, timeout_s: float) -> bool:
        """Block until every reader in another process has acknowledged what was played,
        at most ``timeout_s`` in all (0: no limit); whether they all did.

        A command that exits at the end of the bag calls it first: the last messages may
        still be on their way (a reliable reader that matched late asks for them again),
        and they are lost when the writers go.
        """
        end = time.monotonic() + timeout_s
        for publisher in self._publishers.values():
            left = -1.0 if timeout_s == 0 else max(0.0, end - time.monotonic())
            if not publisher.wait_for_all_acked(Duration(seconds=left)):
                return False
        return True

    def position_ns(self) -> int:
        """Recording time of the next message (-1 at the end)."""
        return self._times[self.position] if self.position < len(self._times) else -1

    def bag_time_ns(self) -> int:
        """The recording time playback is at now (what ``/clock`` publishes): advancing at
        ``rate`` while playing, standing still while paused, waiting or finished."""
        if self.paused or self.finished or self.waiting or self.position >= len(self._times):
            return self._times[min(self.position, len(self._times) - 1)]
        elapsed = self._node.clock.now_ns() - self._anchor_clock
        return self._anchor_log + int(elapsed * self.rate)

    def pause(self) -> None:
        self.paused = True

    def resume(self) -> None:
        self.paused = False
        self._anchor()

    def set_rate(self, rate: float) -> None:
        if not rate > 0:
            raise RecorderConfigError(f"rate must be > 0, not {rate}")
        self.rate = rate
        self._anchor()

    def seek(self, time_ns: int) -> None:
        """Continue from the first message recorded at or after ``time_ns`` (0: the start)."""
        self.position = bisect.bisect_left(self._times, time_ns)
        self.finished = False
        if self.position >= len(self._times) and self.loop:
            self.position = 0
        self._anchor()
        if self.position >= len(self._times):
            self._end()

    def step(self) -> bool:
        """Publish the next message now (meant for paused playback); False at the end."""
        if self.position >= len(self._messages):
            if not self.loop:
                return False
            self.position = 0
        self._publish(self._messages[self.position])
        self.position += 1
        self._anchor()
        return True

    # -- playing ---------------------------------------------------------------------------

    def _anchor(self) -> None:
        """Schedule from here: the next message is due now."""
        self._anchor_clock = self._node.clock.now_ns()
        self._anchor_log = self.position_ns() if self.position < len(self._times) else 0

    def _unmatched(self) -> list[str]:
        return [p.topic_name for p in self._publishers.values()
                if p.get_subscription_count() == 0]

    def _still_waiting(self) -> bool:
        """Whether to hold playback back for subscribers; says once why it stops waiting."""
        unmatched = self._unmatched()
        timed_out = (self._wait_until_ns is not None
                     and self._node.clock.now_ns() >= self._wait_until_ns)
        if unmatched and not timed_out:
            return True
        if unmatched:
            self._node.logger.warning(f"playing although nobody subscribes to {unmatched} "
                                      "(wait_timeout_s passed)")
        self.waiting = False
        self._anchor()
        return False

    def _end(self) -> None:
        self.finished = True
        if self._on_end is not None:
            self._on_end()

    def _on_timer(self) -> None:
        if self.paused or self.finished or (self.waiting and self._still_waiting()):
            return
        now = self._node.clock.now_ns()
        messages, times = self._messages, self._times
        wrapped = False
        while True:
            if self.position >= len(messages):
                if not self.loop:
                    self._end()
                    return
                if wrapped:  # a bag shorter than a tick: once around per tick
                    return
                wrapped = True
                self.position = 0
                self._anchor()
                now = self._anchor_clock
            due = self._anchor_clock + int((times[self.position] - self._anchor_log) / self.rate)
            if due > now:
                return
            self._publish(messages[self.position])
            self.position += 1

    def _publish(self, recorded: BagMessage) -> None:
        msg = deserialize_message(recorded.data, self._types[recorded.topic])
        if self.stamps != "original":
            header: Any = getattr(msg, "header", None)
            stamp = getattr(header, "stamp", None)
            if stamp is not None and hasattr(stamp, "nanosec"):
                ns = from_msg(stamp)
                if self.stamps == "aligned":
                    assert self._model is not None
                    ns = self._model.to_reference(ns)
                else:  # shifted: as old, relative to now, as it was when recorded
                    ns += self._node.clock.now_ns() - recorded.log_time_ns
                header.stamp = to_msg(ns)
        self._publishers[recorded.topic].publish(msg)
        self.published += 1

    # -- remote control --------------------------------------------------------------------

    def _serve(self, node: NodeHandle) -> None:
        from robot_recorder_interfaces.srv import PlayerControl

        node.create_service(PlayerControl, "~/control", self._srv_control)

    def _srv_control(self, request: Any, response: Any) -> Any:
        from robot_recorder_interfaces.srv import PlayerControl

        try:
            if request.command == PlayerControl.Request.PAUSE:
                self.pause()
            elif request.command == PlayerControl.Request.RESUME:
                self.resume()
            elif request.command == PlayerControl.Request.SEEK:
                self.seek(request.time_ns or self.start_ns)
            elif request.command == PlayerControl.Request.STEP:
                if not self.step():
                    raise PlaybackError("at the end of the bag")
            elif request.command == PlayerControl.Request.SET_RATE:
                self.set_rate(request.rate)
            else:
                raise RecorderConfigError(f"unknown command {request.command}")
            response.success = True
        except (PlaybackError, RecorderConfigError) as exc:
            response.success, response.message = False, str(exc)
        response.position_ns = self.position_ns()
        response.paused = self.paused
        return response


def play_qos(offered: Sequence[QosDict]) -> QoSProfile:
    """What the player offers for a topic whose publishers offered ``offered`` when it was
    recorded: transient local where they all were (so late joiners get the last messages,
    as from the original publisher), best effort where they all were; depth 10 at least."""
    latched = bool(offered) and all(q["durability"] == "transient_local" for q in offered)
    best_effort = bool(offered) and all(q["reliability"] == "best_effort" for q in offered)
    return QoSProfile(
        depth=max([10, *(q["depth"] for q in offered)]),
        reliability=ReliabilityPolicy.BEST_EFFORT if best_effort else ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE)


def _model_from_bag(path: Path) -> OffsetModel:
    try:
        from team_clock.model import OffsetModel as TeamModel
    except ImportError as exc:
        raise RecorderConfigError(
            "stamps='aligned' needs offset_model=..., or team_clock to read one from the bag"
        ) from exc
    model: OffsetModel = TeamModel.from_mcap(path)
    return model


def main(argv: Sequence[str] | None = None) -> int:
    """``player BAG [--topics ...] [--remap FROM:=TO ...] [--rate R] [--loop] [--paused]
    [--stamps original|aligned|shifted] [--no-wait | --wait-timeout S]`` as a standalone
    node (``--ros-args`` after).

    It starts playing once every topic has a subscriber (--no-wait: at once; --wait-timeout:
    at the latest after S seconds), and exits at the end of the bag unless --loop."""
    import argparse

    from efficient_comm import run_standalone as run

    args_in = list(sys.argv[1:] if argv is None else argv)
    ros_args: list[str] = []
    if "--ros-args" in args_in:
        i = args_in.index("--ros-args")
        args_in, ros_args = args_in[:i], args_in[i:]
    parser = argparse.ArgumentParser(
        prog="player",
        description="Play a bag (MCAP in the rosbag2 layout) into the running system. It "
        "starts once every topic has a subscriber (--no-wait: at once; --wait-timeout: after "
        "S seconds at the latest) and exits at the end of the bag unless --loop. ROS "
        "arguments go after --ros-args.")
    parser.add_argument("bag", help="the bag's directory (or one of its .mcap files)")
    parser.add_argument("--topics", nargs="*", default=None, metavar="TOPIC",
                        help="play only these topics (default: all)")
    parser.add_argument("--remap", nargs="*", default=[], metavar="FROM:=TO",
                        help="publish topic FROM as TO")
    parser.add_argument("--rate", type=float, default=1.0,
                        help="playback speed, 1.0 = as recorded")
    parser.add_argument("--loop", action="store_true", help="start again at the end")
    parser.add_argument("--paused", action="store_true",
                        help="start paused (resume with the ~/control service)")
    parser.add_argument("--stamps", choices=STAMP_MODES, default="original",
                        help="header stamps: as recorded, aligned to the team clock, or "
                             "shifted to now (default: original)")
    wait = parser.add_mutually_exclusive_group()
    wait.add_argument("--no-wait", action="store_true",
                      help="play at once, without waiting for subscribers")
    wait.add_argument("--wait-timeout", type=float, default=0.0, metavar="S",
                      help="wait at most S seconds for subscribers (default: no limit)")
    ns = parser.parse_args(args_in)
    if ns.wait_timeout < 0:
        parser.error(f"--wait-timeout must be >= 0, not {ns.wait_timeout}")
    try:  # a missing, non-MCAP or damaged bag: one line, before any node starts
        offered_qos(ns.bag)
    except PlaybackError as exc:
        print(f"player: error: {exc}", file=sys.stderr)
        return 1
    players: list[Player] = []

    def make(node: Any) -> Player:
        players.append(Player(node, bag=ns.bag, topics=ns.topics, remappings=ns.remap,
                              rate=ns.rate, loop=ns.loop, start_paused=ns.paused,
                              stamps=ns.stamps, wait_for_subscribers=not ns.no_wait,
                              wait_timeout_s=ns.wait_timeout,
                              on_end=lambda: _exit(players[0])))
        return players[0]

    return run(make, name="player", args=["player", *ros_args])


def _exit(player: Player) -> None:
    """The command's end of the bag: once what was played is acknowledged (at most
    :data:`ACK_WAIT_S`), leave the executor; the node is closed on the way out (a
    SystemExit passes through the callback guards, which catch only Exceptions)."""
    if not player.wait_for_acks(timeout_s=ACK_WAIT_S):
        print(f"player: not every subscriber acknowledged the last messages within "
              f"{ACK_WAIT_S} s", file=sys.stderr)
    raise SystemExit(0)
