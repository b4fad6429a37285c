"""debug_gui's Hub against robots in other processes, without a browser.

Robots are fake_robot processes (tests/_gui_fake_robot.py: plain rclpy, callback statistics,
a plain and a throttle-aware topic) in isolated domains; plain ROS 2 robots (no statistics)
are tests/_gui_plain_robot.py processes.
"""

from __future__ import annotations

import re
import sys
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest
from rcl_interfaces.srv import ListParameters
from rclpy.serialization import serialize_message
from std_msgs.msg import String

from debug_gui import Hub, InvalidInput, RobotId, RobotUnavailable
from debug_gui.errors import CallFailed
from debug_gui.hub import MIN_INTERVAL
from debug_gui.models.components import ComponentsModel
from debug_gui.models.parameters import ParametersModel
from debug_gui.models.topics import TopicsModel
from debug_gui.security import AccessPolicy
from efficient_comm import latched_qos
from efficient_comm.testing import isolated_domain_id, ros_env
from efficient_comm_interfaces.msg import CallbackStats, ExecutorStats

from ._gui import RobotProcess, fake_robot, started, wait_for
from ._ros import Peer, peer

PLAIN_ROBOT = Path(__file__).with_name("_gui_plain_robot.py")


def _robots(hub: Hub, expected: set[RobotId], procs: list[RobotProcess]) -> None:
    wait_for(lambda: set(hub.robots()) == expected, what=f"robots {expected}", alive=procs,
             timeout_s=40)


def test_robots_in_several_domains_and_namespaces_appear_and_disappear_live(
    tmp_path: Path,
) -> None:
    d1, d2 = isolated_domain_id(), isolated_domain_id()
    a, b, c = RobotId(d1, "/a"), RobotId(d2, "/b"), RobotId(d2, "/c")
    changes = threading.Event()
    with Hub(domains=[d1, d2]) as hub, \
            fake_robot(tmp_path, domain_id=d1, namespace="/a") as ra, \
            fake_robot(tmp_path, domain_id=d2, namespace="/b") as rb:
        hub.on_robots_changed(changes.set)
        _robots(hub, {a, b}, [ra, rb])
        assert changes.is_set()
        assert a.label == f"a @ domain {d1}"
        with fake_robot(tmp_path, domain_id=d2, namespace="/c") as rc:
            _robots(hub, {a, b, c}, [ra, rb, rc])
            # One domain, two namespaces: each robot sees only what lies under its own.
            wait_for(lambda: "/c/chatter" in hub.topics(c), what="c's topics", alive=[rc])
            assert "/b/chatter" not in hub.topics(c)
            assert all(t.startswith("/b/") for t in hub.topics(b))
            wait_for(lambda: hub.nodes(c) == ["/c/fake_robot"], what="c's nodes", alive=[rc])
            # Hidden topics (throttle requests and replies) are not listed.
            assert not any("_throttle" in t for t in hub.topics(c))
        _robots(hub, {a, b}, [ra, rb])  # c stopped: gone


@contextmanager
def plain_robot(tmp_path: Path, *, domain_id: int, namespace: str) -> Iterator[RobotProcess]:
    """A plain rclpy node (no statistics, nothing of ours) in ``namespace``."""
    log = tmp_path / f"plain_{domain_id}{namespace.replace('/', '_')}.log"
    cmd: list[str | Path] = [sys.executable, PLAIN_ROBOT, "--namespace", namespace]
    with started(cmd, env=ros_env(domain_id), log=log) as proc:
        yield RobotProcess(proc=proc, log=log, domain_id=domain_id, namespace=namespace)


