"""The topics view's data: a robot's topics with rates, one message echoed, numbers plotted.

Rates come from the robot's own statistics (the ExecutorStats its components publish):
the call rate of the subscriptions that read a topic on the robot is the rate the topic
arrives at, and it costs the robot nothing beyond the statistics it sends anyway. The
statistics also name topics the DDS graph cannot show (in-process topics of a container
running without DDS); they are listed, without a type. A topic
nobody reads on the robot has no such figure; echoing it measures its rate here, as
``ros2 topic hz`` would, from what arrives.

Only the topic being echoed is subscribed to, through the Hub at :data:`ECHO_HZ` (or
:data:`PLOT_HZ` while a field is plotted), so a throttle-aware publisher sends no more.
Messages are shown as the trees ``ros2 topic echo`` prints (efficient_comm's ``to_plain``),
arrays cut at :data:`TRUNCATE`; numeric fields are named by dotted paths (``pose.position.x``,
``data.3``) for plotting over a rolling :data:`WINDOW_S`.

Times are the source's (its clock, and a message's own ``header.stamp`` where it has one,
see :mod:`.ages`): a playback that delivers a second of messages at once after a seek
plots and measures them at the instants they were stamped. A seek (``reset``) forgets the
echoed message, the plot and the rates.
"""

from __future__ import annotations

import threading
from collections import deque
from collections.abc import Callable, Iterator
from typing import Any

from efficient_comm import UnknownTypeError, from_msg, import_type, to_plain

from ..errors import InvalidInput
from ..hub import hidden
from ..robots import STATS_SUFFIX, RobotId
from ..source import Source, Stream
from .ages import StampAges

ECHO_HZ = 5.0
PLOT_HZ = 20.0
TRUNCATE = 32
WINDOW_S = 30.0
#: A received rate at least this fraction of the rate asked for is taken as capped by it.
CAPPED_FRACTION = 0.8
#: Arrival times kept for the measured rate.
RATE_SAMPLES = 50


def message_class(type_name: str) -> type:
    """``pkg/msg/Name`` to its class; InvalidInput when it cannot be imported here."""
    try:
        return import_type(type_name, kind="msg")
    except UnknownTypeError as exc:
        raise InvalidInput(str(exc)) from exc


def numeric_paths(tree: Any, prefix: str = "") -> Iterator[tuple[str, float]]:
    """Every number in a message tree with its dotted path (booleans are not numbers)."""
    if isinstance(tree, dict):
        for key, value in tree.items():
            yield from numeric_paths(value, f"{prefix}{key}.")
    elif isinstance(tree, list):
        for i, value in enumerate(tree):
            yield from numeric_paths(value, f"{prefix}{i}.")
    elif isinstance(tree, int | float) and not isinstance(tree, bool):
        yield prefix[:-1], float(tree)


def value_at(tree: Any, path: str) -> float | None:
    """The number at ``path`` in ``tree`` (None: absent or not a number)."""
    node = tree
    for part in path.split("."):
        if isinstance(node, dict):
            node = node.get(part)
        elif isinstance(node, list) and part.isdigit() and int(part) < len(node):
            node = node[int(part)]
        else:
            return None
    if isinstance(node, int | float) and not isinstance(node, bool):
        return float(node)
    return None


