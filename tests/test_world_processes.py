"""The team's world as a program of its own: each robot's driver, in a process of its own, opens
its robot's port; ground truth, placements and per-robot cameras over DDS."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
from geometry_msgs.msg import Point, PoseStamped, Quaternion
from sensor_msgs.msg import Image, JointState

from efficient_comm.testing import isolated_domain_id
from humanoid_sim.joints import JOINTS

from ._ros import child, executable, peer, wait_until

ROBOTS = ("blue1", "red1")


def _list(values: list[object]) -> str:
    return "[" + ",".join(str(v) for v in values) + "]"


@pytest.mark.timeout(150)
def test_drivers_in_their_own_processes_drive_their_robots_and_the_referee_places(
        tmp_path: Path) -> None:
    domain = isolated_domain_id()
    ports = tmp_path / "ports"
    ports.mkdir()
    world: list[str | Path] = [
        executable("humanoid_sim", "world"), "--ros-args",
        "-p", f"robots:={_list(list(ROBOTS))}", "-p", f"port_dir:={ports}",
        "-p", "camera_hz:=5.0", "-p", "camera_width:=64", "-p", "camera_height:=48"]
    log = tmp_path / "world.log"
    with peer(domain) as p, child(world, domain_id=domain, log=log) as proc:
        assert wait_until(lambda: "servos on" in log.read_text(), proc), log.read_text()
        assert all((ports / name).is_symlink() for name in ROBOTS)
        states: dict[str, list[JointState]] = {name: [] for name in ROBOTS}
        truth: dict[str, list[PoseStamped]] = {name: [] for name in (*ROBOTS, "ball")}
        images: list[Image] = []
        for name in ROBOTS:
            p.node.create_subscription(JointState, f"/{name}/joint_states",
                                       states[name].append, 10)
            p.node.create_subscription(PoseStamped, f"/ground_truth/{name}/pose",
                                       truth[name].append, 10)
        p.node.create_subscription(PoseStamped, "/ground_truth/ball", truth["ball"].append, 10)
        p.node.create_subscription(Image, "/red1/camera/image_raw", images.append, 2)
        drivers = [
            child([executable("humanoid_sim", "servo_driver"), "--ros-args",
                   "-r", f"__ns:=/{name}", "-p", f"port:={ports / name}",
                   "-p", f"ids:={_list(list(JOINTS))}",
                   "-p", f"joint_names:={_list(list(JOINTS.values()))}"],
                  domain_id=domain, log=tmp_path / f"{name}.log")
            for name in ROBOTS]
        with drivers[0], drivers[1]:
            # Each driver found its 20 servos on its own robot's bus.
            assert p.wait_for(lambda: all(len(s) >= 3 for s in states.values()), timeout_s=60), (
                log.read_text() + "".join((tmp_path / f"{n}.log").read_text() for n in ROBOTS))
            for name in ROBOTS:
                assert list(states[name][-1].name) == list(JOINTS.values())
            assert p.wait_for(lambda: len(images) >= 2, timeout_s=30), log.read_text()
            assert (images[-1].width, images[-1].height) == (64, 48)
            # The referee's contracts: a robot and the ball placed.
            place_robot = p.node.create_publisher(PoseStamped, "/place_robot", 10)
            place_ball = p.node.create_publisher(Point, "/place_ball", 10)
            assert p.wait_for(lambda: place_robot.get_subscription_count() > 0
                              and place_ball.get_subscription_count() > 0)
            target = PoseStamped()
            target.header.frame_id = "red1"
            target.pose.position = Point(x=2.5, y=-1.0, z=0.0)
            target.pose.orientation = Quaternion(w=math.cos(math.pi / 4), z=math.sin(math.pi / 4))
            place_robot.publish(target)
            place_ball.publish(Point(x=-2.0, y=1.5, z=0.0))

            def placed() -> bool:
                red, ball = truth["red1"][-1].pose.position, truth["ball"][-1].pose.position
                return (math.hypot(red.x - 2.5, red.y + 1.0) < 0.05
                        and math.hypot(ball.x + 2.0, ball.y - 1.5) < 0.01)

            assert p.wait_for(placed, timeout_s=20), log.read_text()
            blue = truth["blue1"][-1].pose.position
            assert math.hypot(blue.x + 1.0, blue.y) < 0.1  # the other robot stayed
    assert not any(ports.iterdir())  # the links went with the world
