"""The parameters view's model against nodes in other processes, through the Hub (no browser).

Two kinds of node, both reached only through the standard rcl_interfaces services: a plain
rclpy node (tests/_foxglove_peer.py, descriptors with ranges, a read-only parameter and an
on-set-parameters callback that vetoes) and our efficient_comm components in a container
(the example pipeline's tracker, whose on-change callback vetoes alpha outside (0, 1]).
Values are read back from the node over its own service (``params.get``), not from the
model, and changes made elsewhere are made with ``ros2 param set`` as a user types it.
"""

from __future__ import annotations

import subprocess
import sys
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest

from debug_gui import Hub, RobotId, params
from debug_gui.models.parameters import ParametersModel
from debug_gui.security import AccessPolicy
from efficient_comm.testing import (
    isolated_domain_id,
    ros_env,
    stop_process_group,
    unique_topic,
)

from ._cli import ros2
from ._gui import Process, started, wait_for, wait_for_robots
from ._ros import executable
from ._ros import peer as peer_node
from .test_gui_foxglove import Robot
from .test_processes import DEMO_YAML


@pytest.fixture
def peer() -> Iterator[Robot]:
    robot = Robot(isolated_domain_id(), "/pr", unique_topic("chatter"))
    try:
        yield robot
    finally:
        robot.close()


def _read(hub: Hub, robot: RobotId, node: str, name: str) -> object:
    """The node's value, asked over its get_parameters service."""
    return params.python_value(params.get(hub, robot, node, names=[name])[name])


def _model(hub: Hub, robot: RobotId, *, token: bool = True) -> ParametersModel:
    policy = AccessPolicy.for_server()
    return ParametersModel(hub, robot, policy=policy, token=policy.token if token else None)


def test_a_plain_rclpy_node_listed_described_set_vetoed_and_followed(peer: Robot) -> None:
    node = "/pr/detector"
    with Hub(domains=[peer.domain]) as hub:
        robot = RobotId(peer.domain, "/pr")
        wait_for_robots(hub, [robot])  # by name: the domain may hold other robots
        model = _model(hub, robot)
        wait_for(lambda: node in model.nodes(), what="the node's parameter services")
        assert model.nodes("nosuch") == []
        model.activate()

        # list + describe + get
        got = {p.name: p for p in model.load(node)}
        assert {"threshold", "count", "gain", "label", "enabled", "ids", "mode"} <= set(got)
        assert (got["count"].value, got["count"].type_name) == (3, "integer")
        assert got["count"].description == "how many"
        assert got["count"].integer_range == (0, 10, 1)
        assert got["count"].constraints() == "0..10 step 1"
        assert got["gain"].floating_point_range == (0.0, 2.0, 0.0)
        assert got["label"].read_only and got["label"].constraints() == "read-only"
        assert got["mode"].additional_constraints == "fast or slow"
        assert (got["ids"].value, got["ids"].text) == ([1, 2, 3], "[1, 2, 3]")
        assert got["enabled"].value is True and got["threshold"].value == 0.5

        # set: a number field's 7.0 for an integer, an array as text, a switch's bool
        outcome = model.set("count", 7.0)
        assert outcome.ok and outcome.message == "set to 7", outcome
        peer.expect("count 7")
        assert _read(hub, robot, node, "count") == 7
        assert model.set("ids", "[4, 5]").ok
        assert _read(hub, robot, node, "ids") == [4, 5]
        assert model.set("enabled", False).ok
        assert _read(hub, robot, node, "enabled") is False
        assert model.set("threshold", 2).ok  # a whole number for a double
        assert _read(hub, robot, node, "threshold") == 2.0

        # vetoed by the node's callback: its reason, verbatim; the value stays
        vetoed = model.set("mode", "medium")
        assert not vetoed.ok
        assert vetoed.message == "refused by /pr/detector: mode 'medium' is neither fast nor slow"
        assert model.outcome("mode") == vetoed
        assert _read(hub, robot, node, "mode") == "fast"
        assert model.value("mode").value == "fast"  # type: ignore[union-attr]

        # refused before sending: wrong type, out of range, read-only, bad array text
        for name, raw, why in [
            ("count", "seven", "expected an integer, got 'seven'"),
            ("count", 11, "count must be within 0..10, not 11"),
            ("gain", 2.5, "gain must be within 0..2, not 2.5"),
            ("label", "x", "label is read-only"),
            ("ids", "[1, oops", "expected an integer array, got '[1, oops'"),
            ("ids", "[1, 2.5]", "expected an integer array, got '[1, 2.5]'"),
            ("enabled", "maybe", "expected a boolean, got 'maybe'"),
            ("count", None, "expected an integer, got nothing"),
            ("nosuch", 1, "no parameter 'nosuch' on the chosen node"),
        ]:
            refused = model.set(name, raw)
            assert (refused.ok, refused.message) == (False, why), (name, raw)
        assert _read(hub, robot, node, "count") == 7
        assert _read(hub, robot, node, "label") == "peer"
        assert peer.last("count") == "count 7"  # nothing reached the node's callback

        # a change made elsewhere shows up (the model's own sets proved the feed matched)
        wait_for(lambda: model.events > 0, what="the model's /parameter_events feed")
        result = ros2("param", "set", node, "count", "9", domain_id=peer.domain)
        assert result.returncode == 0, result.stderr
        wait_for(lambda: model.value("count").value == 9,  # type: ignore[union-attr]
                 what="the change made with ros2 param set")
        elsewhere = model.outcome("count")
        assert elsewhere is not None and not elsewhere.here
        assert elsewhere.message == "changed elsewhere to 9"

        # Hidden, the view holds no subscription: seen from another participant.
        with peer_node(peer.domain) as other:
            def readers() -> int:
                return other.node.count_subscribers("/parameter_events")

            assert other.wait_for(lambda: readers() == 1), readers()
            model.deactivate()
            assert not model.active
            assert other.wait_for(lambda: readers() == 0), readers()


