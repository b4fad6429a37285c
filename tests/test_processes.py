"""Real processes, started the way ``ros2 run`` starts them, seen by another process."""

from __future__ import annotations

import signal
import sys
from pathlib import Path

import pytest
from geometry_msgs.msg import PointStamped
from sensor_msgs.msg import Image

from efficient_comm.testing import isolated_domain_id, unique_topic
from efficient_comm_interfaces.msg import ExecutorStats
from efficient_comm_interfaces.srv import ListComponents, LoadComponent, UnloadComponent

from ._ros import Peer, child, executable, peer, wait_until


def _call(p: Peer, srv_type: type, name: str, request: object) -> object:
    client = p.node.create_client(srv_type, name)
    assert p.wait_for(client.service_is_ready), f"{name} never came up"
    future = client.call_async(request)
    assert p.wait_for(future.done)
    return future.result()


def test_standalone_component_with_remaps_and_params_file(tmp_path: Path) -> None:
    domain = isolated_domain_id()
    topic = unique_topic("image")
    params = tmp_path / "params.yaml"
    params.write_text("/**:\n  ros__parameters: {rate_hz: 50.0, width: 32, height: 24}\n")
    args: list[str | Path] = [
        executable("efficient_comm", "standalone"),
        "efficient_comm.examples.pipeline:Camera",
        "--ros-args", "-r", f"image:={topic}", "-r", "__node:=front_cam",
        "--params-file", params,
    ]
    with peer(domain) as p, child(args, domain_id=domain, log=tmp_path / "cam.log"):
        frames: list[Image] = []
        p.node.create_subscription(Image, topic, frames.append, 10)
        assert p.wait_for(lambda: len(frames) >= 3), (tmp_path / "cam.log").read_text()
        assert (frames[0].width, frames[0].height) == (32, 24)
        # Node names travel on their own discovery topic and may follow the data: wait.
        assert p.wait_for(
            lambda: ("front_cam", "/") in p.node.get_node_names_and_namespaces()
        ), p.node.get_node_names_and_namespaces()


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_idle_standalone_component_exits_cleanly_on_signals(tmp_path: Path, sig: int) -> None:
    """A component with no timer and no traffic still stops (its wait must wake for it)."""
    domain = isolated_domain_id()
    args: list[str | Path] = [
        executable("efficient_comm", "standalone"), "efficient_comm.examples.pipeline:Monitor",
        "--ros-args", "-r", "__node:=idle_monitor",
    ]
    log = tmp_path / "monitor.log"
    with peer(domain) as p, child(args, domain_id=domain, log=log) as proc:
        assert p.wait_for(
            lambda: ("idle_monitor", "/") in p.node.get_node_names_and_namespaces()
        ), log.read_text()
        proc.send_signal(sig)
        assert proc.wait(timeout=15) == 0, log.read_text()
        assert "Traceback" not in log.read_text()


DEMO_YAML = Path(__file__).resolve().parents[1] / (
    "ros2_ws/src/efficient_comm/efficient_comm/examples/demo.yaml"
)


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_container_process_exits_cleanly_on_signals(tmp_path: Path, sig: int) -> None:
    domain = isolated_domain_id()
    args: list[str | Path] = [
        executable("efficient_comm", "container"), "--config", DEMO_YAML,
        "--ros-args", "-r", "__node:=renamed", "-r", "__ns:=/r",  # as ros2 launch passes them
    ]
    log = tmp_path / "container.log"
    with peer(domain) as p, child(args, domain_id=domain, log=log) as proc:
        _call(p, ListComponents, "/r/renamed/list_components", ListComponents.Request())
        proc.send_signal(sig)
        assert proc.wait(timeout=15) == 0, log.read_text()
        assert "Traceback" not in log.read_text()