def test_plain_ros2_robots_appear_with_plain_robots_only(tmp_path: Path) -> None:
    """A node in /plainbot, and one in the root namespace of another domain, are robots
    under ``plain_robots`` (not the GUIs' own nodes); without it, neither is."""
    d1, d2 = isolated_domain_id(), isolated_domain_id()
    plainbot, root = RobotId(d1, "/plainbot"), RobotId(d2, "/")
    with Hub(domains=[d1, d2], plain_robots=True) as hub, \
            Hub(domains=[d1, d2], node_name="debug_gui_other") as other, \
            plain_robot(tmp_path, domain_id=d2, namespace="/") as rr:
        with plain_robot(tmp_path, domain_id=d1, namespace="/plainbot") as rp:
            # Both GUIs see the nodes; only the one with plain_robots counts them as robots
            # (and neither GUI's own node makes the root namespace of d1 a robot).
            wait_for(lambda: other.nodes(plainbot) == ["/plainbot/plain_node"]
                     and "/plain_node" in other.nodes(root), what="the plain nodes",
                     alive=[rp, rr])
            _robots(hub, {plainbot, root}, [rp, rr])
            assert other.robots() == []
            assert root.label == f"/ @ domain {d2}"
            # Their parameters, through the parameters view's model.
            policy = AccessPolicy.for_server()
            for robot, node in ((plainbot, "/plainbot/plain_node"), (root, "/plain_node")):
                model = ParametersModel(hub, robot, policy=policy, token=None)
                wait_for(lambda m=model, n=node: n in m.nodes(),  # type: ignore[misc]
                         what=f"{node}'s parameter services", alive=[rp, rr])
                assert {p.name: p.value for p in model.load(node)}["speed"] == 1.5
            # Their topics; and the components view has nothing to wait for.
            wait_for(lambda: "/plainbot/chatter" in hub.topics(plainbot),
                     what="the plain robot's topic", alive=[rp])
            assert not hub.publishes_statistics(plainbot)
            assert not ComponentsModel(hub, plainbot).statistics_published()
        _robots(hub, {root}, [rr])  # /plainbot stopped: gone


def test_topics_are_the_published_ones_without_hidden_or_the_guis_own(
    tmp_path: Path,
) -> None:
    """As ``ros2 topic list``: no ``_`` topics (not even those the robot's statistics
    name), and no topic only the GUI subscribes to."""
    domain = isolated_domain_id()
    peer = Peer(domain)
    try:
        with Hub(domains=[domain]) as hub, \
                fake_robot(tmp_path, domain_id=domain, namespace="/r") as proc:
            robot = RobotId(domain, "/r")
            _robots(hub, {robot}, [proc])
            # A view subscribing to what the robot does not publish (the world view to a
            # plain robot's odom), and a throttled feed (its request topic is hidden).
            lonely = hub.subscribe(robot, "odom", String, print)
            counter = hub.subscribe(robot, "counter", String, lambda _m: None, rate_hz=5.0)
            wait_for(lambda: {"/r/odom", "/r/counter/_throttle"}
                     <= dict(peer.node.get_topic_names_and_types()).keys(),
                     what="the GUI's subscriptions on the graph", alive=[proc])
            topics = hub.topics(robot)
            assert {"/r/chatter", "/r/counter"} <= topics.keys()
            assert "/r/odom" not in topics
            assert not any("/_" in name for name in topics), topics
            # The robot's statistics name its throttle request subscription; still hidden.
            model = TopicsModel(hub, robot)
            stats = ExecutorStats(callbacks=[
                CallbackStats(node="/r/camera", kind="subscription", name=name, rate_hz=2.0)
                for name in ("/r/counter/_throttle", "/r/inproc")])
            model.on_stats(stats)
            listed = {t["name"] for t in model.topics()}
            assert "/r/inproc" in listed  # an in-process topic only the statistics name
            assert not any("/_" in name for name in listed), listed
            assert "/r/odom" not in listed
            lonely.close()
            counter.close()
    finally:
        peer.close()


def test_team_link_domains_mark_their_robots(tmp_path: Path) -> None:
    domain = isolated_domain_id()
    with Hub(domains=[], team_link_domains=[domain]) as hub, \
            fake_robot(tmp_path, domain_id=domain, namespace="/far") as far:
        robot = RobotId(domain, "/far", via="team link")
        _robots(hub, {robot}, [far])
        assert robot.label == f"far @ domain {domain}, team link"


def _computed(robot: RobotProcess) -> int:
    found = re.findall(r"computed (\d+)", robot.output())
    return int(found[-1]) if found else -1


