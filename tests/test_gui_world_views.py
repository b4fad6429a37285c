"""The world, topics and diagnostics/log views of debug_gui, against plain rclpy peers.

The peers are separate processes nobody wrote for the GUI (tests/_gui_world_peer.py: a
plain rclpy node) next to the light robot that makes their namespace a robot
(tests/_gui_fake_robot.py). Data-side tests use the Hub and the models without a browser;
the browser tests drive ``debug_gui`` in headless chromium as a user would.
"""

from __future__ import annotations

import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest

from debug_gui import Hub, InvalidInput, RobotId
from debug_gui.models.logs import LogsModel
from debug_gui.models.topics import TopicsModel, numeric_paths, value_at
from debug_gui.models.world import WorldModel
from efficient_comm.testing import isolated_domain_id, ros_env

from ._gui import (
    RobotProcess,
    by_testid,
    choose,
    click,
    click_cell,
    fake_robot,
    gui,
    present,
    ready,
    screenshot,
    started,
    text_of,
    wait_for,
    wait_for_robots,
    wait_for_text,
)

PEER = Path(__file__).with_name("_gui_world_peer.py")


@contextmanager
def peer(tmp_path: Path, *, domain_id: int, namespace: str, x: float,
         token: str = "hello") -> Iterator[RobotProcess]:
    log = tmp_path / f"peer_{domain_id}{namespace.replace('/', '_')}.log"
    cmd: list[str | Path] = [sys.executable, PEER, "--namespace", namespace, "--x", str(x),
                             "--token", token]
    with started(cmd, env=ros_env(domain_id), log=log) as proc:
        yield RobotProcess(proc=proc, log=log, domain_id=domain_id, namespace=namespace)


@contextmanager
def robot_with_peer(tmp_path: Path, *, domain_id: int, namespace: str, x: float,
                    token: str = "hello") -> Iterator[list[RobotProcess]]:
    with fake_robot(tmp_path, domain_id=domain_id, namespace=namespace) as robot, \
            peer(tmp_path, domain_id=domain_id, namespace=namespace, x=x,
                 token=token) as p:
        yield [robot, p]


# -- data side ---------------------------------------------------------------------------


def test_world_model_places_each_robot_and_its_ball_from_odometry(tmp_path: Path) -> None:
    domain = isolated_domain_id()
    ids = [RobotId(domain, "/alpha"), RobotId(domain, "/beta")]
    # The domain already holds a robot that is none of the test's, as a reused domain id
    # can (a participant that outlived an earlier test): the view is of the test's robots,
    # awaited by name. Taking the first two robots the Hub saw, the test waited 30 s for
    # poses of such a robot (the fake robots logged "computed 0" all along: nothing here
    # asks them for anything).
    with fake_robot(tmp_path, domain_id=domain, namespace="/aardvark") as other, \
            Hub(domains=[domain]) as hub:
        wait_for_robots(hub, [RobotId(domain, "/aardvark")], alive=[other])
        with robot_with_peer(tmp_path, domain_id=domain, namespace="/alpha", x=1.5) as a, \
                robot_with_peer(tmp_path, domain_id=domain, namespace="/beta", x=-2.0) as b:
            alive = [other, *a, *b]
            wait_for_robots(hub, ids, alive=alive)
            ready(alive)
            model = WorldModel(hub, ids)
            model.activate()
            try:
                states = wait_for(
                    lambda: (s := model.states()) and all(
                        x.pose is not None and x.ball is not None and x.true_pose is not None
                        and x.motion for x in s) and s,
                    what="poses, balls and motion states of both robots", alive=alive)
            finally:
                model.deactivate()
            alpha, beta = states
            assert alpha.colour != beta.colour
            assert alpha.pose_source == beta.pose_source == "odom"
            # Published once before the view existed: latched, so the view learns it.
            assert alpha.motion == beta.motion == "walk"
            # Odometry is anchored where it first met ground truth (0.1 m further along x).
            assert alpha.pose is not None and beta.pose is not None
            assert alpha.pose.x == pytest.approx(1.6, abs=1e-6)
            assert beta.pose.x == pytest.approx(-1.9, abs=1e-6)
            assert alpha.pose.y == pytest.approx(-1.0, abs=1e-6)
            # The ball 1 m straight ahead of a robot facing +y.
            assert alpha.ball == pytest.approx((1.6, 0.0), abs=1e-6)
            # The team ball: the two estimates at equal distance, so their mean.
            team = model.team_ball(states)
            assert team == pytest.approx(((1.6 - 1.9) / 2, 0.0), abs=1e-6)
            assert not model.active


