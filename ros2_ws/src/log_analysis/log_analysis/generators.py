"""The built-in event generators: the known issues of a soccer team's logs.

Each reads the topics the robots of humanoid_sim's match record (humanoid_sim.soccer's
docstring lists them) and keeps its state per robot, so one instance serves a whole team.
Thresholds are keyword options; their defaults are what a person watching a KidSize game
would call the issue. Every event's ``robot`` is the robot it concerns, its ``metadata``
the figures behind it (as text: Foxglove's events carry strings).

======================  ==============================  =====================================
generator               reads                           marks
======================  ==============================  =====================================
:class:`Falls`          ``fall/state``                  ``fell`` (down until standing again),
                                                        ``got up`` (the instant it stands)
:class:`BallLost`       ``ball/detection``,             ``ball lost``: no detection for more
                        ``localization/pose``           than ``after_s``
:class:`RoleOscillation` ``role``                       ``role oscillation``: more than
                                                        ``switches`` changes within
                                                        ``within_s``
:class:`LongCallbacks`  ``efficient_comm/stats``        ``callback overran``: a window's
                                                        longest call beyond the callback's
                                                        period
:class:`BallDisagreement` ``ball/position``,            ``ball disagreement``: two robots'
                        ``localization/pose``           balls (on the field) more than
                                                        ``max_m`` apart
:class:`LocalizationJump` ``localization/pose``         ``localization jump``: the pose moved
                                                        more than ``max_m`` between two
                                                        estimates
:class:`TeamLinkSilent` ``team/messages``               ``team link silent``: nothing from a
                                                        teammate for more than ``after_s``
:class:`Goals`          ``/world/game_state``           ``goal``: a team's score went up
======================  ==============================  =====================================
"""

from __future__ import annotations

import math
import re
from collections import deque
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

from .events import Event
from .source import LogMessage

__all__ = ["BallDisagreement", "BallLost", "Falls", "Goals", "LocalizationJump",
           "LongCallbacks", "RoleOscillation", "TeamLinkSilent"]

_NS = 1_000_000_000


def _ns(seconds: float) -> int:
    return round(seconds * _NS)


def _positive(**values: float) -> None:
    for name, value in values.items():
        if not value > 0:
            raise ValueError(f"{name} must be positive, not {value!r}")


class Falls:
    """``fell`` from the first ``falling`` or ``fallen`` to ``standing`` again (or the end of
    the log), and ``got up`` at that instant. ``fall/state`` is latched and published on
    change, so a robot that never fell has one message and no event."""

    topics = ("fall/state",)
    name = "falls"

    def __init__(self) -> None:
        self._down_since: dict[str, int] = {}

    def __call__(self, m: LogMessage) -> Iterable[Event]:
        state = m.message.data
        if state in ("falling", "fallen"):
            self._down_since.setdefault(m.robot, m.log_time_ns)
            return ()
        since = self._down_since.pop(m.robot, None)
        if since is None or state != "standing":
            return ()
        down = (m.log_time_ns - since) / _NS
        return (Event("fell", since, m.log_time_ns, m.robot, f"{m.robot} fell, down {down:.1f} s",
                      {"down_s": f"{down:.2f}", "got_up": "true"}),
                Event("got up", m.log_time_ns, m.log_time_ns, m.robot, f"{m.robot} got up"))

    def finish(self, end_ns: int) -> Iterable[Event]:
        return [Event("fell", since, max(since, end_ns), robot,
                      f"{robot} fell and did not get up before the log ended",
                      {"got_up": "false"}) for robot, since in sorted(self._down_since.items())]