def test_feeds_go_through_throttle_publisher_and_a_closed_feed_costs_nothing(
    tmp_path: Path,
) -> None:
    """The robot sends (and computes) only the view's rate; when the view goes, nothing."""
    domain = isolated_domain_id()
    with Hub(domains=[domain]) as hub, \
            fake_robot(tmp_path, domain_id=domain, namespace="/r") as proc:
        robot = RobotId(domain, "/r")
        _robots(hub, {robot}, [proc])
        wait_for(lambda: _computed(proc) == 0, what="the robot idle", alive=[proc])
        got: list[String] = []
        feed = hub.subscribe(robot, "counter", String, got.append, rate_hz=5.0)
        assert feed.throttled
        wait_for(lambda: len(got) >= 10, what="10 samples", alive=[proc])
        counted = hub.counters()[(robot, "/r/counter")]
        # The link carried only what the view asked for: nothing dropped locally.
        assert counted.messages == feed.received >= 10
        # 5 Hz of a 50 Hz source: the robot computed about a tenth of its samples.
        sent = [int(m.data.split()[1]) for m in got]
        assert sent == sorted(sent) and (sent[-1] - sent[0]) / (len(sent) - 1) < 2.5
        feed.close()
        # The first report after the close may still count samples computed before it.
        reports = proc.output().count("computed ")
        wait_for(lambda: proc.output().count("computed ") >= reports + 2,
                 what="2 more reports", alive=[proc])
        reports, after_close = proc.output().count("computed "), _computed(proc)
        wait_for(lambda: proc.output().count("computed ") >= reports + 3,
                 what="3 more reports", alive=[proc])
        # Then nothing at all: nobody wants a sample.
        assert _computed(proc) == after_close


def test_plain_publishers_are_rate_limited_locally(tmp_path: Path) -> None:
    domain = isolated_domain_id()
    with Hub(domains=[domain]) as hub, \
            fake_robot(tmp_path, domain_id=domain, namespace="/p") as proc:
        robot = RobotId(domain, "/p")
        _robots(hub, {robot}, [proc])
        got: list[String] = []
        feed = hub.subscribe(robot, "/p/chatter", String, got.append, rate_hz=2.0)
        assert not feed.throttled
        wait_for(lambda: hub.counters()[(robot, "/p/chatter")].messages >= 40,
                 what="2 s of chatter", alive=[proc])
        # 20 Hz arrive (the link pays), the view gets its 2 Hz.
        assert 1 <= feed.received <= 8
        feed.set_rate(None)
        start = feed.received
        wait_for(lambda: feed.received >= start + 20, what="every message", alive=[proc])
        feed.close()


def _requests(robot: RobotProcess) -> str:
    """The rates the robot's throttle-aware ``counter`` was asked for, as it last said."""
    found = re.findall(r"counter requests (\[[^]]*\])", robot.output())
    return found[-1] if found else ""


def test_two_feeds_of_a_topic_share_one_stream_and_each_keeps_its_rate(
    tmp_path: Path,
) -> None:
    """Two views of one plain topic: the link carries it once (the Hub's counters show one
    stream's messages), one view gets every message, the other its 2 Hz."""
    domain = isolated_domain_id()
    with Hub(domains=[domain]) as hub, \
            fake_robot(tmp_path, domain_id=domain, namespace="/p") as proc:
        robot = RobotId(domain, "/p")
        _robots(hub, {robot}, [proc])
        every: list[String] = []
        start = time.monotonic()
        all_feed = hub.subscribe(robot, "chatter", String, every.append)
        slow = hub.subscribe(robot, "/p/chatter", String, lambda _m: None, rate_hz=2.0)
        assert not all_feed.throttled and not slow.throttled
        wait_for(lambda: all_feed.received >= 40, what="2 s of chatter", alive=[proc])
        counted = hub.counters()[(robot, "/p/chatter")]
        elapsed = time.monotonic() - start
        # One stream crossed the link (two subscriptions would count each message twice).
        assert all_feed.received <= counted.messages <= all_feed.received + 1
        sizes = [len(serialize_message(m)) for m in every]
        # One stream's bytes (CDR pads each a little on the wire), not two streams'.
        assert sum(sizes) <= counted.bytes < 1.5 * sum(sizes)
        # One at least 0.9 of 0.5 s after the last: 2 Hz, not 20.
        assert 1 <= slow.received <= elapsed / (MIN_INTERVAL * 0.5) + 1
        all_feed.close()  # the other feed's stream stays
        before = slow.received
        wait_for(lambda: slow.received >= before + 2, what="2 more at 2 Hz", alive=[proc])
        slow.close()