def test_container_process_serves_load_unload_list_and_publishes_to_others(
    tmp_path: Path,
) -> None:
    domain = isolated_domain_id()
    args: list[str | Path] = [
        executable("efficient_comm", "container"), "--config", DEMO_YAML, "--name", "ctr"
    ]
    log = tmp_path / "container.log"
    with peer(domain) as p, child(args, domain_id=domain, log=log):
        listed = _call(p, ListComponents, "/ctr/list_components", ListComponents.Request())
        assert list(listed.full_node_names) == [  # type: ignore[attr-defined]
            "/demo/camera", "/demo/detector", "/demo/tracker", "/demo/monitor",
        ], log.read_text()

        # Composed topics are visible to other processes, like `ros2 topic echo`.
        tracks: list[PointStamped] = []
        p.node.create_subscription(PointStamped, "/demo/track", tracks.append, 10)
        assert p.wait_for(lambda: len(tracks) >= 3), log.read_text()

        ok = _call(p, LoadComponent, "/ctr/load_component", LoadComponent.Request(
            class_path="efficient_comm.examples.pipeline:Monitor", node_name="monitor2",
            node_namespace="/demo", remap_rules=["track:=/demo/spot"],
        ))
        assert ok.success and ok.full_node_name == "/demo/monitor2"  # type: ignore[attr-defined]

        bad = _call(p, LoadComponent, "/ctr/load_component", LoadComponent.Request(
            class_path="no.such:Thing", node_name="ghost",
        ))
        assert not bad.success and "no.such" in bad.error_message  # type: ignore[attr-defined]

        dup = _call(p, LoadComponent, "/ctr/load_component", LoadComponent.Request(
            class_path="efficient_comm.examples.pipeline:Monitor", node_name="monitor2",
            node_namespace="demo", parameters_yaml="/**: {ros__parameters: {}}",
        ))
        assert not dup.success and "already taken" in dup.error_message  # type: ignore[attr-defined]
        broken = _call(p, LoadComponent, "/ctr/load_component", LoadComponent.Request(
            class_path="efficient_comm.examples.pipeline:Monitor", node_name="monitor3",
            parameters_yaml="{not: [valid",
        ))
        assert not broken.success  # type: ignore[attr-defined]

        gone = _call(p, UnloadComponent, "/ctr/unload_component",
                     UnloadComponent.Request(unique_id=ok.unique_id))  # type: ignore[attr-defined]
        assert gone.success  # type: ignore[attr-defined]
        again = _call(p, UnloadComponent, "/ctr/unload_component",
                      UnloadComponent.Request(unique_id=ok.unique_id))  # type: ignore[attr-defined]
        assert not again.success  # type: ignore[attr-defined]
        listed = _call(p, ListComponents, "/ctr/list_components", ListComponents.Request())
        assert len(listed.full_node_names) == 4  # type: ignore[attr-defined]


def test_messages_from_another_process_reach_composed_components(tmp_path: Path) -> None:
    from efficient_comm import Container
    from efficient_comm.examples.pipeline import SpotDetector

    domain = isolated_domain_id()
    topic = unique_topic("image")
    camera: list[str | Path] = [
        executable("efficient_comm", "standalone"), "efficient_comm.examples.pipeline:Camera",
        "--ros-args", "-r", f"image:={topic}", "-p", "rate_hz:=50.0",
    ]
    with (
        Container("ctr", domain_id=domain, serve=False) as container,
        child(camera, domain_id=domain, log=tmp_path / "camera.log"),
    ):
        container.add(SpotDetector, name="detector", remappings={"image": topic})
        spots: list[PointStamped] = []
        container.add(
            lambda n: n.create_subscription(PointStamped, "/spot", spots.append), name="sink"
        )
        assert container.spin_until(lambda: len(spots) >= 5, timeout_s=20), (
            tmp_path / "camera.log"
        ).read_text()
        assert all(0 <= s.point.x < 160 and 0 <= s.point.y < 120 for s in spots)


USER_PROGRAM = """
import sys
from efficient_comm import Container

class Part:
    def __init__(self, node):
        self.name = node.name
        self.timer = node.create_timer(0.01, self.first_tick)

    def first_tick(self):
        print("spinning", self.name, flush=True)
        self.timer.cancel()

    def close(self):
        print("closed", self.name, flush=True)

with Container("user", dds=sys.argv[1] == "dds", serve=False) as container:
    container.add(Part, name="a")
    container.add(Part, name="b")
    container.spin()
print("done", flush=True)
"""