class _Silence:
    """Per robot, the last time something awaited came (or the robot's first sign of life)
    and its last sign of life: a gap longer than ``after_s`` between two is an event, and
    at the end of the log the gap up to the last sign of life."""

    event = ""

    def __init__(self, *, after_s: float = 3.0) -> None:
        _positive(after_s=after_s)
        self._after = _ns(after_s)
        self._since: dict[str, int] = {}
        self._alive: dict[str, int] = {}

    def _describe(self, robot: str, gap_s: float, ended: bool) -> tuple[str, dict[str, str]]:
        raise NotImplementedError

    def _lived(self, m: LogMessage) -> None:
        self._alive[m.robot] = m.log_time_ns
        self._since.setdefault(m.robot, m.log_time_ns)

    def _came(self, m: LogMessage) -> Iterable[Event]:
        since, self._since[m.robot] = self._since[m.robot], m.log_time_ns
        return self._gap(m.robot, since, m.log_time_ns, ended=True)

    def _gap(self, robot: str, since: int, until: int, *, ended: bool) -> Iterable[Event]:
        if until - since <= self._after:
            return ()
        description, metadata = self._describe(robot, (until - since) / _NS, ended)
        return (Event(self.event, since, until, robot, description, metadata),)

    def finish(self, end_ns: int) -> Iterable[Event]:
        return [e for robot, since in sorted(self._since.items())
                for e in self._gap(robot, since, self._alive[robot], ended=False)]


class BallLost(_Silence):
    """``ball lost`` while a robot's ball detector found nothing for more than ``after_s``:
    from its last detection (or the robot's first estimate of its pose, the sign that it
    runs) to its next (or its last pose at the end of the log)."""

    topics = ("ball/detection", "localization/pose")
    name = "ball_lost"
    event = "ball lost"

    def __call__(self, m: LogMessage) -> Iterable[Event]:
        self._lived(m)
        return self._came(m) if m.topic == "ball/detection" else ()

    def _describe(self, robot: str, gap_s: float, ended: bool) -> tuple[str, dict[str, str]]:
        return (f"{robot} did not see the ball for {gap_s:.1f} s",
                {"lost_s": f"{gap_s:.2f}", "found_again": str(ended).lower()})


class RoleOscillation:
    """``role oscillation``: more than ``switches`` role changes within ``within_s``, from
    the first change of the episode to its last; the episode ends (and the event is told)
    once ``within_s`` passes without a change. A team whose role hysteresis is set too low
    swaps striker and supporter back and forth (the dissertation's Fig. 5.11)."""

    topics = ("role",)
    name = "role_oscillation"

    def __init__(self, *, switches: int = 3, within_s: float = 10.0) -> None:
        _positive(switches=switches, within_s=within_s)
        self._k, self._t = switches, _ns(within_s)
        self._role: dict[str, str] = {}
        self._recent: dict[str, deque[int]] = {}
        self._episode: dict[str, tuple[int, int, int]] = {}  # start, last change, changes

    def __call__(self, m: LogMessage) -> Iterable[Event]:
        out = list(self._close(m.robot, m.log_time_ns))
        role, before = m.message.data, self._role.get(m.robot)
        self._role[m.robot] = role
        if before is None or role == before:
            return out
        recent = self._recent.setdefault(m.robot, deque())
        recent.append(m.log_time_ns)
        while recent and recent[0] < m.log_time_ns - self._t:
            recent.popleft()
        episode = self._episode.get(m.robot)
        if episode is not None:
            self._episode[m.robot] = (episode[0], m.log_time_ns, episode[2] + 1)
        elif len(recent) > self._k:
            self._episode[m.robot] = (recent[0], m.log_time_ns, len(recent))
        return out

    def _close(self, robot: str, now: int) -> Iterable[Event]:
        episode = self._episode.get(robot)
        if episode is None or now - episode[1] <= self._t:
            return ()
        del self._episode[robot]
        start, last, changes = episode
        return (Event("role oscillation", start, last, robot,
                      f"{robot} changed its role {changes} times in {(last - start) / _NS:.1f} s",
                      {"changes": str(changes)}),)

    def finish(self, end_ns: int) -> Iterable[Event]:
        return [e for robot in sorted(self._episode)
                for e in self._close(robot, max(end_ns, self._episode[robot][1] + self._t + 1))]


