"""The team match's world process: the world, the team referee, and each robot's sensors
delivered on that robot's own DDS domain.

Started by :mod:`.match` (one per match) with one JSON argument, the plan
(:func:`.match.world_plan`). It hosts, in one container on the world's domain, the
:class:`~.world_simulator.WorldSimulator` (robots' servo buses on ptys linked under
``port_dir``) and the :class:`~.soccer.team_referee.TeamReferee`; per robot a
:class:`SensorLink` holds a DDS participant on that robot's domain and forwards what the
robot's own hardware and radio would give it, under ``/<robot>/device/``: its camera
(``camera/image_raw``, ``camera/camera_info``), its IMU (``imu/data``), the
GameController's broadcast (``game_state``), and ground truth at 10 Hz
(``ground_truth/pose``, ``ground_truth/ball``: for the stand-in localization and the
robot's recording).

Why one participant per robot domain, here: each robot's domain is its own computer's
network, and the camera and IMU are the robot's own devices; the world is the only process
that has them. A bridge process per robot would copy every image twice more; a robot that
joined the world's domain would see every other robot's topics. The links only publish
(the servo buses are ptys), so nothing flows back from a robot's domain into the world.

Every ``status_period_s`` it prints one line ``status {json}`` on stdout: simulated time,
real-time factor, game state and its changes so far, score, goals, the distance each robot
walked (ground truth, its torso sampled every half second of simulated time: one gait
cycle, so the sway from foot to foot does not count), the world's physics and render
times, its ticks (one IMU message per robot each), the IMU messages sent to each robot
while its reader was matched, and its CPU split
(:meth:`~.world_simulator.WorldSimulator.cpu_split`).
"""

from __future__ import annotations

import contextlib
import functools
import json
import math
import sys
from typing import Any

import rclpy
from geometry_msgs.msg import PoseStamped
from rclpy.context import Context
from sensor_msgs.msg import CameraInfo, Image, Imu

from efficient_comm import Container, latched_qos, stop_on_sigterm
from efficient_comm.handle import NodeHandle
from soccer_interfaces.msg import GameState

from .soccer.team_referee import STATE_NAMES, TeamReferee
from .world_simulator import WorldSimulator

#: Where a robot's devices arrive on its domain (``/<robot>/device/imu/data``, ...); the
#: robot's :class:`~.match_robot.DeviceInput` takes each once from DDS and publishes it
#: in-process under the usual name.
DEVICE = "device"
#: The IMU's history on a robot's domain (both ends): at 100 Hz, half a second. A loaded
#: robot takes DDS samples only between its callbacks; with 10, the writer overwrote what
#: the robot had not taken yet.
IMU_DEPTH = 50


