"""Software in the loop: the robot kicks the ball through the real servo driver.

Lockstep on a manual clock: simulator, servo driver (dynamixel-sdk on the pty), fall
detector, walk engine, kick and motion arbiter in one test container with the mutation guard
raising. The robot stands behind the ball, is asked for a kick on ``motion/kick/request``,
and the ball's way is measured in the simulator's ground truth. The statistic over many
seeds is bench/motion_bench.py's; the arbiter's rules and refused requests are tested on a
TestHandle (ros2_ws/src/humanoid_sim/test/test_motion_arbiter.py).
"""

from __future__ import annotations

import pytest
from geometry_msgs.msg import Twist
from std_msgs.msg import String

from efficient_comm.testing import TestHandle, test_container
from humanoid_sim.soccer.arbiter import LATCHED
from humanoid_sim.soccer.kick_rig import KickResult, ball_spot, compose_kicker, kick_trial

#: A kick: this far, within this angle of straight ahead. (Issue 13 asked for 2 m when the
#: ball rolled on almost without resistance; on turf-like rolling friction, 0.8 m/s², the
#: kick's 1 m/s takes the ball 0.36 to 0.56 m: docs/HUMANOID_SIM.md.)
DISTANCE_M, ANGLE_DEG = 0.3, 15.0


def _kick(side: str, *, seed: int = 0, line_noise: float = 0.01, seconds: float = 10.0,
          until_m: float | None = DISTANCE_M + 0.3, guard: bool = True) -> KickResult:
    with test_container(guard_mutation="raise" if guard else False) as container:
        robot = compose_kicker(container, simulator={
            "seed": seed, "line_noise": line_noise, "ball_position": list(ball_spot(side))})
        result = kick_trial(container, robot, side, seconds=seconds, until_m=until_m)
        assert robot.driver.status()["present"] == list(range(1, 21))
        assert not robot.simulator.pty.errors
        assert sum(s.exceptions for s in container.stats()) == 0
        assert robot.kick.refused == 0 and robot.kick.aborted == 0
        # The arbiter handed the body to the kick and took it back.
        if result.completed:
            assert robot.arbiter.changes == {("stand", "kick"): 1, ("kick", "stand"): 1}
    return result


@pytest.mark.timeout(180)
@pytest.mark.parametrize("side", ["right", "left"])
def test_kicks_the_ball_two_metres_straight_ahead(side: str) -> None:
    result = _kick(side)
    assert not result.fell, f"fell {result.fell_at_s} s after the request"
    assert result.completed
    assert result.distance_m >= DISTANCE_M, result
    assert abs(result.angle_deg) <= ANGLE_DEG, result


#: How far the joint-space swing rolls the ball on the turf-like ball, followed until it
#: rests: the spline swing's kick went 0.36 to 0.56 m (docs/HUMANOID_SIM.md).
JOINT_SWING_M = 0.75


@pytest.mark.timeout(240)
@pytest.mark.parametrize(("side", "dx"), [("left", 0.0), ("right", 0.02), ("right", -0.02)])
def test_the_joint_swing_rolls_the_ball_further_and_the_robot_stands(side: str, dx: float
                                                                     ) -> None:
    with test_container() as container:
        robot = compose_kicker(container, simulator={
            "line_noise": 0.01, "ball_position": list(ball_spot(side, dx=dx))})
        result = kick_trial(container, robot, side, seconds=8.0)
        assert robot.kick.refused == 0 and robot.kick.aborted == 0
        container.advance(1.0)  # standing on both feet again, and still
        assert robot.fall_detector.falls == 0 and robot.fall_detector.state == "standing"
    assert result.completed and not result.fell, result
    assert result.distance_m >= JOINT_SWING_M, result
    assert abs(result.angle_deg) <= ANGLE_DEG, result


@pytest.mark.timeout(180)
def test_same_seed_same_kick_another_seed_another() -> None:
    def kick(seed: int) -> KickResult:
        return _kick("right", seed=seed, line_noise=0.03, seconds=2.6, until_m=None,
                     guard=False)  # (the guard's checks run in the test above)

    first, again, other = kick(3), kick(3), kick(4)
    assert first.path == again.path and first.peak_torque == again.peak_torque
    assert first.ball_speed > 0.3  # the ball was kicked within the window compared
    assert other.path != first.path or other.peak_torque != first.peak_torque


@pytest.mark.timeout(180)
def test_a_kick_asked_for_while_walking_is_refused_and_after_the_stop_it_runs() -> None:
    with test_container(guard_mutation="raise") as container:
        robot = compose_kicker(container, simulator={"ball_position": [3.0, 2.0]})
        probe = TestHandle("probe", container=container)
        states: list[str] = []
        probe.create_subscription(String, "/robot/motion/state",
                                  lambda m: states.append(m.data), qos=LATCHED)
        cmd_vel = probe.create_publisher(Twist, "/robot/cmd_vel", qos=10)
        request = probe.create_publisher(String, "/robot/motion/kick/request", qos=10)

        def kicking() -> bool:  # a call: mypy does not narrow it between the steps
            return robot.kick.active

        container.advance(1.0)
        walk = Twist()
        walk.linear.x = 0.15
        cmd_vel.publish(walk)
        container.advance(1.5)
        assert robot.arbiter.state == "walk"
        request.publish(String(data="left"))
        container.advance(0.05)
        assert robot.kick.refused == 1 and not kicking()
        cmd_vel.publish(Twist())
        for _ in range(300):  # the walk slows down and lowers its steps: at most 3 s
            if robot.arbiter.state == "stand":
                break
            container.advance(0.01)
        assert robot.arbiter.state == "stand"
        container.advance(0.5)  # the blend into the stance
        request.publish(String(data="left"))
        container.advance(0.05)
        assert kicking()
        while kicking():
            container.advance(0.1)
        container.advance(0.5)
        assert robot.kick.kicks == 1 and robot.fall_detector.falls == 0
        assert states == ["stand", "walk", "stand", "kick", "stand"]
        assert sum(s.exceptions for s in container.stats()) == 0