class LongCallbacks:
    """``callback overran``: a callback with a period (a timer) whose longest call in a
    statistics window took longer than the period, over the windows in a row that did."""

    topics = ("efficient_comm/stats",)
    name = "long_callbacks"

    def __init__(self) -> None:
        self._open: dict[tuple[str, str, str], tuple[int, int, int, int]] = {}

    def __call__(self, m: LogMessage) -> Iterable[Event]:
        stats = m.message
        end = m.log_time_ns
        start = end - int(stats.window_ns)
        over = set()
        for cb in stats.callbacks:
            if cb.period_ns > 0 and cb.max_ns > cb.period_ns:
                key = (m.robot, cb.node, cb.name)
                over.add(key)
                was = self._open.get(key)
                self._open[key] = (was[0] if was else start, end,
                                   max(int(cb.max_ns), was[2] if was else 0), int(cb.period_ns))
        done = [k for k in self._open if k[0] == m.robot and k not in over]
        return [self._event(k, *self._open.pop(k)) for k in done]

    @staticmethod
    def _event(key: tuple[str, str, str], start: int, end: int, longest: int,
               period: int) -> Event:
        robot, node, name = key
        return Event("callback overran", start, end, robot,
                     f"{node} {name}: {longest / 1e6:.1f} ms, period {period / 1e6:.1f} ms",
                     {"node": node, "callback": name, "max_ms": f"{longest / 1e6:.2f}",
                      "period_ms": f"{period / 1e6:.2f}"})

    def finish(self, end_ns: int) -> Iterable[Event]:
        return [self._event(k, *v) for k, v in sorted(self._open.items())]


def _yaw(q: Any) -> float:
    return math.atan2(2 * (q.w * q.z + q.x * q.y), 1 - 2 * (q.y * q.y + q.z * q.z))


@dataclass
class _Pose:
    x: float
    y: float
    yaw: float
    t: int


class BallDisagreement:
    """``ball disagreement``: two robots' beliefs of where the ball lies on the field (each
    robot's ``ball/position`` placed with its ``localization/pose``) more than ``max_m``
    apart while both are fresh (at most ``fresh_s`` old), for as long as they stay so."""

    topics = ("ball/position", "localization/pose")
    name = "ball_disagreement"

    def __init__(self, *, max_m: float = 1.0, fresh_s: float = 1.0) -> None:
        _positive(max_m=max_m, fresh_s=fresh_s)
        self._max, self._fresh = max_m, _ns(fresh_s)
        self._pose: dict[str, _Pose] = {}
        self._ball: dict[str, tuple[float, float, int]] = {}
        self._open: dict[tuple[str, str], tuple[int, int, float]] = {}

    def __call__(self, m: LogMessage) -> Iterable[Event]:
        msg = m.message
        if m.topic == "localization/pose":
            p = msg.pose.pose
            self._pose[m.robot] = _Pose(p.position.x, p.position.y, _yaw(p.orientation),
                                        m.log_time_ns)
            return self._check(m.log_time_ns)
        pose = self._pose.get(m.robot)
        if pose is None or m.log_time_ns - pose.t > self._fresh:
            return self._check(m.log_time_ns)
        c, s = math.cos(pose.yaw), math.sin(pose.yaw)
        bx, by = msg.point.x, msg.point.y
        self._ball[m.robot] = (pose.x + c * bx - s * by, pose.y + s * bx + c * by,
                               m.log_time_ns)
        return self._check(m.log_time_ns)

    def _check(self, now: int) -> list[Event]:
        fresh = {r: b for r, b in self._ball.items() if now - b[2] <= self._fresh}
        robots = sorted(fresh)
        apart = {}
        for i, a in enumerate(robots):
            for b in robots[i + 1:]:
                d = math.dist(fresh[a][:2], fresh[b][:2])
                if d > self._max:
                    apart[(a, b)] = d
        for pair, d in apart.items():
            was = self._open.get(pair)
            self._open[pair] = (was[0] if was else now, now, max(d, was[2] if was else 0.0))
        done = [p for p in self._open if p not in apart]
        return [self._event(p, *self._open.pop(p)) for p in done]

    @staticmethod
    def _event(pair: tuple[str, str], start: int, end: int, worst: float) -> Event:
        a, b = pair
        return Event("ball disagreement", start, end, a,
                     f"{a} and {b} put the ball up to {worst:.1f} m apart",
                     {"robots": f"{a},{b}", "max_m": f"{worst:.2f}"})

    def finish(self, end_ns: int) -> Iterable[Event]:
        return [self._event(p, *v) for p, v in sorted(self._open.items())]