def main(argv: list[str] | None = None) -> int:
    plan: dict[str, Any] = json.loads((argv or sys.argv[1:])[0])
    robots: list[str] = plan["robots"]

    class SensorLink:
        """One robot's sensors on its own domain (see the module docstring)."""

        def __init__(self, node: NodeHandle, *, robot: str, domain_id: int) -> None:
            self.context = Context()
            rclpy.init(context=self.context, domain_id=domain_id)
            self.rnode = rclpy.create_node(f"{robot}_sensors", namespace=f"/{robot}",
                                           context=self.context)
            self._truth_every = max(1, round(plan["step_hz"] / 10.0))
            self._truth_count = 0
            pairs: list[tuple[type, str, str, Any]] = [
                (Image, f"/{robot}/camera/image_raw", "camera/image_raw", 2),
                (CameraInfo, f"/{robot}/camera/camera_info", "camera/camera_info",
                 latched_qos()),
                (Imu, f"/{robot}/imu/data", "imu/data", IMU_DEPTH),
                (GameState, "/game_state", "game_state", latched_qos()),
            ]
            #: IMU messages sent while the robot's reader was matched: what it should hear.
            self.imu_sent = 0
            for msg_type, source, target, qos in pairs:
                pub = self.rnode.create_publisher(msg_type, f"{DEVICE}/{target}", qos)
                relay = self._imu(pub) if msg_type is Imu else pub.publish
                node.create_subscription(msg_type, source, relay, qos=qos)
            pose_pub = self.rnode.create_publisher(PoseStamped, f"{DEVICE}/ground_truth/pose", 10)
            ball_pub = self.rnode.create_publisher(PoseStamped, f"{DEVICE}/ground_truth/ball", 10)
            node.create_subscription(PoseStamped, f"/ground_truth/{robot}/pose",
                                     lambda m: self._truth(pose_pub, m), qos=10)
            node.create_subscription(PoseStamped, "/ground_truth/ball",
                                     lambda m: self._truth(ball_pub, m, count=False), qos=10)

        def _imu(self, pub: Any) -> Any:
            def relay(msg: Imu) -> None:
                pub.publish(msg)
                if pub.get_subscription_count():
                    self.imu_sent += 1
            return relay

        def _truth(self, pub: Any, msg: PoseStamped, *, count: bool = True) -> None:
            if count:
                self._truth_count += 1
            if self._truth_count % self._truth_every == 0:
                pub.publish(msg)

        def close(self) -> None:
            self.rnode.destroy_node()
            self.context.try_shutdown()

    stop_on_sigterm()
    with Container("match_world", dds=True, serve=False, stats_namespace="/world") as container:
        world: WorldSimulator = container.add(WorldSimulator, name="world",
                                              parameters=plan["world"])
        referee: TeamReferee = container.add(TeamReferee, name="team_referee",
                                             parameters=plan["referee"])
        links: dict[str, SensorLink] = {
            robot: container.add(functools.partial(SensorLink, robot=robot,
                                                   domain_id=plan["domains"][robot]),
                                 name=f"{robot}_link")
            for robot in robots}
        walked = dict.fromkeys(robots, 0.0)
        last: dict[str, tuple[float, float]] = {}
        sampled_at = [-math.inf]
        # [game state, simulated s] at each change, from the referee's first state on (the
        # sampling timer may first run after a loaded start has passed it).
        states: list[list[Any]] = [[STATE_NAMES.get(referee.state, str(referee.state)), 0.0]]

        def sample() -> None:
            name = STATE_NAMES.get(referee.state, str(referee.state))
            if not states or states[-1][0] != name:
                states.append([name, round(world.sim_time_s, 2)])
            if world.sim_time_s - sampled_at[0] < 0.5:
                return
            sampled_at[0] = world.sim_time_s
            for robot in robots:
                position, _ = world.world.torso_pose(robot)
                here = (float(position[0]), float(position[1]))
                if robot in last:
                    walked[robot] += math.dist(last[robot], here)
                last[robot] = here

        def report() -> None:
            status = world.status()
            print("status " + json.dumps({
                "sim_time_s": round(world.sim_time_s, 3),
                "real_time_factor": round(status["real_time_factor"], 3),
                "skipped_s": round(status["skipped_s"], 3),
                "game_state": STATE_NAMES.get(referee.state, str(referee.state)),
                "first_half": referee.first_half,
                "score": referee.score,
                "states": states,
                "goals": [[round(t / 1e9, 1), team] for t, team in referee.goals],
                "walked_m": {r: round(v, 3) for r, v in walked.items()},
                "physics_ms": round(status["physics_ms_mean"], 3),
                "render_ms": round(status["render_ms_mean"], 3),
                "frames": status["frames"],
                "ticks": status["ticks"], "tick_hz": round(status["tick_hz"], 1),
                "imu_sent": {r: link.imu_sent for r, link in links.items()},
                "cpu_s": {k: round(v, 3) for k, v in status["cpu_s"].items()},
            }), flush=True)

        tools = container.add(lambda n: n, name="match_status")
        tools.create_timer(0.1, sample)
        tools.create_timer(plan["status_period_s"], report)
        print("ready", flush=True)
        with contextlib.suppress(KeyboardInterrupt):
            container.spin()
        report()
    return 0


if __name__ == "__main__":
    sys.exit(main())
