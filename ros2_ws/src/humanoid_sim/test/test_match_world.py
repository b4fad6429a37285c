"""The match world's sensor links: a robot's camera is rendered only while a reader on the
robot's own DDS domain reads it (frames counted, not timed)."""

from __future__ import annotations

import functools

import rclpy
from rclpy.context import Context
from sensor_msgs.msg import Image

from efficient_comm import Container, ManualClock
from efficient_comm.testing import isolated_domain_id
from humanoid_sim.match_devices import DEVICE
from humanoid_sim.match_world import SensorLink
from humanoid_sim.world_simulator import WorldSimulator


def test_a_camera_nobody_reads_on_the_robots_domain_is_not_rendered() -> None:
    domains = {"blue1": isolated_domain_id(), "red1": isolated_domain_id()}
    reader_context = Context()
    rclpy.init(context=reader_context, domain_id=domains["blue1"])
    with Container("match_world", dds=True, serve=False, clock=ManualClock(),
                   domain_id=isolated_domain_id()) as container:
        world: WorldSimulator = container.add(WorldSimulator, name="world", parameters={
            "robots": list(domains), "camera_hz": 10.0, "camera_width": 64,
            "camera_height": 48})
        links = {robot: container.add(functools.partial(
            SensorLink, robot=robot, domain_id=domain, truth_every=10, world=world),
            name=f"{robot}_link") for robot, domain in domains.items()}
        try:
            container.advance(0.5)
            assert world.status()["frames_by_robot"] == {"blue1": 0, "red1": 0}

            # blue1's software reads its camera (as the robot's DeviceInput does).
            node = rclpy.create_node("blue1_camera_reader", context=reader_context)
            node.create_subscription(Image, f"/blue1/{DEVICE}/camera/image_raw",
                                     lambda _: None, 2)
            image_writer = links["blue1"].device_pubs[0]
            assert image_writer.topic_name == f"/blue1/{DEVICE}/camera/image_raw"
            assert container.spin_until(lambda: image_writer.get_subscription_count() > 0,
                                        timeout_s=30)
            container.advance(1.0)
            frames = world.status()["frames_by_robot"]
            assert frames["blue1"] == 10, frames
            assert frames["red1"] == 0, frames  # nobody on red1's domain: never drawn
            assert world.renderer is not None
            assert world.renderer.frames == {"blue1/head_camera": 10}
        finally:
            reader_context.try_shutdown()