def test_without_the_token_the_model_refuses_to_write(peer: Robot) -> None:
    node = "/pr/detector"
    with Hub(domains=[peer.domain]) as hub:
        robot = RobotId(peer.domain, "/pr")
        wait_for_robots(hub, [robot])
        reader = _model(hub, robot, token=False)
        wait_for(lambda: node in reader.nodes(), what="the node's parameter services")
        assert {p.name for p in reader.load(node)} >= {"count"}  # reading needs no token
        refused = reader.set("count", 5)
        assert not refused.ok and "needs the server's token" in refused.message
        policy = AccessPolicy.for_server()
        wrong = ParametersModel(hub, robot, policy=policy, token="not-the-token")
        wrong.load(node)
        assert "needs the server's token" in wrong.set("count", 5).message
        assert _read(hub, robot, node, "count") == 3
        assert peer.last("count") is None


def test_our_components_in_a_container(tmp_path: Path) -> None:
    """The example pipeline's container: the tracker vetoes alpha outside (0, 1]."""
    domain = isolated_domain_id()
    args: list[str | Path] = [executable("efficient_comm", "container"), "--config",
                              DEMO_YAML, "--name", "params_ctr"]
    log = tmp_path / "container.log"
    with started(args, env=ros_env(domain), log=log) as proc, Hub(domains=[domain]) as hub:
        alive = [Process(proc=proc, log=log)]
        robot = RobotId(domain, "/")
        wait_for(lambda: robot in hub.robots(), what="the container's statistics",
                 alive=alive)
        model = _model(hub, robot)
        wait_for(lambda: {"/demo/tracker", "/demo/camera"} <= set(model.nodes()),
                 what="the components' parameter services", alive=alive)
        assert "/debug_gui" not in model.nodes()  # the GUI's own node is no robot's
        model.activate()

        camera = {p.name: p for p in model.load("/demo/camera")}
        assert camera["rate_hz"].value == 30.0 and camera["rate_hz"].description == "frame rate"
        # The range the component declared: shown, and checked before anything is sent.
        assert camera["rate_hz"].floating_point_range == (1.0, 1000.0, 0.0)
        assert model.set("rate_hz", 0.5).message == "rate_hz must be within 1..1000, not 0.5"
        assert camera["width"].read_only and camera["width"].value == 160
        assert model.set("width", 320).message == "width is read-only"

        tracker = {p.name: p for p in model.load("/demo/tracker")}
        assert tracker["alpha"].value == 0.6  # the container file's override
        assert tracker["alpha"].description == "0 < alpha <= 1"
        assert model.parameters() == sorted(tracker.values(), key=lambda p: p.name)
        assert model.set("alpha", 0.8).ok
        assert _read(hub, robot, "/demo/tracker", "alpha") == 0.8

        vetoed = model.set("alpha", 2.0)
        assert not vetoed.ok
        assert vetoed.message.startswith("refused by /demo/tracker: ")
        assert "alpha must be in (0, 1], got 2.0" in vetoed.message
        assert _read(hub, robot, "/demo/tracker", "alpha") == 0.8
        assert model.set("alpha", "fast").message == "expected a double, got 'fast'"

        wait_for(lambda: model.events > 0, what="the model's /parameter_events feed",
                 alive=alive)
        result = ros2("param", "set", "/demo/tracker", "alpha", "0.3", domain_id=domain)
        assert result.returncode == 0, result.stderr
        wait_for(lambda: model.value("alpha").value == 0.3,  # type: ignore[union-attr]
                 what="the change made with ros2 param set", alive=alive)


