"""The simulator component alone: what it opens is closed, on close and when it fails."""

from __future__ import annotations

import math
import os
import time
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import pytest
from geometry_msgs.msg import Vector3

from efficient_comm.testing import TestHandle
from humanoid_sim import simulator
from humanoid_sim.errors import SimConfigError
from humanoid_sim.simulator import MAX_CATCH_UP, PUSH_SECONDS, Simulator


def _open_fds() -> set[str]:
    return set(os.listdir("/proc/self/fd"))


def _simulator(**parameters: Any) -> Simulator:
    return Simulator(TestHandle("sim", parameters={"camera_hz": 0.0, **parameters}))


def test_port_link_points_at_the_pty_and_goes_with_the_simulator(tmp_path: Path) -> None:
    link = tmp_path / "ttyDXL"
    link.symlink_to("/dev/pts/does-not-exist")  # stale, from a run that was killed
    before = _open_fds()
    sim = _simulator(port_link=str(link))
    assert sim.port == str(link) and os.readlink(link) == sim.pty.port
    sim.close()
    sim.close()  # twice is harmless
    assert not link.is_symlink()
    assert _open_fds() == before  # the pty's two fds are closed


def test_a_newer_simulators_link_is_left_alone(tmp_path: Path) -> None:
    link = str(tmp_path / "ttyDXL")
    old, new = _simulator(port_link=link), _simulator(port_link=link)
    old.close()
    assert os.readlink(link) == new.pty.port
    new.close()
    assert not os.path.lexists(link)


@pytest.mark.parametrize("make", ["file", "no_dir"])
def test_a_bad_port_link_is_refused_and_nothing_is_left_open(tmp_path: Path, make: str) -> None:
    target = tmp_path / "ttyUSB0"
    if make == "file":
        target.write_text("not ours")
    else:
        target = tmp_path / "missing" / "ttyDXL"
    before = _open_fds()
    with pytest.raises(SimConfigError, match="port_link"):
        _simulator(port_link=str(target))
    assert _open_fds() == before
    if make == "file":
        assert target.read_text() == "not ours"  # never replaced


def test_real_time_catches_up_a_little_and_gives_a_stall_up(
        monkeypatch: pytest.MonkeyPatch) -> None:
    wall = [100.0]  # the simulator's wall clock, moved by hand
    monkeypatch.setattr(simulator, "time", SimpleNamespace(
        monotonic=lambda: wall[0], perf_counter_ns=time.perf_counter_ns))
    sim = _simulator()
    try:
        sim._lockstep = False  # as on a wall clock

        def tick_after(seconds: float) -> float:
            wall[0] += seconds
            before = sim.sim_time_s
            sim.tick()
            return sim.sim_time_s - before

        assert tick_after(0.0) == pytest.approx(sim.period_s)  # the first tick
        assert tick_after(sim.period_s) == pytest.approx(sim.period_s)  # on time
        assert tick_after(2.5 * sim.period_s) == pytest.approx(2.5 * sim.period_s, abs=2e-3)
        assert sim.skipped_s == 0
        assert tick_after(5.0) == pytest.approx(MAX_CATCH_UP * sim.period_s, abs=2e-3)
        assert sim.skipped_s == pytest.approx(5.0 - MAX_CATCH_UP * sim.period_s, abs=2e-3)
        assert tick_after(sim.period_s) == pytest.approx(sim.period_s, abs=2e-3)  # no racing
        assert sim.real_time_factor < 0.1  # the stall shows where it belongs
    finally:
        sim.close()


def test_imu_ground_truth_and_camera_info_describe_the_same_world() -> None:
    node = TestHandle("sim", parameters={"camera_hz": 0.0, "ball_position": [2.0, 1.0]})
    sim = Simulator(node)
    try:
        node.advance(2.0)  # no driver: the limp robot sinks to the ground and lies still
        assert len(node.published("imu/data")) == 200  # every physics tick
        imu, robot = node.published("imu/data")[-1], node.published("ground_truth/robot")[-1]
        assert imu.header.stamp == robot.header.stamp
        q, r = imu.orientation, robot.pose.orientation  # the IMU sits square on the torso
        assert abs(q.w * r.w + q.x * r.x + q.y * r.y + q.z * r.z) == pytest.approx(1, abs=1e-6)
        a = imu.linear_acceleration
        assert math.sqrt(a.x**2 + a.y**2 + a.z**2) == pytest.approx(9.81, abs=0.5)  # at rest
        ball = node.published("ground_truth/ball")[-1].pose.position
        assert (ball.x, ball.y, ball.z) == pytest.approx((2.0, 1.0, 0.07), abs=1e-3)
        (info,) = node.published("camera/camera_info")
        f = (240 / 2) / math.tan(math.radians(70 / 2))  # the head camera's vertical view
        assert list(info.k) == pytest.approx([f, 0, 160, 0, f, 120, 0, 0, 1])
        assert robot.header.frame_id == "field"
    finally:
        sim.close()


