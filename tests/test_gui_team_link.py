"""A robot reached only through rf_bridge's team link shows in the debug GUI (issue 12.4).

The robot (``python -m humanoid_sim.demo``) runs in DDS domain A with an rf_bridge whose
team link (Zenoh, TCP on loopback) carries its statistics and the world view's topics out,
the world topics throttled at the robot's ThrottledPublishers. On the GUI's side a second
rf_bridge brings the team link into domain B, which the Hub watches as a team-link domain:
the robot appears there as ``via="team link"`` and its figures arrive. Domain A is never
joined by the GUI, so whatever it sees crossed the team link. Everything is started as a
user starts it (the demo module, the ``rf_bridge`` program with its bridge file).
"""

from __future__ import annotations

import sys
import threading
import time
from pathlib import Path
from typing import Any

import yaml
from geometry_msgs.msg import PoseStamped

from debug_gui import Hub, RobotId
from efficient_comm.testing import isolated_domain_id
from efficient_comm_interfaces.msg import ExecutorStats
from rf_bridge.testing import free_port

from ._ros import child, executable

NS = "/r1"
#: The robot's topics the GUI's views need, as the team link carries them.
TOPICS: list[dict[str, Any]] = [
    {"ros2": f"{NS}/efficient_comm/stats", "type": "efficient_comm_interfaces/msg/ExecutorStats"},
    {"ros2": f"{NS}/ground_truth/robot", "type": "geometry_msgs/msg/PoseStamped",
     "throttle": {"max_rate_hz": 5.0, "mode": "publisher"}},
    {"ros2": f"{NS}/ball/estimate", "type": "geometry_msgs/msg/PointStamped",
     "throttle": {"max_rate_hz": 5.0, "mode": "publisher"}},
]


def bridge_file(path: Path, *, robot_id: str, direction: str, endpoint: str,
                listen: bool) -> Path:
    # The throttle belongs where the robot's publishers are: on the robot's side.
    topics = [t if direction == "to_peer" else {k: v for k, v in t.items() if k != "throttle"}
              for t in TOPICS]
    config = {
        "team": {"robot_id": robot_id, ("listen" if listen else "connect"): [endpoint]},
        "topics": [{**t, "peer": "team", "direction": direction} for t in topics],
    }
    path.write_text(yaml.safe_dump(config))
    return path


def test_a_robot_behind_the_team_link_shows_in_the_hub(tmp_path: Path) -> None:
    domain_a, domain_b = isolated_domain_id(), isolated_domain_id()
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    robot_bridge = bridge_file(tmp_path / "robot_bridge.yaml", robot_id="r1",
                               direction="to_peer", endpoint=endpoint, listen=True)
    gui_bridge = bridge_file(tmp_path / "gui_bridge.yaml", robot_id="gui",
                             direction="from_peer", endpoint=endpoint, listen=False)
    rf_bridge = executable("rf_bridge", "rf_bridge")
    demo = [sys.executable, "-m", "humanoid_sim.demo", "--duration", "0", "--namespace", NS,
            "--bag-dir", str(tmp_path / "bags"), "--report", str(tmp_path / "report.md")]
    with child(demo, domain_id=domain_a, log=tmp_path / "robot.log"), child(
        [rf_bridge, "--ros-args", "-p", f"config:={robot_bridge}"],
        domain_id=domain_a, log=tmp_path / "robot_bridge.log",
    ), child(
        # The GUI side's bridge publishes no statistics of its own: it is no robot.
        [rf_bridge, "--ros-args", "-p", f"config:={gui_bridge}", "-p", "stats_period_s:=0.0"],
        domain_id=domain_b, log=tmp_path / "gui_bridge.log",
    ), Hub(domains=[], team_link_domains=[domain_b], node_name="gui_test") as hub:
        expected = RobotId(domain=domain_b, namespace=NS, via="team link")
        assert hub.wait_for_robots(1, timeout_s=60) == [expected]
        assert expected.label == f"r1 @ domain {domain_b}, team link"

        stats: list[ExecutorStats] = []
        poses: list[float] = []
        got_stats = threading.Event()

        def on_stats(msg: ExecutorStats) -> None:
            stats.append(msg)
            if any(c.node == f"{NS}/simulator" for c in msg.callbacks):
                got_stats.set()

        hub.subscribe(expected, "efficient_comm/stats", ExecutorStats, on_stats, rate_hz=1.0)
        hub.subscribe(expected, "ground_truth/robot", PoseStamped,
                      lambda _msg: poses.append(time.monotonic()))
        logs = "\n".join(p.read_text(errors="replace") for p in sorted(tmp_path.glob("*.log")))
        assert got_stats.wait(90), logs
        last = stats[-1]
        assert last.process_name == f"{NS}/soccer" and last.window_ns > 0
        assert {f"{NS}/ball_detector", f"{NS}/recorder"} <= {c.node for c in last.callbacks}

        # The world view's topic crossed at the rate the robot's bridge asked the robot's
        # ThrottledPublisher for (5 Hz), not at the simulator's full rate.
        deadline = time.monotonic() + 30
        while len(poses) < 2 and time.monotonic() < deadline:
            time.sleep(0.05)
        assert len(poses) >= 2, logs
        first = len(poses)
        time.sleep(3.0)  # a measuring window, not synchronisation: count what arrives in it
        assert 1 <= len(poses) - first <= 5 * 3 + 3
        counted = hub.counters()[(expected, f"{NS}/ground_truth/robot")]
        assert counted.messages >= len(poses) and counted.bytes > 0
