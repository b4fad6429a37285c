"""Each soccer component alone on a TestHandle: no simulator, no DDS, exact inputs."""

from __future__ import annotations

import array
import math

import cv2
import numpy as np
import pytest
from geometry_msgs.msg import PointStamped
from sensor_msgs.msg import CameraInfo, Image, JointState

from efficient_comm import to_msg
from efficient_comm.testing import TestHandle
from humanoid_sim.soccer.behaviour import SEARCH_PITCH_RAD, HeadBehaviour
from humanoid_sim.soccer.motion import NECK_LIMITS, STANCE, Motion
from humanoid_sim.soccer.vision import BallDetector
from humanoid_sim.soccer.world_model import BALL_RADIUS_M, BallModel

W, H, F = 320, 240, 200.0


def _info() -> CameraInfo:
    return CameraInfo(width=W, height=H, k=[F, 0.0, W / 2, 0.0, F, H / 2, 0.0, 0.0, 1.0])


def _image(centre: tuple[int, int] | None, radius: int = 10, stamp_ns: int = 0) -> Image:
    pixels = np.full((H, W, 3), (40, 140, 40), dtype=np.uint8)  # green field
    cv2.line(pixels, (0, 200), (W, 200), (255, 255, 255), 3)  # a white line
    if centre is not None:
        cv2.circle(pixels, centre, radius, (255, 115, 0), -1)  # orange ball
    image = Image(height=H, width=W, encoding="rgb8", step=W * 3)
    image.header.stamp = to_msg(stamp_ns)
    image.data = array.array("B", pixels.tobytes())
    return image


def test_detector_reports_the_ball_as_angles_from_the_image_centre() -> None:
    node = TestHandle("detector")
    detector = BallDetector(node)
    node.inject("camera/camera_info", _info())
    node.inject("camera/image_raw", _image((250, 60), radius=12, stamp_ns=42))
    (found,) = node.published("ball/detection")
    assert found.point.x == pytest.approx(math.atan2(W / 2 - 250, F), abs=0.01)  # right: < 0
    assert found.point.y == pytest.approx(math.atan2(60 - H / 2, F), abs=0.01)  # up: < 0
    assert found.point.z == pytest.approx(math.atan2(12, F), abs=0.01)
    assert found.header.stamp.nanosec == 42
    node.inject("camera/image_raw", _image(None))
    assert len(node.published("ball/detection")) == 1  # no ball, no detection
    assert (detector.frames, detector.detections) == (2, 1)


def test_detector_skips_images_it_cannot_read_and_says_why() -> None:
    node = TestHandle("detector")
    detector = BallDetector(node)
    bad = _image((100, 100))
    bad.encoding = "mono8"
    short = _image((100, 100))
    short.data = array.array("B", bytes(100))
    node.inject("camera/image_raw", bad, short)
    assert node.published("ball/detection") == []
    assert detector.rejected == 2
    assert sum("skipping" in text for level, text in node.records if level == "warning") == 2


def test_ball_model_adds_the_neck_angles_and_estimates_distance() -> None:
    node = TestHandle("model")
    model = BallModel(node)
    node.inject("joint_states", JointState(name=["neck_yaw", "neck_pitch"],
                                           position=[0.5, 0.3]))
    detection = PointStamped()
    detection.point.x, detection.point.y, detection.point.z = 0.1, 0.05, 0.035
    node.inject("ball/detection", detection)
    (estimate,) = node.published("ball/estimate")
    assert (estimate.point.x, estimate.point.y) == pytest.approx((0.6, 0.35))
    assert estimate.point.z == pytest.approx(BALL_RADIUS_M / math.sin(0.035))
    assert model.yaw.rate == 0.0


def test_behaviour_tracks_then_searches_when_the_ball_is_gone() -> None:
    node = TestHandle("behaviour")
    behaviour = HeadBehaviour(node)
    estimate = PointStamped()
    estimate.point.x, estimate.point.y = 0.4, 0.5
    node.inject("ball/estimate", estimate)
    assert behaviour.state == "tracking"
    assert list(node.published("head/goal")[-1].position) == [0.4, 0.5]
    node.advance(0.3)
    assert behaviour.state == "tracking"  # a short gap is not a lost ball
    node.advance(0.6)
    assert behaviour.state == "searching"
    assert node.published("head/goal")[-1].position[1] == SEARCH_PITCH_RAD


def test_motion_commands_the_stance_and_clamps_head_goals() -> None:
    node = TestHandle("motion")
    Motion(node)
    node.advance(0.05)
    stance = node.published("joint_commands")[-1]
    assert dict(zip(stance.name, stance.position, strict=True)) == STANCE
    node.inject("head/goal", JointState(name=["neck_yaw", "neck_pitch", "l_knee"],
                                        position=[9.0, -9.0, 2.0]))
    command = dict(zip(node.published("joint_commands")[-1].name,
                       node.published("joint_commands")[-1].position, strict=True))
    assert command["neck_yaw"] == NECK_LIMITS["neck_yaw"][1]
    assert command["neck_pitch"] == NECK_LIMITS["neck_pitch"][0]
    assert command["l_knee"] == STANCE["l_knee"]  # the head goal moves only the head
