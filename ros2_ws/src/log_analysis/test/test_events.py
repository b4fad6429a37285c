"""Event generators over a team log: every built-in one finds what the log holds, exactly
there and nowhere else; a failing generator leaves the others alone; events round-trip
through the sidecar MCAP that other tools read."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import pytest
from geometry_msgs.msg import PointStamped, PoseWithCovarianceStamped
from mcap.reader import make_reader
from std_msgs.msg import String

from efficient_comm_interfaces.msg import CallbackStats, ExecutorStats
from log_analysis import (
    Event,
    GeneratorError,
    LogMessage,
    LogSourceError,
    TeamLog,
    detect,
    event_generator,
    generators_from_file,
    load_generators,
    read_events,
    write_events,
)
from log_analysis.generators import (
    BallDisagreement,
    BallLost,
    Falls,
    Goals,
    LocalizationJump,
    LongCallbacks,
    RoleOscillation,
    TeamLinkSilent,
)
from log_analysis.testing import LogBuilder
from soccer_interfaces.msg import GameState, TeamInfo, TeamMessage

END = 20.0


def _pose(x: float, y: float, yaw: float) -> PoseWithCovarianceStamped:
    msg = PoseWithCovarianceStamped()
    msg.pose.pose.position.x, msg.pose.pose.position.y = float(x), float(y)
    msg.pose.pose.orientation.z, msg.pose.pose.orientation.w = math.sin(yaw / 2), math.cos(yaw / 2)
    return msg


def _point(x: float, y: float) -> PointStamped:
    msg = PointStamped()
    msg.point.x, msg.point.y = float(x), float(y)
    return msg


def _stats(max_ms: float) -> ExecutorStats:
    return ExecutorStats(window_ns=1_000_000_000, callbacks=[
        CallbackStats(node="/walk", name="cycle", max_ns=int(max_ms * 1e6), period_ns=10_000_000),
        CallbackStats(node="/walk", name="on_cmd", max_ns=50_000_000, period_ns=0)])


def _team(player: int) -> TeamMessage:
    return TeamMessage(team_number=1, player_number=player)


def _game(blue: int) -> GameState:
    return GameState(teams=[TeamInfo(team_colour=0, score=blue), TeamInfo(team_colour=1)])


def _ticks(start: float, stop: float, step: float) -> list[float]:
    return [round(start + i * step, 6) for i in range(round((stop - start) / step))]


@pytest.fixture(scope="module")
def team_log(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, LogBuilder]:
    """Two robots and the world for 20 s, each known issue staged once (the comments)."""
    path = tmp_path_factory.mktemp("log") / "match"
    with LogBuilder(path) as log:
        # blue1 falls at 5 s and stands again at 9 s; blue2 falls at 18 s for good.
        for t, state in ((0, "standing"), (5, "falling"), (5.5, "fallen"), (9, "standing")):
            log.add("blue1", "fall/state", String(data=state), t=t)
        for t, state in ((0, "standing"), (18, "falling")):
            log.add("blue2", "fall/state", String(data=state), t=t)
        for t in _ticks(0, END, 0.1):
            log.add("blue1", "localization/pose", _pose(0, 0, 0), t=t)
            # blue2 faces blue1 from 2 m; its estimate jumps 0.8 m sideways at 16 s.
            log.add("blue2", "localization/pose", _pose(2, 0.8 if t >= 16 else 0, math.pi), t=t)
        for t in _ticks(0, END, 0.25):
            # blue1 sees nothing from 4 s to 10 s; both see the ball at (1, 0) on the field,
            # except blue2 from 14 s to 15 s, which puts it at (3, 0).
            if not 4 < t < 10:
                log.add("blue1", "ball/detection", PointStamped(), t=t)
                log.add("blue1", "ball/position", _point(1, 0), t=t)
            log.add("blue2", "ball/detection", PointStamped(), t=t)
            log.add("blue2", "ball/position", _point(-1 if 14 <= t < 15 else 1, 0), t=t)
        # blue1's role flips four times in 4 s; blue2's once.
        for t, role in ((1, "striker"), (2, "supporter"), (3, "striker"), (4, "supporter"),
                        (5, "striker")):
            log.add("blue1", "role", String(data=role), t=t)
        for t, role in ((1, "striker"), (12, "supporter")):
            log.add("blue2", "role", String(data=role), t=t)
        # blue1's walk cycle (10 ms period) takes 25 ms in the windows ending at 7 and 8 s.
        for t in range(1, int(END) + 1):
            log.add("blue1", "efficient_comm/stats", _stats(25 if t in (7, 8) else 5), t=t)
        # Each hears the other at 2 Hz, but blue1 hears nothing from 12 s to 17 s.
        for t in _ticks(0, END, 0.5):
            for robot, own, other in (("blue1", 1, 2), ("blue2", 2, 1)):
                log.add(robot, "team/messages", _team(own), t=t)
                if not (robot == "blue1" and 12 <= t < 17):
                    log.add(robot, "team/messages", _team(other), t=t + 0.01)
        # Blue scores at 13 s; every robot logs its copy of the referee's broadcast too.
        for t in range(0, int(END)):
            log.add("world", "game_state", _game(1 if t >= 13 else 0), t=t)
            log.add("blue1", "game_state", _game(1 if t >= 13 else 0), t=t)
        log.add("blue1", "camera/image_raw/compressed/whatever", String(data="unread"), t=1)
    return path, log


def _found(team_log: tuple[Path, LogBuilder], *generators: Any, start_ns: int | None = None,
           end_ns: int | None = None) -> list[tuple[str, str, float, float]]:
    path, log = team_log
    detection = detect(TeamLog(path), list(generators), start_ns=start_ns, end_ns=end_ns)
    assert detection.failures == {}
    zero = log.ns(0)
    return [(e.name, e.robot, round((e.start_ns - zero) / 1e9, 2),
             round((e.end_ns - zero) / 1e9, 2)) for e in detection.events]


def test_each_built_in_generator_finds_its_issue_where_it_was_staged(team_log: Any) -> None:
    end = 20.0  # the log's last message (statistics): where open events end
    assert _found(team_log, Falls()) == [
        ("fell", "blue1", 5.0, 9.0), ("got up", "blue1", 9.0, 9.0), ("fell", "blue2", 18.0, end)]
    assert _found(team_log, BallLost(after_s=3)) == [("ball lost", "blue1", 4.0, 10.0)]
    assert _found(team_log, BallLost(after_s=7)) == []
    assert _found(team_log, RoleOscillation(switches=3, within_s=10)) == [
        ("role oscillation", "blue1", 2.0, 5.0)]
    assert _found(team_log, RoleOscillation(switches=4, within_s=10)) == []
    assert _found(team_log, LongCallbacks()) == [("callback overran", "blue1", 6.0, 8.0)]
    assert _found(team_log, BallDisagreement(max_m=1.0)) == [
        ("ball disagreement", "blue1", 14.0, 15.0)]
    assert _found(team_log, LocalizationJump(max_m=0.5)) == [
        ("localization jump", "blue2", 15.9, 16.0)]
    assert _found(team_log, LocalizationJump(max_m=1.0)) == []
    assert _found(team_log, TeamLinkSilent(after_s=3)) == [
        ("team link silent", "blue1", 11.51, 17.01)]
    assert _found(team_log, Goals()) == [("goal", "", 13.0, 13.0)]


def test_all_registered_generators_run_in_one_pass_with_their_figures(team_log: Any) -> None:
    path, _ = team_log
    generators = load_generators()
    assert {type(g).__name__ for g in generators} >= {
        "Falls", "BallLost", "RoleOscillation", "LongCallbacks", "BallDisagreement",
        "LocalizationJump", "TeamLinkSilent", "Goals"}
    detection = detect(TeamLog(path), generators)
    assert detection.failures == {}
    assert {e.name for e in detection.events} == {
        "fell", "got up", "ball lost", "role oscillation", "callback overran",
        "ball disagreement", "localization jump", "team link silent", "goal"}
    fell = next(e for e in detection.events if e.name == "fell" and e.robot == "blue1")
    assert fell.generator == "falls"
    assert fell.metadata == {"down_s": "4.00", "got_up": "true"}
    overran = next(e for e in detection.events if e.name == "callback overran")
    assert overran.metadata["max_ms"] == "25.00" and overran.metadata["callback"] == "cycle"
    # Images and other topics no generator reads are never decoded: the camera topic here
    # holds a String under an image's name and would not even decode as an image.
    assert detection.messages < 2000


def test_a_time_window_finds_only_the_events_in_it(team_log: Any) -> None:
    _, log = team_log
    assert _found(team_log, Falls(), Goals(), start_ns=log.ns(10), end_ns=log.ns(17)) == [
        ("goal", "", 13.0, 13.0)]


def test_a_generator_that_raises_is_reported_and_the_others_go_on(team_log: Any) -> None:
    path, _ = team_log
    seen = []

    @event_generator(topics=["role"], name="fragile")
    def fragile(m: LogMessage) -> list[Event]:
        seen.append(m.log_time_ns)
        if len(seen) == 3:
            raise ZeroDivisionError("third role")
        return []

    @event_generator(topics=["fall/state"], name="sloppy")
    def sloppy(m: LogMessage) -> Any:
        return ["not an event"]

    detection = detect(TeamLog(path), [fragile, sloppy, Falls()])
    assert set(detection.failures) == {"fragile", "sloppy"}
    assert "ZeroDivisionError: third role" in detection.failures["fragile"]
    assert "test_events.py" in detection.failures["fragile"]
    assert "not an Event" in detection.failures["sloppy"]
    assert len(seen) == 3  # left out after it raised
    assert [e.name for e in detection.events] == ["fell", "got up", "fell"]


def test_events_round_trip_through_a_sidecar_other_tools_read(
        team_log: Any, tmp_path: Path) -> None:
    path, _ = team_log
    events = detect(TeamLog(path), load_generators()).events
    sidecar = write_events(tmp_path / "match.events.mcap", events)
    assert read_events(sidecar) == events
    with open(sidecar, "rb") as stream:
        read = list(make_reader(stream).iter_messages())
    assert len(read) == len(events)
    schema, channel, message = read[0]
    assert schema is not None and (schema.name, schema.encoding) == ("foxglove.Event",
                                                                     "jsonschema")
    assert channel.message_encoding == "json"
    data = json.loads(message.data)
    assert set(data) == {"start_time", "end_time", "metadata"}
    assert data["start_time"]["sec"] * 10**9 + data["start_time"]["nsec"] == events[0].start_ns
    keys = {kv["key"] for kv in data["metadata"]}
    assert {"name", "robot", "description", "generator"} <= keys


def test_generators_from_a_file_and_what_a_bad_file_is_told(tmp_path: Path,
                                                            team_log: Any) -> None:
    good = tmp_path / "kicks.py"
    good.write_text(
        "from log_analysis import Event, event_generator\n\n"
        "@event_generator(topics=['role'])\n"
        "def striker(m):\n"
        "    if m.message.data == 'striker':\n"
        "        return [Event('striker', m.log_time_ns, m.log_time_ns, robot=m.robot)]\n\n"
        "GENERATORS = [striker]\n")
    (found,) = generators_from_file(good)
    assert len(detect(TeamLog(team_log[0]), [found]).events) == 4
    cases = {
        "missing.py": None,
        "broken.py": "def (:\n",
        "empty.py": "X = 1\n",
        "wrong.py": "GENERATORS = [print]\n",
        "string.py": "class G:\n    topics = 'role'\n    def __call__(self, m): return []\n"
                     "    def finish(self, end_ns): return []\nGENERATORS = [G()]\n",
    }
    for name, text in cases.items():
        if text is not None:
            (tmp_path / name).write_text(text)
        with pytest.raises(GeneratorError, match=name.replace(".", r"\.")):
            generators_from_file(tmp_path / name)
    with pytest.raises(GeneratorError, match=r"known: .*falls"):
        load_generators(names=["falls", "nonsense"])


def test_bad_logs_and_thresholds_are_refused_with_the_reason(tmp_path: Path) -> None:
    with pytest.raises(LogSourceError, match="no bag"):
        TeamLog(tmp_path / "nothing")
    junk = tmp_path / "junk.mcap"
    junk.write_bytes(b"not an mcap file at all" * 10)
    with pytest.raises(LogSourceError, match=r"junk\.mcap"):
        TeamLog(junk)
    for make in (lambda: BallLost(after_s=0), lambda: RoleOscillation(switches=0),
                 lambda: LocalizationJump(max_m=-1)):
        with pytest.raises(ValueError, match="must be positive"):
            make()


def test_one_robots_own_bag_reads_as_that_robots_part(tmp_path: Path) -> None:
    with LogBuilder(tmp_path / "own.mcap") as log:
        for t, state in ((0, "standing"), (2, "fallen"), (3, "standing")):
            log.add("", "fall/state", String(data=state), t=t)
    team = TeamLog(tmp_path / "own.mcap", robot="red2")
    assert team.robots == ["red2"]
    assert [(e.name, e.robot) for e in detect(team, [Falls()]).events] == [
        ("fell", "red2"), ("got up", "red2")]