def test_logs_model_keeps_a_robots_records_and_statuses_and_filters(tmp_path: Path) -> None:
    domain = isolated_domain_id()
    with robot_with_peer(tmp_path, domain_id=domain, namespace="/alpha", x=0,
                         token="alphatok") as a, \
            robot_with_peer(tmp_path, domain_id=domain, namespace="/beta", x=0,
                            token="betatok") as b, \
            Hub(domains=[domain]) as hub:
        wait_for_robots(hub, [RobotId(domain, "/alpha"), RobotId(domain, "/beta")],
                        alive=[*a, *b])
        model = LogsModel(hub, RobotId(domain, "/alpha"))
        model.activate()
        try:
            wait_for(lambda: model.logs() and model.statuses(), what="alpha's log and status",
                     alive=[*a, *b])
            records = model.logs()
            # Only alpha's peer: beta's records carry beta's logger name and stay out.
            assert all("alphatok" in r.text for r in records), records[:3]
            assert records[0].logger == "alpha.world_peer" and not records[0].shared
            assert records[0].stamp_ns >= records[-1].stamp_ns  # newest first
            [status] = model.statuses()
            assert status.name == "/alpha/world_peer: battery"
            assert status.level_name == "WARN" and ("volts", "10.9") in status.values
            # Filters: error level hides the INFO records and the WARN status; text filters.
            assert model.logs(level="error") == [] and model.statuses(level="error") == []
            assert model.logs(text="no such words") == []
            assert model.logs(text="ALPHATOK")
            with pytest.raises(InvalidInput):
                model.logs(level="loud")
        finally:
            model.deactivate()


def test_topics_model_lists_echoes_and_plots_a_plain_publisher(tmp_path: Path) -> None:
    domain = isolated_domain_id()
    with robot_with_peer(tmp_path, domain_id=domain, namespace="/alpha", x=2.5) as a, \
            Hub(domains=[domain]) as hub:
        robot = RobotId(domain, "/alpha")
        wait_for_robots(hub, [robot], alive=a)
        model = TopicsModel(hub, robot)
        model.activate()
        try:
            listed = wait_for(
                lambda: {t["name"]: t for t in model.topics()}.get("/alpha/point"),
                what="/alpha/point listed", alive=a)
            assert listed["types"] == ["geometry_msgs/msg/Point"]
            # The robot's statistics give its subscriptions' rates, and name its in-process
            # topics (the fake robot's are nowhere in the DDS graph: no type known).
            rates = wait_for(lambda: {t["name"]: t for t in model.topics()
                                      if t["rate_source"] == "robot"},
                             what="rates from the robot's statistics", alive=a)
            assert rates["/alpha/alpha_topic0"]["rate_hz"] == pytest.approx(10.0)
            assert rates["/alpha/alpha_topic0"]["types"] == []
            with pytest.raises(InvalidInput):
                model.echo("/alpha/point", "no_such_pkg/msg/Nothing")
            model.echo("point", "geometry_msgs/msg/Point")
            tree = wait_for(model.last, what="an echoed message", alive=a)
            assert tree["y"] == 2.5 and set(tree) == {"x", "y", "z"}
            assert model.fields() == ["x", "y", "z"]
            model.plot("x")
            wait_for(lambda: len(model.series()) >= 5, what="five plotted values", alive=a)
            values = [v for _, v in model.series()]
            assert values == sorted(values) and values[-1] > values[0]  # x counts up
            with pytest.raises(InvalidInput):
                model.plot("nope")
        finally:
            model.deactivate()
        assert model.echo_topic is None


def test_numeric_paths_and_value_at() -> None:
    tree = {"a": {"b": [1, 2.5, True, "x"]}, "c": 3}
    assert list(numeric_paths(tree)) == [("a.b.0", 1.0), ("a.b.1", 2.5), ("c", 3.0)]
    assert value_at(tree, "a.b.1") == 2.5
    assert value_at(tree, "a.b.2") is None and value_at(tree, "a.z") is None


# -- in the browser ----------------------------------------------------------------------


def _add_view(browser, title: str, robot_option: str) -> None:
    choose(browser, "add-kind", title)
    choose(browser, "add-robot", robot_option)
    click(browser, "add-view")


def _robot_attrs(browser, key: str) -> dict[str, str] | None:
    return browser.execute_script(  # type: ignore[no-any-return]
        "const g = document.querySelector(`[data-testid='world-robot-${arguments[0]}']`);"
        "return g && g.dataset.motion ? {x: g.dataset.x, colour: g.dataset.colour,"
        " source: g.dataset.source, motion: g.dataset.motion} : null;", key)


