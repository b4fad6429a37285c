"""The soccer demo is a robot a debugging tool can watch (issue 12): in its namespace it
publishes its callback statistics, its world-view topics are throttle-aware, and its
recorder starts and stops on request. Driven over DDS from another participant, as the
debug GUI does, against ``python -m humanoid_sim.demo`` as a user starts it."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path
from typing import Any

from geometry_msgs.msg import PointStamped, PoseStamped

from efficient_comm import Container
from efficient_comm.handle import NodeHandle
from efficient_comm.testing import isolated_domain_id, ros_env
from efficient_comm_interfaces.msg import ExecutorStats
from robot_recorder import read_messages
from robot_recorder_interfaces.msg import RecorderStatus
from robot_recorder_interfaces.srv import Start, Stop
from throttle_publisher import ThrottledSubscription, ThrottleOptions

from ._ros import child

NS = "/r7"


class Watcher:
    """What a viewer of robot ``/r7`` subscribes to, and its recorder's clients."""

    def __init__(self, node: NodeHandle) -> None:
        self.stats: list[Any] = []
        self.truth: list[Any] = []
        self.estimates: list[Any] = []
        node.create_subscription(ExecutorStats, f"{NS}/efficient_comm/stats", self.stats.append)
        slow = ThrottleOptions(max_rate_hz=2.0)
        self.subs = [
            ThrottledSubscription(node, PoseStamped, f"{NS}/ground_truth/robot",
                                  self.truth.append, options=slow),
            ThrottledSubscription(node, PointStamped, f"{NS}/ball/estimate",
                                  self.estimates.append, options=slow),
        ]
        self.start = node.create_client(Start, f"{NS}/recorder/start")
        self.stop = node.create_client(Stop, f"{NS}/recorder/stop")
        self.recorder: list[Any] = []
        node.create_subscription(RecorderStatus, f"{NS}/recorder/status", self.recorder.append)

    def recorded(self, topic: str) -> int:
        """Messages of ``topic`` the recorder's last status says it wrote."""
        last = self.recorder[-1].topics if self.recorder else ()
        return next((t.messages for t in last if t.name == topic), 0)


def _call(container: Container, client: Any, request: Any) -> Any:
    assert container.spin_until(client.service_is_ready, timeout_s=30), "no recorder service"
    future = client.call_async(request)
    assert container.spin_until(future.done, timeout_s=30)
    return future.result()


def test_demo_robot_publishes_stats_throttles_its_world_topics_and_records(
    tmp_path: Path,
) -> None:
    domain = isolated_domain_id()
    bags = tmp_path / "bags"
    demo = [sys.executable, "-m", "humanoid_sim.demo", "--duration", "0",
            "--namespace", NS.lstrip("/"), "--bag-dir", str(bags), "--report",
            str(tmp_path / "report.md")]
    with child(demo, domain_id=domain, log=tmp_path / "demo.log"), Container(
        "watcher", domain_id=domain, serve=False, stats_period_s=0
    ) as container:
        w: Watcher = container.add(Watcher, name="watcher")

        def robot_stats() -> set[str]:
            return {c.node for m in w.stats for c in m.callbacks}

        assert container.spin_until(lambda: f"{NS}/simulator" in robot_stats(), timeout_s=90), (
            (tmp_path / "demo.log").read_text())
        assert {f"{NS}/recorder", f"{NS}/ball_model"} <= robot_stats()
        assert w.stats[-1].process_name == f"{NS}/soccer"
        # Throttle-aware publishers answer on this subscriber's own reply topic, at its rate
        # (a plain publisher would send nothing there).
        assert container.spin_until(lambda: len(w.truth) >= 2 and len(w.estimates) >= 2,
                                    timeout_s=30)
        first = len(w.truth)
        container.spin_for(3.0)
        assert len(w.truth) - first <= 2 * 3.0 + 2
        assert w.stats[-1].window_ns > 0

        assert not bags.exists() or not any(bags.iterdir())  # idle until told
        started = _call(container, w.start, Start.Request())
        assert started.success, started.message
        # Until every topic asserted below is in the bag (the ball's estimate comes only while
        # the camera sees the ball, and the recorder says so once a second).
        wanted = (f"{NS}/ball/estimate", f"{NS}/ground_truth/robot", f"{NS}/joint_states")
        assert container.spin_until(lambda: all(map(w.recorded, wanted)), timeout_s=30), (
            w.recorder[-1:])
        stopped = _call(container, w.stop, Stop.Request())
        assert stopped.success, stopped.message
    recorded = {m.topic for m in read_messages(started.bag)}
    assert Path(started.bag).parent == bags
    assert set(wanted) <= recorded


def test_a_bad_namespace_is_refused_in_one_line(tmp_path: Path) -> None:
    result = subprocess.run(
        [sys.executable, "-m", "humanoid_sim.demo", "--namespace", "two words"],
        env=ros_env(isolated_domain_id()), capture_output=True, text=True, timeout=60,
        cwd=tmp_path,
    )
    assert result.returncode == 2
    assert "Traceback" not in result.stderr
    assert "--namespace" in result.stderr and "two words" in result.stderr