def test_throttled_feeds_of_a_topic_send_one_request_at_the_highest_rate(
    tmp_path: Path,
) -> None:
    """The robot's throttle-aware publisher hears one subscriber asking for the fastest
    feed's rate (not one per view), follows a feed's new rate and the last close."""
    domain = isolated_domain_id()
    with Hub(domains=[domain]) as hub, \
            fake_robot(tmp_path, domain_id=domain, namespace="/r") as proc:
        robot = RobotId(domain, "/r")
        _robots(hub, {robot}, [proc])
        slow = hub.subscribe(robot, "counter", String, lambda _m: None, rate_hz=5.0)
        fast = hub.subscribe(robot, "counter", String, lambda _m: None, rate_hz=10.0)
        assert slow.throttled and fast.throttled
        wait_for(lambda: _requests(proc) == "[10.0]", what="one request at 10 Hz",
                 alive=[proc])
        wait_for(lambda: fast.received >= 20, what="2 s at 10 Hz", alive=[proc])
        counted = hub.counters()[(robot, "/r/counter")]
        # What the robot sends at the fastest feed's rate reaches that feed whole; the
        # slower one keeps about every other message.
        assert fast.received <= counted.messages <= fast.received + 1
        assert 0.3 * fast.received <= slow.received <= 0.6 * fast.received + 1
        fast.set_rate(2.0)
        wait_for(lambda: _requests(proc) == "[5.0]", what="the request down to 5 Hz",
                 alive=[proc])
        slow.close()
        wait_for(lambda: _requests(proc) == "[2.0]", what="the request down to 2 Hz",
                 alive=[proc])
        fast.close()  # the last: the shared stream goes, the robot computes nothing more
        reports = proc.output().count("computed ")
        wait_for(lambda: proc.output().count("computed ") >= reports + 2,
                 what="2 more reports", alive=[proc])
        reports, after_close = proc.output().count("computed "), _computed(proc)
        wait_for(lambda: proc.output().count("computed ") >= reports + 2,
                 what="2 more reports", alive=[proc])
        assert _computed(proc) == after_close


def test_a_view_joining_a_latched_stream_gets_its_last_message() -> None:
    """A latched topic (a robot's motion state) is sent once to the shared stream; a view
    opened later still learns the current state at once, from the stream."""
    domain = isolated_domain_id()
    robot = RobotId(domain, "/l")
    with Hub(domains=[domain]) as hub, peer(domain) as p:
        state = p.node.create_publisher(String, "/l/motion/state", latched_qos())
        state.publish(String(data="kick"))
        first: list[str] = []
        hub.subscribe(robot, "motion/state", String, lambda m: first.append(m.data),
                      qos=latched_qos())
        wait_for(lambda: first == ["kick"], what="the latched state")
        later: list[str] = []
        hub.subscribe(robot, "motion/state", String, lambda m: later.append(m.data),
                      qos=latched_qos())
        wait_for(lambda: later == ["kick"], what="the state for the later view")
        state.publish(String(data="walk"))
        wait_for(lambda: first[-1:] == later[-1:] == ["walk"], what="the next state")
        assert later == ["kick", "walk"]
        assert hub.counters()[(robot, "/l/motion/state")].messages == 2  # one stream


def test_service_calls_answer_or_fail_clearly(tmp_path: Path) -> None:
    domain = isolated_domain_id()
    with Hub(domains=[domain]) as hub, \
            fake_robot(tmp_path, domain_id=domain, namespace="/s") as proc:
        robot = RobotId(domain, "/s")
        _robots(hub, {robot}, [proc])
        answer = hub.call(robot, "fake_robot/list_parameters", ListParameters,
                          ListParameters.Request())
        assert "use_sim_time" in answer.result.names
        with pytest.raises(RobotUnavailable, match="no service /s/nothing"):
            hub.call(robot, "nothing", ListParameters, ListParameters.Request(), timeout_s=1)
        with pytest.raises(CallFailed, match="did not answer"):
            hub.call(robot, "fake_robot/slow", ListParameters, ListParameters.Request(),
                     timeout_s=2)


def test_bad_input_is_refused_with_a_clear_error() -> None:
    domain = isolated_domain_id()
    with Hub(domains=[domain]) as hub:
        robot = RobotId(domain, "/x")
        with pytest.raises(InvalidInput, match="topic name"):
            hub.subscribe(robot, "bad name", String, print)
        with pytest.raises(InvalidInput, match="rate"):
            hub.subscribe(robot, "ok", String, print, rate_hz=-1)
        with pytest.raises(RobotUnavailable, match="not one this GUI joined"):
            hub.subscribe(RobotId(domain + 1, "/x"), "ok", String, print)
        with pytest.raises(InvalidInput, match="service name"):
            hub.call(robot, "a//b", ListParameters, ListParameters.Request())
    with pytest.raises(InvalidInput, match="given both as a domain and as a team-link"):
        Hub(domains=[domain], team_link_domains=[domain])
    with pytest.raises(InvalidInput, match="namespace"):
        RobotId(domain, "robot")
    with pytest.raises(InvalidInput, match="domain"):
        RobotId(300, "/robot")
