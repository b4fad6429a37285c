"""A robot's team layer in a process of its own, for tests/test_team_play_link.py.

TeamComm and rf_bridge composed in one container on the robot's own DDS domain (the
environment's ROS_DOMAIN_ID), on the real clock; a scripted pose (and ball, if it sees one)
stands in for localization and the ball model. Prints "ready", then a JSON status line
every 0.25 s: role, fresh teammates, the fused ball, the team link's usage.

Argument: JSON with "config" (the bridge file as a mapping), "parameters" (TeamComm's),
"pose" [x, y, theta] and "ball" ([x, y] on the field, or null: it sees no ball).
"""

from __future__ import annotations

import dataclasses
import json
import math
import sys
import time

from efficient_comm.dds import prepare_process

prepare_process()

from geometry_msgs.msg import PointStamped, PoseWithCovarianceStamped  # noqa: E402

from efficient_comm import Container, to_msg  # noqa: E402
from humanoid_sim.soccer.team_comm import TeamComm  # noqa: E402
from rf_bridge import BridgeNode, parse_config  # noqa: E402


def main() -> None:
    args = json.loads(sys.argv[1])
    x, y, theta = args["pose"]
    ball = args["ball"]
    player = args["parameters"]["player_number"]
    with Container(f"robot_{player}", dds=True, serve=False) as container:
        team: TeamComm = container.add(TeamComm, name="team_comm",
                                       parameters=args["parameters"])
        config = parse_config(args["config"])
        bridge: BridgeNode = container.add(lambda n: BridgeNode(n, config=config),
                                           name="rf_bridge")
        feeder = container.add(lambda n: n, name="feeder")
        pose_pub = feeder.create_publisher(PoseWithCovarianceStamped, "localization/pose")
        ball_pub = feeder.create_publisher(PointStamped, "ball/position")
        pose = PoseWithCovarianceStamped()
        pose.header.frame_id = "field"
        pose.pose.pose.position.x, pose.pose.pose.position.y = x, y
        pose.pose.pose.orientation.z = math.sin(theta / 2)
        pose.pose.pose.orientation.w = math.cos(theta / 2)
        pose.pose.covariance = [0.01 if i in (0, 7) else 0.0 for i in range(36)]
        print("ready", flush=True)
        next_feed = next_print = time.monotonic()
        while True:
            container.spin_once(0.02)
            now = time.monotonic()
            if now >= next_feed:
                next_feed += 0.1
                pose_pub.publish(pose)
                if ball is not None:
                    seen = PointStamped()
                    seen.header.stamp = to_msg(feeder.clock.now_ns())
                    seen.header.frame_id = "base_footprint"
                    dx, dy = ball[0] - x, ball[1] - y
                    c, s = math.cos(theta), math.sin(theta)
                    seen.point.x, seen.point.y = c * dx + s * dy, -s * dx + c * dy
                    ball_pub.publish(seen)
            if now >= next_print:
                next_print += 0.25
                mates = team.teammates.fresh(feeder.clock.now_ns())
                fused = team.ball
                usage = [dataclasses.asdict(u) for u in bridge.link_usage()]
                print(json.dumps({
                    "role": team.keeper.role.value,
                    "mates": [m.state.player for m in mates],
                    "ball": None if fused is None else [fused.x, fused.y, list(fused.sources)],
                    "usage": usage[0] if usage else None,
                }), flush=True)


if __name__ == "__main__":
    main()
