"""The motion arbiter: the one owner of ``joint_commands``, choosing which motion moves the body.

Each motion (walk engine, kick, get-up) publishes whole-body goals on its own topic and says
on another whether it is under way; the arbiter forwards the goals of the one that counts,
by priority **getup > kick > walk > standing pose** (:data:`~.motion.STANCE`), with the head
behaviour's ``head/goal`` overriding the neck joints except while getting up or fallen.
A motion never has to know about the others, and the servo driver has one writer.

The fall detector's ``fall/state`` is an input: while the robot is not standing and no
get-up runs, the arbiter's state is ``fallen`` and it holds the last command it sent (a
get-up starts from there). A change of source is blended over ``blend_s``: from the command
sent last to the new source's goals, linearly, so no servo is asked to jump (the walk's
standing crouch is not the stance, for example).

Topics, relative to the robot's namespace (the contract every motion keeps):

* in: ``motion/walk``, ``motion/kick``, ``motion/getup`` (sensor_msgs/JointState, whole
  body); ``motion/<name>/active`` (std_msgs/Bool, transient local depth 1, published on
  every change); ``head/goal`` (JointState: neck_yaw, neck_pitch); ``fall/state``
  (std_msgs/String, :mod:`.fall`);
* out: ``joint_commands`` (JointState for the servo driver) and ``motion/state``
  (std_msgs/String, transient local depth 1, on every change: ``stand``, ``walk``,
  ``kick``, ``getup`` or ``fallen``).

A source's goals are forwarded as they arrive (the walk's cycle reaches the driver in the
same pass); a head goal is sent at once (image to servo goal in one pass); while standing or
fallen, the command is repeated every ``1 / rate_hz`` s. Motions are not told to stop when
a higher one takes over: the kick refuses requests unless the state is ``stand``, and the
behaviour stops the walk (``cmd_vel`` zero) and waits for ``stand`` before asking for a kick.
"""

from __future__ import annotations

from collections import Counter
from functools import partial

from builtin_interfaces.msg import Time
from sensor_msgs.msg import JointState
from std_msgs.msg import Bool, String

from efficient_comm import latched_qos, to_msg
from efficient_comm.handle import NodeHandle

from ..errors import SimConfigError
from .fall import STANDING
from .motion import NECK_LIMITS, STANCE

LATCHED = latched_qos()
#: The motions, highest priority first; each on ``motion/<name>`` and ``motion/<name>/active``.
SOURCES = ("getup", "kick", "walk")
STAND, FALLEN = "stand", "fallen"
#: Every value ``motion/state`` takes.
STATES = (STAND, "walk", "kick", "getup", FALLEN)
#: States in which the head behaviour's goals do not move the neck.
HEAD_OFF = ("getup", FALLEN)


def active_topic(source: str) -> str:
    """Where motion ``source`` says whether it is under way (std_msgs/Bool, latched)."""
    return f"motion/{source}/active"