class TopicsModel:
    """One robot's topic list, and the one topic being echoed (and maybe plotted)."""

    def __init__(self, source: Source, robot: RobotId, *,
                 clock: Callable[[], float] | None = None) -> None:
        self.source = source
        self.robot = robot
        #: The source's clock (seconds): monotonic live, the log's time in a playback.
        self._clock = clock or source.now
        self._ages = StampAges(self._clock)
        self._unsubscribe_reset: Callable[[], None] | None = None
        self._lock = threading.Lock()
        self._stats_feed: Stream | None = None
        self._stats_rates: dict[str, float] = {}
        self._echo_feed: Stream | None = None
        self.echo_topic: str | None = None
        self.echo_type: str | None = None
        self._last: Any = None
        #: (stamp ns or 0, delivered on the source's clock) of the echoed messages.
        self._arrivals: deque[tuple[int, float]] = deque(maxlen=RATE_SAMPLES)
        self.plot_path: str | None = None
        #: (stamp ns or 0, delivered, value) of the plotted field.
        self._series: deque[tuple[int, float, float]] = deque()

    # -- list ----------------------------------------------------------------------------

    def activate(self) -> None:
        """Follow the robot's statistics (for rates) while the view is shown."""
        from efficient_comm_interfaces.msg import ExecutorStats

        if self._stats_feed is None:
            self._unsubscribe_reset = self.source.on_reset(self.reset)
            self._stats_feed = self.source.subscribe(
                self.robot, STATS_SUFFIX, ExecutorStats, self.on_stats, rate_hz=1.0)

    def deactivate(self) -> None:
        """Close every feed (the echo too): a hidden view costs the robot nothing."""
        feed, self._stats_feed = self._stats_feed, None
        unsubscribe, self._unsubscribe_reset = self._unsubscribe_reset, None
        if feed is not None:
            feed.close()
        self.stop_echo()
        if unsubscribe is not None:
            unsubscribe()

    def reset(self) -> None:
        """Forget rates, the echoed message and the plot's series (the source moved to
        another instant); the echoed topic and plotted field stay chosen."""
        with self._lock:
            self._stats_rates.clear()
            self._last = None
            self._arrivals.clear()
            self._series.clear()
            self._ages.reset()

    @property
    def active(self) -> bool:
        return self._stats_feed is not None

    def on_stats(self, msg: Any) -> None:
        rates: dict[str, float] = {}
        for cb in msg.callbacks:
            if cb.kind == "subscription":
                rates[cb.name] = max(rates.get(cb.name, 0.0), float(cb.rate_hz))
        with self._lock:
            self._stats_rates.update(rates)

    def topics(self) -> list[dict[str, Any]]:
        """Name, types, rate (Hz; None = unknown) and where the rate comes from, per topic.

        ``rate_source`` is "robot" (its subscriptions' call rate) or "received" (the echoed
        topic as it arrives here: at most the echo or plot rate, since the GUI asks for no
        more). ``rate_capped`` is True where that received rate is the cap itself: the
        topic may well be faster, and the view must not pass the cap off as its rate."""
        feed = self._echo_feed
        cap = None if feed is None else feed.rate_hz
        with self._lock:
            rates = dict(self._stats_rates)
            echo, measured = self.echo_topic, self._measured_rate()
        graph = self.source.topics(self.robot)
        # Topics only the statistics name: in-process topics of a container (no DDS
        # reader or writer, so the graph does not see them); their types are unknown here.
        # Hidden ones (a ThrottledPublisher's ``_throttle`` request subscriptions) are left
        # out here as the Hub leaves them out of the graph's.
        known = graph | {name: [] for name in rates if name not in graph
                         and self.robot.contains(name) and not hidden(name)}
        out = []
        for name, types in sorted(known.items()):
            rate, source = rates.get(name), "robot"
            if rate is None and name == echo and measured is not None:
                rate, source = measured, "received"
            capped = (source == "received" and rate is not None and cap is not None
                      and rate >= CAPPED_FRACTION * cap)
            out.append({"name": name, "types": types, "rate_hz": rate,
                        "rate_source": source if rate is not None else "",
                        "rate_capped": capped})
        return out

    # -- echo and plot -------------------------------------------------------------------

    def echo(self, topic: str, type_name: str) -> None:
        """Subscribe to ``topic`` (the view's one echoed topic) at the echo rate."""
        cls = message_class(type_name)
        self.stop_echo()
        full = self.robot.resolve(topic)
        with self._lock:
            self.echo_topic, self.echo_type = full, type_name
            self._last, self.plot_path = None, None
            self._arrivals.clear()
            self._series.clear()
            self._ages.reset()  # another topic, stamped by another clock maybe
        self._echo_feed = self.source.subscribe(self.robot, full, cls, self.on_message,
                                             rate_hz=ECHO_HZ)

    def stop_echo(self) -> None:
        feed, self._echo_feed = self._echo_feed, None
        if feed is not None:
            feed.close()
        with self._lock:
            self.echo_topic = self.echo_type = self.plot_path = None

    def on_message(self, msg: Any) -> None:
        tree = to_plain(msg, truncate_length=TRUNCATE)
        stamp = getattr(getattr(msg, "header", None), "stamp", None)
        stamp_ns = from_msg(stamp) if stamp is not None else 0
        with self._lock:
            at = (stamp_ns, self._ages.heard(stamp_ns))
            self._last = tree
            self._arrivals.append(at)
            if self.plot_path is not None:
                value = value_at(tree, self.plot_path)
                if value is not None:
                    self._series.append((*at, value))
                while self._series and _seconds(at) - _seconds(self._series[0]) > WINDOW_S:
                    self._series.popleft()

    def last(self) -> Any:
        """The newest echoed message as a tree (None: none yet)."""
        with self._lock:
            return self._last

    def fields(self) -> list[str]:
        """Dotted paths of the numeric fields of the newest message (for the plot picker)."""
        with self._lock:
            last = self._last
        return [] if last is None else [path for path, _ in numeric_paths(last)]

    def plot(self, path: str | None) -> None:
        """Plot ``path`` of the echoed topic (None: stop plotting); raises on a bad path."""
        if path is not None and path not in self.fields():
            raise InvalidInput(f"{path!r} is not a numeric field of {self.echo_topic}")
        with self._lock:
            self.plot_path = path
            self._series.clear()
        if self._echo_feed is not None:
            self._echo_feed.set_rate(PLOT_HZ if path is not None else ECHO_HZ)

    def series(self) -> list[tuple[float, float]]:
        """(seconds ago, value) of the plotted field, oldest first: by the messages'
        stamps where they have them, on the source's clock."""
        with self._lock:
            return [(-self._ages.age_s(stamp, delivered_s=delivered), v)
                    for stamp, delivered, v in self._series]

    def _measured_rate(self) -> float | None:
        a = self._arrivals
        if len(a) < 2 or self._ages.age_s(a[-1][0], delivered_s=a[-1][1]) > 5.0:
            return None
        span = _seconds(a[-1]) - _seconds(a[0])
        return (len(a) - 1) / span if span > 0 else None


def _seconds(at: tuple[int, float] | tuple[int, float, float]) -> float:
    """A sample's time: its stamp where it has one, else when it was delivered (one topic's
    messages are all stamped or none)."""
    return at[0] / 1e9 if at[0] else at[1]