PARAM_NODE = Path(__file__).with_name("_gui_param_node.py")


def test_own_set_shows_setting_then_set_never_changed_elsewhere(tmp_path: Path) -> None:
    """Issue 18, 4f: a set in flight is ``setting to …``; the node's event of our own
    change (published before its answer) is not "changed elsewhere"; a change made
    elsewhere still is. The node (a plain rclpy one, range 0..100 from its descriptor)
    holds each set until the test lets it go."""
    domain = isolated_domain_id()
    log = tmp_path / "tuner.log"
    with log.open("wb") as out:  # the child holds its own copy
        proc = subprocess.Popen([sys.executable, str(PARAM_NODE), "--namespace", "/tn"],
                                env=ros_env(domain), stdin=subprocess.PIPE, stdout=out,
                                stderr=subprocess.STDOUT, start_new_session=True)
    node = Process(proc=proc, log=log)
    alive = [node]
    assert proc.stdin is not None

    def release() -> None:
        assert proc.stdin is not None
        proc.stdin.write(b"go\n")
        proc.stdin.flush()

    try:
        wait_for(lambda: "ready" in node.output(), what="the node", alive=alive)
        with Hub(domains=[domain]) as hub:
            robot = RobotId(domain, "/tn")
            model = _model(hub, robot)
            seen: list[tuple[object, str]] = []  # (value, outcome) after each event
            follow = model.on_event

            def on_event(event: object) -> None:
                follow(event)
                value, outcome = model.value("level"), model.outcome("level")
                seen.append((value and value.value, outcome.message if outcome else ""))

            model.on_event = on_event  # type: ignore[method-assign]
            wait_for(lambda: "/tn/tuner" in model.nodes(), what="the node's services",
                     alive=alive)
            model.activate()
            level = {p.name: p for p in model.load("/tn/tuner")}["level"]
            # The descriptor's range is known, shown and checked before anything is sent.
            assert level.integer_range == (0, 100, 1)
            assert "0..100 step 1" in level.constraints()
            refused = model.set("level", 101)
            assert (refused.ok, refused.message) == (False, "level must be within 0..100, "
                                                            "not 101")
            assert "holding" not in node.output()

            with ThreadPoolExecutor(1) as pool:
                setting = pool.submit(model.set, "level", 42)
                wait_for(lambda: "holding level 42" in node.output(),
                         what="the set to reach the node", alive=alive)
                pending = model.outcome("level")
                assert pending is not None and pending.pending and pending.ok, pending
                assert pending.message == "setting to 42…"
                release()
                done = setting.result(timeout=30)
            assert (done.ok, done.message, done.pending) == (True, "set to 42", False)
            assert model.value("level").value == 42  # type: ignore[union-attr]
            # Our own change's event arrived (before or after the answer): never
            # reported as made elsewhere.
            wait_for(lambda: any(v == 42 for v, _ in seen), what="the event of our set",
                     alive=alive)
            assert not [m for _, m in seen if "elsewhere" in m], seen
            assert model.outcome("level") == done

            # A change made elsewhere (ros2 param set, held and let go the same way).
            with ThreadPoolExecutor(1) as pool:
                other = pool.submit(ros2, "param", "set", "/tn/tuner", "level", "7",
                                    domain_id=domain)
                wait_for(lambda: "holding level 7" in node.output(),
                         what="ros2 param set to reach the node", alive=alive)
                release()
                assert other.result(timeout=60).returncode == 0
            wait_for(lambda: (o := model.outcome("level")) and not o.here,
                     what="the change made elsewhere", alive=alive)
            assert model.outcome("level").message == "changed elsewhere to 7"  # type: ignore[union-attr]
            model.deactivate()
    finally:
        stop_process_group(proc)
        if proc.stdin is not None:
            proc.stdin.close()