class MotionArbiter:
    """The arbiter component (see the module's docstring for topics and rules)."""

    def __init__(self, node: NodeHandle) -> None:
        self.node = node
        rate = node.declare_parameter("rate_hz", 50.0)
        self.blend_ns = round(node.declare_parameter("blend_s", 0.3) * 1e9)
        if not 1.0 <= rate <= 1000.0 or not 0 <= self.blend_ns <= 5e9:
            raise SimConfigError(f"need 1 <= rate_hz <= 1000 and 0 <= blend_s <= 5, got "
                                 f"{rate}, {self.blend_ns / 1e9}")
        self.active = dict.fromkeys(SOURCES, False)
        self.goals: dict[str, JointState | None] = dict.fromkeys(SOURCES)
        self.standing = True
        self.state = STAND
        #: How often the state changed, and how often each (from, to) change happened.
        self.transitions = 0
        self.changes: Counter[tuple[str, str]] = Counter()
        #: The neck goal from ``head/goal`` (clamped), applied unless getting up or fallen.
        self.head: dict[str, float] = {}
        #: The last command sent (every joint).
        self.command: dict[str, float] = dict(STANCE)
        self._blend_from: dict[str, float] | None = None
        self._blend_start_ns = 0
        self.pub = node.create_publisher(JointState, "joint_commands", qos=10)
        self.state_pub = node.create_publisher(String, "motion/state", qos=LATCHED)
        for source in SOURCES:
            node.create_subscription(JointState, f"motion/{source}",
                                     partial(self._on_goals, source), qos=10)
            node.create_subscription(Bool, active_topic(source),
                                     partial(self._on_active, source), qos=LATCHED)
        node.create_subscription(JointState, "head/goal", self._on_head, qos=10)
        node.create_subscription(String, "fall/state", self._on_posture, qos=LATCHED)
        node.create_timer(1.0 / rate, self._tick)
        self.state_pub.publish(String(data=self.state))

    # -- inputs ---------------------------------------------------------------------------

    def _on_goals(self, source: str, goals: JointState) -> None:
        self.goals[source] = goals
        if self.state == source:
            self._send(goals.header.stamp)

    def _on_active(self, source: str, active: Bool) -> None:
        self.active[source] = bool(active.data)
        self._decide()

    def _on_posture(self, posture: String) -> None:
        self.standing = posture.data == STANDING
        self._decide()

    def _on_head(self, goal: JointState) -> None:
        for name, position in zip(goal.name, goal.position, strict=False):
            if name in NECK_LIMITS:
                low, high = NECK_LIMITS[name]
                self.head[name] = min(high, max(low, position))
        if self.state not in HEAD_OFF:
            self._send(goal.header.stamp, body=self.command)

    def _tick(self) -> None:
        if self.state in (STAND, FALLEN):
            self._send()

    # -- the decision ---------------------------------------------------------------------

    def _wanted(self) -> str:
        if self.active["getup"]:
            return "getup"
        if not self.standing:
            return FALLEN
        for source in SOURCES[1:]:
            if self.active[source]:
                return source
        return STAND

    def _decide(self) -> None:
        state = self._wanted()
        if state == self.state:
            return
        self.node.logger.info(f"motion: {self.state} -> {state}")
        self.changes[(self.state, state)] += 1
        self.transitions += 1
        self.state = state
        self._blend_from = dict(self.command)
        self._blend_start_ns = self.node.clock.now_ns()
        self.state_pub.publish(String(data=state))
        if state == STAND:
            self._send()

    def _target(self) -> dict[str, float] | None:
        """What the present state asks of the body; None: hold the last command."""
        if self.state == STAND:
            return STANCE
        if self.state == FALLEN:
            return None
        goals = self.goals[self.state]
        if goals is None:
            return None
        return dict(zip(goals.name, goals.position, strict=False))

    def _send(self, stamp: Time | None = None, *, body: dict[str, float] | None = None) -> None:
        """Send the present state's goals (or ``body``), blended and with the head's neck."""
        now = self.node.clock.now_ns()
        if body is None:
            target = self._target()
            command = dict(self.command)
            if target is not None:
                command.update((k, v) for k, v in target.items() if k in command)
                if self._blend_from is not None:
                    share = (now - self._blend_start_ns) / self.blend_ns if self.blend_ns else 1
                    if share >= 1.0:
                        self._blend_from = None
                    else:
                        start = self._blend_from
                        command = {k: start[k] + share * (v - start[k])
                                   for k, v in command.items()}
        else:
            command = dict(body)
        if self.state not in HEAD_OFF:
            command.update(self.head)
        self.command = command
        message = JointState(name=list(command), position=list(command.values()))
        message.header.stamp = stamp if stamp is not None else to_msg(now)
        self.pub.publish(message)

    def status(self) -> dict[str, object]:
        """The state, its transitions and which motions are under way (for reports)."""
        return {"state": self.state, "transitions": self.transitions,
                "changes": {f"{a}->{b}": n for (a, b), n in sorted(self.changes.items())},
                "active": dict(self.active)}