@pytest.mark.parametrize("dds", ["dds", "no-dds"])
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_container_spin_in_a_users_program_stops_cleanly_on_signals(
    tmp_path: Path, sig: int, dds: str
) -> None:
    """``Container.spin()`` in the user's own program: SIGTERM unloads every component as
    Ctrl-C does (before, SIGTERM killed the process and no ``close()`` ran)."""
    program = tmp_path / "robot.py"
    program.write_text(USER_PROGRAM)
    log = tmp_path / "robot.log"
    with child([sys.executable, program, dds], domain_id=isolated_domain_id(), log=log) as proc:
        assert wait_until(lambda: "spinning b" in log.read_text(), proc), log.read_text()
        proc.send_signal(sig)
        assert proc.wait(timeout=15) == 0, log.read_text()
    lines = log.read_text().splitlines()
    assert "closed b" in lines and "closed a" in lines and lines[-1] == "done", lines
    assert "Traceback" not in log.read_text()


def test_processes_publish_their_callback_statistics_where_they_are_told(tmp_path: Path) -> None:
    """A standalone node in its namespace (``-p stats_period_s``), a container under its
    ``--stats-namespace``; a standalone node with ``stats_period_s:=0.0`` publishes none."""
    domain = isolated_domain_id()
    camera: list[str | Path] = [
        executable("efficient_comm", "standalone"), "efficient_comm.examples.pipeline:Camera",
        "--ros-args", "-r", "__ns:=/bot_a", "-p", "stats_period_s:=0.2",
    ]
    quiet: list[str | Path] = [
        executable("efficient_comm", "standalone"), "efficient_comm.examples.pipeline:Monitor",
        "--ros-args", "-r", "__ns:=/bot_q", "-p", "stats_period_s:=0.0",
    ]
    container: list[str | Path] = [
        executable("efficient_comm", "container"), "--config", DEMO_YAML, "--name", "ctr",
        "--stats-namespace", "/bot_c",
    ]
    with peer(domain) as p, child(camera, domain_id=domain, log=tmp_path / "cam.log"), child(
        quiet, domain_id=domain, log=tmp_path / "quiet.log"
    ), child(container, domain_id=domain, log=tmp_path / "ctr.log"):
        got: dict[str, list[ExecutorStats]] = {"/bot_a": [], "/bot_c": []}
        for ns, store in got.items():
            p.node.create_subscription(ExecutorStats, f"{ns}/efficient_comm/stats",
                                       store.append, 10)
        assert p.wait_for(lambda: all(len(s) >= 2 for s in got.values()), timeout_s=60), (
            (tmp_path / "cam.log").read_text() + (tmp_path / "ctr.log").read_text())
        cam = got["/bot_a"][-1]
        assert cam.process_name == "/bot_a/camera"
        assert any(c.node == "/bot_a/camera" and c.kind == "timer" and c.rate_hz > 0
                   for c in cam.callbacks)
        assert 0 < cam.window_ns < 1_000_000_000  # the 0.2 s period, not the default
        assert got["/bot_c"][-1].process_name == "/ctr"
        assert {c.node for c in got["/bot_c"][-1].callbacks} >= {"/demo/camera"}
        assert p.wait_for(lambda: ("monitor", "/bot_q") in
                          p.node.get_node_names_and_namespaces(), timeout_s=30)
        topics = dict(p.node.get_topic_names_and_types())
        assert "/bot_q/efficient_comm/stats" not in topics


def test_a_container_lists_the_nodes_on_a_topic_in_other_processes() -> None:
    """``Container.publisher_nodes`` / ``subscriber_nodes``: what a program waits on for a
    peer in another process (the split demo waits so for its perception process)."""
    from std_msgs.msg import String

    from efficient_comm import Container

    domain = isolated_domain_id()
    topic = unique_topic("graph")
    with Container("ctr", domain_id=domain, serve=False) as container, \
            peer(domain, "graph_peer") as other:
        container.add(lambda n: n.create_subscription(String, topic, lambda _: None),
                      name="listener", namespace="/me")
        assert container.publisher_nodes(topic) == []
        other.node.create_publisher(String, topic, 10)
        assert container.spin_until(lambda: "/graph_peer" in container.publisher_nodes(topic),
                                    timeout_s=20), container.publisher_nodes(topic)
        assert "/me/listener" in container.subscriber_nodes(topic)
    with Container("off", dds=False, serve=False) as offline:
        assert offline.publisher_nodes(topic) == [] == offline.subscriber_nodes(topic)