def test_world_view_shows_two_robots_in_two_colours(tmp_path: Path, browser) -> None:
    d1, d2 = isolated_domain_id(), isolated_domain_id()
    with robot_with_peer(tmp_path, domain_id=d1, namespace="/alpha", x=1.0) as a, \
            robot_with_peer(tmp_path, domain_id=d2, namespace="/beta", x=-3.0) as b, \
            gui(tmp_path, domains=[d1, d2]) as server:
        alive = [*a, *b, server]
        browser.get(server.url)
        wait_for_text(browser, f"beta @ domain {d2}", alive=alive)
        _add_view(browser, "World", "team: every robot")
        ka, kb = f"{d1}:/alpha", f"{d2}:/beta"
        # Until a robot's ground truth is heard its odometry is drawn unanchored (x = 1.0,
        # not the 1.1 where truth fixes the odometry frame): await the anchored drawing.
        wait_for(lambda: present(browser, f"world-ball-{ka}") and present(
            browser, "world-team-ball") and present(browser, f"world-truth-{ka}") and present(
            browser, f"world-truth-{kb}"), what="balls, team ball and ground truth", alive=alive)
        # The drawing is replaced at the display rate: read each robot's attributes at once.
        ra, rb = wait_for(lambda: (a_ := _robot_attrs(browser, ka)) and (b_ := _robot_attrs(
            browser, kb)) and (a_, b_), what="both robots drawn", alive=alive)
        assert ra["colour"] != rb["colour"]
        assert float(ra["x"]) == pytest.approx(1.1, abs=1e-3)
        assert float(rb["x"]) == pytest.approx(-2.9, abs=1e-3)
        assert ra["source"] == rb["source"] == "odom"
        assert ra["motion"] == rb["motion"] == "walk"
        screenshot(browser, "world_two_robots")


def test_log_view_shows_a_plain_nodes_line_and_the_filter_hides_it(
        tmp_path: Path, browser) -> None:
    from selenium.webdriver.common.keys import Keys

    domain = isolated_domain_id()
    with robot_with_peer(tmp_path, domain_id=domain, namespace="/alpha", x=0,
                         token="zebra") as a, gui(tmp_path, domains=[domain]) as server:
        alive = [*a, server]
        browser.get(server.url)
        key = f"{domain}:/alpha"
        wait_for_text(browser, f"alpha @ domain {domain}", alive=alive)
        _add_view(browser, "Diagnostics and log", f"alpha @ domain {domain}")
        wait_for(lambda: "peer zebra says" in text_of(browser, f"logs-records-{key}"),
                 what="the peer's log line", alive=alive)
        # Diagnostics come on their own topic, at their own rate: awaited as the log line is.
        wait_for(lambda: "battery low" in text_of(browser, f"logs-diagnostics-{key}"),
                 what="the peer's diagnostic status", alive=alive)
        box = by_testid(browser, f"logs-filter-{key}")
        if box.tag_name != "input":  # the attribute lands on the native input or its wrapper
            box = box.find_element("css selector", "input")
        box.send_keys("giraffe", Keys.TAB)
        wait_for(lambda: "peer zebra" not in text_of(browser, f"logs-records-{key}"),
                 what="the filter to hide the line", alive=alive)
        screenshot(browser, "logs_filtered")


def test_topic_echo_shows_a_field_of_a_plain_publisher(tmp_path: Path, browser) -> None:

    domain = isolated_domain_id()
    with robot_with_peer(tmp_path, domain_id=domain, namespace="/alpha", x=7.25) as a, \
            gui(tmp_path, domains=[domain]) as server:
        alive = [*a, server]
        browser.get(server.url)
        key = f"{domain}:/alpha"
        wait_for_text(browser, f"alpha @ domain {domain}", alive=alive)
        _add_view(browser, "Topics", f"alpha @ domain {domain}")
        click_cell(browser, f"topics-{key}", "/alpha/point", alive=alive)
        wait_for(lambda: "y: 7.25" in text_of(browser, f"topics-echo-{key}"),
                 what="the echoed field", alive=alive)
        # A nested message opens expanded: a field two levels down is visible at once.
        click_cell(browser, f"topics-{key}", "/alpha/ball/estimate", alive=alive)
        wait_for(lambda: "z: 1.0" in text_of(browser, f"topics-echo-{key}"),
                 what="point.z of the ball estimate, shown expanded", alive=alive)
        screenshot(browser, "topics_echo")
        assert "default-expand-all" not in server.output()
