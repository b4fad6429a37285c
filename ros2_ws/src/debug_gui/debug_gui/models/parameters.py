"""The parameters view's data: one node's parameters, edited, and kept live (seed Fig. 5.4).

Generic: any node with the standard ``rcl_interfaces`` parameter services (ours, plain rclpy
or rclcpp ones) through :mod:`debug_gui.params`. :meth:`ParametersModel.load` lists,
describes and gets a node's parameters; :meth:`ParametersModel.set` validates what the user
entered against the parameter's type and descriptor, needs the server's token, sends it, and
records the outcome per parameter: the node's veto reason verbatim, or why it was refused
before being sent. While a set is in flight its outcome is ``setting to …`` (``pending``).
While active, the model follows ``/parameter_events``, so a change made elsewhere
(``ros2 param set``, another browser, the node itself) shows up live; the event of the
model's own set (published by the node before it answers) is recognised by its value and
never shown as ``changed elsewhere``.

``load`` and ``set`` block on service calls: a UI calls them off its event loop.

A log played back answers no service: there the model shows the parameters as recorded,
from the ``/parameter_events`` the log holds (nodes and values, without descriptors), and
``load`` raises, ``set`` answers, :class:`~debug_gui.errors.NotLive`. A seek (``reset``)
forgets the values; the playback then delivers the events leading up to the new instant.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from .. import params
from ..errors import NOT_LIVE, DebugGuiError, InvalidInput, NotLive
from ..robots import RobotId
from ..security import AccessPolicy, check_name
from ..source import Source, Stream


@dataclass(frozen=True, slots=True)
class Outcome:
    """The last thing that happened to one parameter, as the view shows it beside it."""

    ok: bool
    message: str
    #: Set here (True) or seen changed elsewhere (False, ``ok`` is then True).
    here: bool = True
    #: Sent, no answer yet (``ok`` is then True).
    pending: bool = False


class ParametersModel:
    """One robot's parameter nodes and the chosen node's parameters (activate to follow
    changes made elsewhere, deactivate to stop)."""

    def __init__(self, source: Source, robot: RobotId, *, policy: AccessPolicy,
                 token: str | None) -> None:
        self.source = source
        self.robot = robot
        self._policy = policy
        self._token = token
        self._lock = threading.Lock()
        self._feed: Stream | None = None
        self.node: str | None = None
        self._params: dict[str, params.Described] = {}
        self._outcomes: dict[str, Outcome] = {}
        #: Values this model is setting, by name (sent, not answered yet): their events are
        #: this model's own changes, not changes made elsewhere.
        self._pending: dict[str, list[Any]] = {}
        #: Bumped on every change of what :meth:`parameters` returns (the view redraws then).
        self.version = 0
        #: Bumped when parameters appear or go (the view rebuilds its widgets then).
        self.shape = 0
        #: A parameter appeared elsewhere: its descriptor needs a describe (:meth:`load`).
        self.stale = False
        self._loading = 0
        self.events = 0
        #: Nodes heard of in ``/parameter_events`` (what a log can tell of its nodes).
        self._event_nodes: set[str] = set()
        self._unsubscribe_reset: Callable[[], None] | None = None

    # -- feed --------------------------------------------------------------------------

    def activate(self) -> None:
        """Follow ``/parameter_events`` of the robot's domain (idempotent)."""
        if self._feed is None:
            self._unsubscribe_reset = self.source.on_reset(self.reset)
            self._feed = params.watch(self.source, self.robot, self.on_event)

    def deactivate(self) -> None:
        feed, self._feed = self._feed, None
        unsubscribe, self._unsubscribe_reset = self._unsubscribe_reset, None
        if feed is not None:
            feed.close()
        if unsubscribe is not None:
            unsubscribe()

    def reset(self) -> None:
        """Forget the values and outcomes (the source moved to another instant); the
        chosen node stays chosen."""
        with self._lock:
            self._params, self._outcomes = {}, {}
            self._event_nodes.clear()
            self.stale = False
            self.version += 1
            self.shape += 1

    def _check_live(self, what: str) -> None:
        if not self.source.live:
            raise NotLive(f"{self.robot.label}: {NOT_LIVE}: a log cannot {what} (it holds "
                          "only the parameter changes it recorded)")

    @property
    def active(self) -> bool:
        return self._feed is not None

    def on_event(self, event: Any) -> None:
        """One ParameterEvent (on the Hub's thread, or from tests): the chosen node's
        changes update its values; new parameters make the model stale (they need a
        describe, which cannot be called from here)."""
        recorded = not self.source.live
        with self._lock:
            if recorded and self.robot.contains(event.node):
                self._event_nodes.add(event.node)
            if event.node != self.node:
                return
            self.events += 1
            if self._loading:
                self.stale = True  # a load in flight may have read the value before this
            for p in [*event.new_parameters, *event.changed_parameters]:
                known = self._params.get(p.name)
                if known is None and recorded:  # as recorded: no descriptor to ask for
                    self._params[p.name] = params.Described(
                        p.name, p.value.type, params.python_value(p.value))
                    self.version += 1
                    self.shape += 1
                    continue
                if known is None:
                    self.stale = True
                    continue
                updated = known.with_value(p.value)
                if updated.value != known.value or updated.type != known.type:
                    self._params[p.name] = updated
                    if updated.value not in self._pending.get(p.name, ()):
                        self._outcomes[p.name] = Outcome(
                            True, f"changed elsewhere to {updated.text}", here=False)
                    self.version += 1
            for p in event.deleted_parameters:
                if self._params.pop(p.name, None) is not None:
                    self._outcomes.pop(p.name, None)
                    self.version += 1
                    self.shape += 1

    # -- what the view reads ------------------------------------------------------------

    def nodes(self, text: str = "") -> list[str]:
        """The robot's nodes with parameter services (recorded: those the log's parameter
        events name), those containing ``text``."""
        if not self.source.live:
            with self._lock:
                return sorted(n for n in self._event_nodes if text in n)
        return [n for n in params.parameter_nodes(self.source, self.robot) if text in n]

    def parameters(self, text: str = "") -> list[params.Described]:
        """The chosen node's parameters (those whose name contains ``text``), by name."""
        with self._lock:
            return [p for name, p in sorted(self._params.items()) if text in name]

    def outcome(self, name: str) -> Outcome | None:
        with self._lock:
            return self._outcomes.get(name)

    def value(self, name: str) -> params.Described | None:
        with self._lock:
            return self._params.get(name)

    # -- calls (blocking) ---------------------------------------------------------------

    def load(self, node: str) -> list[params.Described]:
        """Choose ``node`` and read its parameters with their descriptors (blocking).

        Recorded (not live): ``node`` is chosen, its parameters show as the log's events
        tell them, and NotLive says that nothing more can be read."""
        check_name(node, what="node name")
        if not self.robot.contains(node):
            raise InvalidInput(f"{node} is not a node of {self.robot.label}")
        recorded = not self.source.live
        with self._lock:
            if node != self.node:
                self.node = node
                self._params, self._outcomes = {}, {}
                self.version += 1
                self.shape += 1
            self.stale = False
            if not recorded:
                self._loading += 1
        if recorded:  # chosen: its recorded changes show; describing it needs the robot
            self._check_live(f"describe the parameters of {node}")
        try:
            got = params.describe(self.source, self.robot, node)
        finally:
            with self._lock:
                self._loading -= 1
        with self._lock:
            if node != self.node:
                return got  # another node was chosen meanwhile
            fresh = {p.name: p for p in got}
            if set(fresh) != set(self._params) or any(
                fresh[n] != self._params[n] for n in fresh
            ):
                if set(fresh) != set(self._params):
                    self.shape += 1
                self._params = fresh
                self.version += 1
        return got

    def set(self, name: str, raw: object) -> Outcome:
        """Set parameter ``name`` of the chosen node to what the user entered (blocking).

        Never raises for the user's input or the node's answer: the outcome (also kept for
        :meth:`outcome`) says what happened, a veto in the node's own words.
        """
        try:
            outcome = self._set(name, raw)
        except DebugGuiError as exc:
            outcome = Outcome(False, str(exc))
        with self._lock:
            if name in self._params:
                self._outcomes[name] = outcome
                self.version += 1
        return outcome

    def _set(self, name: str, raw: object) -> Outcome:
        self._check_live(f"set {name}")
        self._policy.check_write(self._token)
        with self._lock:
            node, param = self.node, self._params.get(name)
        if node is None or param is None:
            raise InvalidInput(f"no parameter {name!r} on the chosen node")
        value = params.parse(raw, param.type)
        params.check(param, value)
        wanted = params.python_value(value)
        with self._lock:
            self._pending.setdefault(name, []).append(wanted)
            self._outcomes[name] = Outcome(
                True, f"setting to {params.format_value(wanted)}…", pending=True)
            self.version += 1
        try:
            return self._send(node, name, value)
        finally:
            with self._lock:
                waiting = self._pending.get(name, [])
                waiting.remove(wanted)
                if not waiting:
                    self._pending.pop(name, None)

    def _send(self, node: str, name: str, value: Any) -> Outcome:
        (result,) = params.set_values(self.source, self.robot, node, {name: value})
        # What the node holds now: the value set, or the old one after a veto.
        now = params.get_values(self.source, self.robot, node, [name]).get(name)
        if now is not None:
            with self._lock:
                known = self._params.get(name)
                if known is not None and node == self.node:
                    self._params[name] = known.with_value(now)
        if not result.successful:
            return Outcome(False, f"refused by {node}: {result.reason or 'no reason given'}")
        return Outcome(True, f"set to {params.format_value(params.python_value(value))}")