def test_pushes_last_as_long_as_asked_from_a_method_a_topic_or_a_schedule() -> None:
    node = TestHandle("sim", parameters={"camera_hz": 0.0, "push_at": 0.5,
                                         "push_force": [0.0, -30.0, 0.0]})
    sim = Simulator(node)
    try:
        torso = sim.model.body("torso").id

        def force() -> list[float]:
            return [round(float(f), 6) for f in sim.data.xfrc_applied[torso, :3]]

        node.advance(0.5)
        assert force() == [0.0, 0.0, 0.0]
        node.advance(0.01)  # the tick that steps from 0.5 s on
        assert force() == [0.0, -30.0, 0.0]  # the scheduled one, at 0.5 s
        node.advance(0.1)
        assert force() == [0.0, 0.0, 0.0]  # over after PUSH_SECONDS
        node.inject("push", Vector3(x=2.0, y=0.0, z=0.5))  # an impulse, N s
        sim.push((0.0, 5.0, 0.0), duration_s=0.2)
        node.advance(0.05)
        assert force() == [2.0 / PUSH_SECONDS, 5.0, 0.5 / PUSH_SECONDS]  # they add up
        node.advance(0.1)
        assert force() == [0.0, 5.0, 0.0]  # the longer one still on
        node.advance(0.1)
        assert force() == [0.0, 0.0, 0.0]
        assert sim.status()["pushes"] == 3
        node.inject("push", Vector3(x=math.nan))
        assert force() == [0.0, 0.0, 0.0] and sim.status()["pushes"] == 3
        assert any("push ignored" in message for _, message in node.records)
        with pytest.raises(SimConfigError, match="duration"):
            sim.push((1.0, 0.0, 0.0), duration_s=0.0)
        with pytest.raises(SimConfigError, match="no body 'tail'"):
            sim.push((1.0, 0.0, 0.0), body="tail")
    finally:
        sim.close()


def test_the_camera_renders_only_frames_someone_wants_and_counts_the_rest() -> None:
    from sensor_msgs.msg import Image

    from efficient_comm.testing import test_container
    from throttle_publisher import ThrottledSubscription, ThrottleOptions

    container = test_container()
    sim = Simulator(TestHandle("sim", container=container,
                               parameters={"camera_hz": 10.0, "camera_width": 32,
                                           "camera_height": 24}))
    try:
        container.advance(0.5)
        assert sim.frames == 0 and sim.frames_skipped >= 4  # nobody subscribed: no rendering
        got: list[Image] = []
        ThrottledSubscription(TestHandle("viewer", container=container), Image,
                              "/camera/image_raw", got.append,
                              options=ThrottleOptions(every_nth=2))
        skipped = sim.frames_skipped
        container.advance(1.0)
        assert len(got) == sim.frames == 5  # every 2nd of 10 frames rendered and sent
        assert sim.frames_skipped - skipped == 5
        assert (got[0].width, got[0].height) == (32, 24)
    finally:
        sim.close()


@pytest.mark.parametrize(("side", "forward_z"), [("front", -1.0), ("back", 1.0)])
def test_lay_down_puts_the_robot_on_its_front_or_back_where_it_stands(
        side: str, forward_z: float) -> None:
    node = TestHandle("sim", parameters={"camera_hz": 0.0})
    sim = Simulator(node)
    try:
        torso = sim.model.body("torso").id
        sim.plant.data.qpos[0:2] = [1.0, -0.5]
        sim.lay_down(side, heading=0.7)
        rotation = sim.data.xmat[torso].reshape(3, 3)
        assert rotation[2, 0] == pytest.approx(forward_z, abs=1e-9)  # forward axis down/up
        assert math.atan2(rotation[1, 2], rotation[0, 2]) == pytest.approx(
            0.7 if side == "front" else 0.7 - math.pi, abs=1e-9)  # up axis along the heading
        assert list(sim.data.xpos[torso][:2]) == pytest.approx([1.0, -0.5])
        node.advance(1.0)  # dropped onto the ground and lying there
        assert sim.plant.torso_height() < 0.08
        with pytest.raises(SimConfigError, match="side"):
            sim.lay_down("sideways")
    finally:
        sim.close()