class LocalizationJump:
    """``localization jump``: a robot's estimated pose moved more than ``max_m`` (or turned
    more than ``max_rad``) from one estimate to the next, faster than a walking robot can
    (estimates more than ``within_s`` apart are not compared)."""

    topics = ("localization/pose",)
    name = "localization_jump"

    def __init__(self, *, max_m: float = 0.5, max_rad: float = 1.0,
                 within_s: float = 0.5) -> None:
        _positive(max_m=max_m, max_rad=max_rad, within_s=within_s)
        self._max, self._max_rad, self._within = max_m, max_rad, _ns(within_s)
        self._last: dict[str, _Pose] = {}

    def __call__(self, m: LogMessage) -> Iterable[Event]:
        p = m.message.pose.pose
        now = _Pose(p.position.x, p.position.y, _yaw(p.orientation), m.log_time_ns)
        last = self._last.get(m.robot)
        self._last[m.robot] = now
        if last is None or now.t - last.t > self._within:
            return ()
        moved = math.hypot(now.x - last.x, now.y - last.y)
        turned = abs(math.remainder(now.yaw - last.yaw, math.tau))
        if moved <= self._max and turned <= self._max_rad:
            return ()
        return (Event("localization jump", last.t, now.t, m.robot,
                      f"{m.robot}'s pose jumped {moved:.2f} m, {math.degrees(turned):.0f}°",
                      {"moved_m": f"{moved:.2f}", "turned_rad": f"{turned:.2f}",
                       "from": f"{last.x:.2f},{last.y:.2f}", "to": f"{now.x:.2f},{now.y:.2f}"}),)

    def finish(self, end_ns: int) -> Iterable[Event]:
        return ()


class TeamLinkSilent(_Silence):
    """``team link silent``: a robot heard no teammate for more than ``after_s``, from the
    last message it heard to the next (or its last own message at the end of the log).

    ``team/messages`` carries a robot's own messages out and its teammates' in; its own are
    those whose player number is the number its name ends in (``blue2``: 2). The clock
    starts at the robot's first message, so a robot whose teammates never spoke shows too.
    """

    topics = ("team/messages",)
    name = "team_link_silent"
    event = "team link silent"

    def __call__(self, m: LogMessage) -> Iterable[Event]:
        number = re.search(r"(\d+)$", m.robot)
        own = number is not None and m.message.player_number == int(number.group(1))
        self._lived(m)
        return () if own else self._came(m)

    def _describe(self, robot: str, gap_s: float, ended: bool) -> tuple[str, dict[str, str]]:
        return (f"{robot} heard no teammate for {gap_s:.1f} s",
                {"silent_s": f"{gap_s:.2f}", "heard_again": str(ended).lower()})


class Goals:
    """``goal``: a team's score went up in the referee's ``game_state`` (the world's, by
    default: every robot logs its copy of the same broadcast)."""

    name = "goals"

    def __init__(self, *, topic: str = "/world/game_state") -> None:
        self.topics = (topic,)
        self._score: dict[int, int] = {}

    def __call__(self, m: LogMessage) -> Iterable[Event]:
        out = []
        for team in m.message.teams:
            before = self._score.get(team.team_colour)
            self._score[team.team_colour] = team.score
            if before is not None and team.score > before:
                colour = {0: "blue", 1: "red"}.get(team.team_colour, str(team.team_colour))
                scores = "-".join(str(self._score.get(c, 0)) for c in sorted(self._score))
                out.append(Event("goal", m.log_time_ns, m.log_time_ns, "",
                                 f"goal for {colour} ({scores})",
                                 {"team": colour, "score": str(team.score)}))
        return out

    def finish(self, end_ns: int) -> Iterable[Event]:
        return ()

