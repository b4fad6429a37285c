"""Where the views' data comes from: the seam between the live Hub and a log's playback.

Every model takes a :class:`Source`, never a concrete Hub, so the same views show robots
live over DDS (:class:`~debug_gui.hub.Hub`) or a recorded team log played back on a
timeline (``debug_gui.playback``), and a test drives them with a double
(``debug_gui.testing.FakeSource``) without DDS or a browser.

What differs between the two is said here once:

* :meth:`Source.now` is the source's clock, in seconds: monotonic time live, the log's time
  at the playback cursor offline. Models judge freshness ("how old is this robot's pose")
  against it and against the messages' own stamps, never against the wall clock or the time
  a message happened to be delivered (a paused playback delivers nothing, yet its last
  messages are not stale).
* :meth:`Source.on_reset` callbacks run when what was delivered no longer holds (a seek):
  the model forgets what it accumulated; the source then delivers the messages leading up
  to the new instant. A live source never resets.
* :meth:`Source.call` answers from the robot live; a log cannot answer a service and raises
  :class:`~debug_gui.errors.NotLive`, which a view shows as such ("recorded: not live").
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, Protocol

from efficient_comm.handle import QoSLike

from .robots import RobotId


class Stream(Protocol):
    """One view's subscription to one robot topic (the Hub's ``Feed``)."""

    @property
    def robot(self) -> RobotId: ...

    @property
    def topic(self) -> str:
        """The absolute topic name."""
        ...

    @property
    def received(self) -> int:
        """Messages handed to the callback so far."""
        ...

    @property
    def rate_hz(self) -> float | None:
        """The rate asked for (None: every message)."""
        ...

    def set_rate(self, rate_hz: float | None) -> None:
        """Deliver at most ``rate_hz`` from now on (None: every message)."""
        ...

    def close(self) -> None:
        """Stop delivering at once (idempotent)."""
        ...


class Source(Protocol):
    """Robots, their topics and messages, a clock: what every view is built on."""

    @property
    def live(self) -> bool:
        """True for robots running now; False for a log played back."""
        ...

    def now(self) -> float:
        """The source's clock in seconds (see the module docstring)."""
        ...

    def on_reset(self, callback: Callable[[], None]) -> Callable[[], None]:
        """Call ``callback()`` before the messages of a new instant (a seek) arrive.

        Returns a function that unsubscribes. A live source never calls it.
        """
        ...

    def robots(self) -> list[RobotId]:
        """The robots there are now, sorted."""
        ...

    def on_robots_changed(self, callback: Callable[[], None]) -> Callable[[], None]:
        """Call ``callback()`` when robots come or go; returns an unsubscribe function."""
        ...

    def topics(self, robot: RobotId) -> dict[str, list[str]]:
        """Absolute topic names under the robot's namespace, with their types."""
        ...

    def publishes(self, robot: RobotId, topic: str) -> bool:
        """True if the robot has ``topic`` (relative to its namespace, or absolute)."""
        ...

    def publishes_statistics(self, robot: RobotId) -> bool:
        """True if the robot has efficient_comm statistics."""
        ...

    def nodes(self, robot: RobotId) -> list[str]:
        """Fully qualified names of the robot's nodes."""
        ...

    def services(self, robot: RobotId) -> dict[str, list[str]]:
        """Service names and types of the robot (none in a log)."""
        ...

    def subscribe(
        self,
        robot: RobotId,
        topic: str,
        msg_type: type,
        callback: Callable[[Any], None],
        *,
        rate_hz: float | None = None,
        qos: QoSLike = 10,
    ) -> Stream:
        """Deliver ``topic`` of ``robot`` to ``callback`` at most at ``rate_hz``.

        The callback runs on the source's thread (never a UI event loop's).
        """
        ...

    def call(
        self,
        robot: RobotId,
        service: str,
        srv_type: type,
        request: Any,
        *,
        timeout_s: float = 5.0,
    ) -> Any:
        """Call a service of the robot and wait for its response (blocking).

        Raises RobotUnavailable, CallFailed, or NotLive from a log.
        """
        ...


__all__ = ["Source", "Stream"]
