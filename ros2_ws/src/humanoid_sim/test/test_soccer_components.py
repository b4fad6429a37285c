"""Each soccer component alone on a TestHandle: no simulator, no DDS, exact inputs."""

from __future__ import annotations

import array
import math

import cv2
import numpy as np
import pytest
from diagnostic_msgs.msg import DiagnosticStatus
from geometry_msgs.msg import PointStamped, Quaternion
from sensor_msgs.msg import CameraInfo, Image, Imu, JointState
from std_msgs.msg import String

from efficient_comm import Container, ManualClock, ParameterError, to_msg
from efficient_comm.testing import TestHandle, isolated_domain_id
from humanoid_sim.errors import SimConfigError
from humanoid_sim.soccer.behaviour import SEARCH_PITCH_RAD, HeadBehaviour
from humanoid_sim.soccer.fall import FallDetector
from humanoid_sim.soccer.vision import FALLBACK_FOVY_DEG, BallDetector
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


def test_before_camera_info_the_detector_assumes_the_head_cameras_view() -> None:
    node = TestHandle("detector")
    BallDetector(node)
    node.inject("camera/image_raw", _image((250, 60), radius=12))
    (found,) = node.published("ball/detection")
    f = (H / 2) / math.tan(math.radians(FALLBACK_FOVY_DEG / 2))  # 70° over the image height
    assert found.point.x == pytest.approx(math.atan2(W / 2 - 250, f), abs=0.01)
    assert found.point.y == pytest.approx(math.atan2(60 - H / 2, f), abs=0.01)


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


def _rotation(axis: int, angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    m = np.eye(3)
    i, j = [(1, 2), (2, 0), (0, 1)][axis]  # rotation in the plane of the other two axes
    m[i, i], m[i, j], m[j, i], m[j, j] = c, -s, s, c
    return m


@pytest.mark.parametrize(("neck_yaw", "neck_pitch"), [(0.0, 0.0), (0.5, 0.3), (-1.2, 0.9)])
def test_ball_model_turns_the_detection_by_the_neck_into_the_torso_frame(
        neck_yaw: float, neck_pitch: float) -> None:
    # A ball 40° left and 25° below the torso's forward axis (x forward, y left, z up).
    yaw, pitch = math.radians(40), math.radians(25)
    ball = np.array([math.cos(pitch) * math.cos(yaw), math.cos(pitch) * math.sin(yaw),
                     -math.sin(pitch)])
    head = _rotation(2, neck_yaw) @ _rotation(1, neck_pitch)  # yaw joint, then pitch joint
    x, y, z = head.T @ ball  # the ball seen from the head
    node = TestHandle("model")
    model = BallModel(node)
    node.inject("joint_states", JointState(name=["neck_yaw", "neck_pitch"],
                                           position=[neck_yaw, neck_pitch]))
    detection = PointStamped()
    detection.point.x, detection.point.y, detection.point.z = (
        math.atan2(y, x), math.atan2(-z, x), 0.035)  # image angles, as the detector gives
    node.inject("ball/detection", detection)
    (estimate,) = node.published("ball/estimate")
    assert (estimate.point.x, estimate.point.y) == pytest.approx((yaw, pitch), abs=1e-9)
    assert estimate.point.z == pytest.approx(BALL_RADIUS_M / math.sin(0.035))
    assert model.yaw.rate == 0.0


def test_ball_model_takes_the_neck_angle_at_the_image_time() -> None:
    node = TestHandle("model")
    BallModel(node)
    state = JointState(name=["neck_yaw", "neck_pitch"], position=[0.2, 0.0],
                       velocity=[1.0, 0.0])
    state.header.stamp = to_msg(1_000_000_000)
    node.inject("joint_states", state)
    detection = PointStamped()
    detection.header.stamp = to_msg(1_010_000_000)  # 10 ms later the neck is at 0.21
    node.inject("ball/detection", detection)
    assert node.published("ball/estimate")[-1].point.x == pytest.approx(0.21)


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


def _imu(stamp_s: float, tilt_deg: float, rate: float = 0.0, *, heading_deg: float = 0.0
         ) -> Imu:
    """The torso turned to ``heading_deg``, then tilted by ``tilt_deg`` about its y axis."""
    h, t = math.radians(heading_deg) / 2, math.radians(tilt_deg) / 2
    imu = Imu()  # q = yaw(h) * pitch(t)
    imu.orientation = Quaternion(w=math.cos(h) * math.cos(t), x=-math.sin(h) * math.sin(t),
                                 y=math.cos(h) * math.sin(t), z=math.sin(h) * math.cos(t))
    imu.angular_velocity.y = rate
    imu.header.stamp = to_msg(round(stamp_s * 1e9))
    return imu


def _feed(node: TestHandle, start_s: float, seconds: float, tilt_deg: float,
          rate: float = 0.0) -> float:
    """IMU messages at 100 Hz, as the simulator sends them; returns the time after them."""
    steps = round(seconds * 100)
    for k in range(steps):
        node.inject("imu/data", _imu(start_s + k / 100, tilt_deg, rate))
    return start_s + steps / 100


def _states(node: TestHandle) -> list[str]:
    return [m.data for m in node.published("fall/state")]


def test_fall_detector_sees_a_fall_and_a_getting_up_with_hysteresis() -> None:
    node = TestHandle("fall")
    fall = FallDetector(node)
    t = _feed(node, 0.0, 1.0, tilt_deg=5.0, rate=1.0)  # a wobble, and a head turning
    t = _feed(node, t, 1.0, tilt_deg=35.0, rate=0.2)  # leaning far, but still: not yet
    assert _states(node) == ["standing"]
    node.inject("imu/data", _imu(t, 25.0, rate=2.0))  # leaning and tipping over fast
    assert _states(node) == ["standing", "falling"] and fall.down
    node.inject("imu/data", _imu(t + 0.01, 85.0, rate=0.3, heading_deg=120))  # any heading
    assert _states(node) == ["standing", "falling", "fallen"]
    assert fall.falls == 1 and fall.fell_at_ns == [round((t + 0.01) * 1e9)]
    status = node.published("/diagnostics")[-1].status[0]
    assert (status.level, status.message, status.hardware_id) == (
        DiagnosticStatus.ERROR, "fallen", "imu")
    assert {v.key: v.value for v in status.values}["falls"] == "1"
    t = _feed(node, t + 0.02, 0.9, tilt_deg=10.0)  # upright again, not long enough yet
    t = _feed(node, t, 0.5, tilt_deg=10.0, rate=0.8)  # still moving: the wait starts anew
    t = _feed(node, t, 0.9, tilt_deg=10.0)
    assert fall.state == "fallen"
    _feed(node, t, 0.2, tilt_deg=10.0)  # a whole second upright and still
    assert _states(node)[-1] == "standing" and fall.falls == 1
    node.advance(1.0)  # and reported as such once a second
    assert node.published("/diagnostics")[-1].status[0].level == DiagnosticStatus.OK


def test_fall_detector_a_stumble_caught_in_time_is_no_fall() -> None:
    node = TestHandle("fall")
    fall = FallDetector(node)
    node.inject("imu/data", _imu(0.0, 45.0))
    assert fall.state == "falling"
    _feed(node, 0.01, 1.1, tilt_deg=3.0)
    assert _states(node) == ["standing", "falling", "standing"]
    assert fall.falls == 0  # never on the ground


def test_fall_detector_refuses_bad_thresholds_and_skips_broken_orientations() -> None:
    with pytest.raises(SimConfigError, match="fall_tilt_deg"):
        FallDetector(TestHandle("fall", parameters={"fall_tilt_deg": 10.0}))
    with pytest.raises(SimConfigError, match="rest_rate"):
        FallDetector(TestHandle("fall", parameters={"rest_rate": 0.0}))
    node = TestHandle("fall")
    fall = FallDetector(node)
    broken = _imu(0.0, 0.0)
    broken.orientation = Quaternion(w=0.0, x=0.0, y=0.0, z=0.0)
    node.inject("imu/data", broken)
    assert fall.rejected == 1 and fall.state == "standing"


def test_behaviour_stops_tracking_and_searching_while_the_robot_is_down() -> None:
    node = TestHandle("behaviour")
    behaviour = HeadBehaviour(node)
    estimate = PointStamped()
    node.inject("ball/estimate", estimate)
    assert behaviour.state == "tracking"
    node.inject("fall/state", String(data="falling"))
    assert behaviour.state == "fallen"
    node.clear_published()
    node.inject("ball/estimate", estimate)  # still seen, as the robot goes down
    node.advance(2.0)  # long past lost_after: no search either
    assert behaviour.state == "fallen" and node.published("head/goal") == []
    node.inject("fall/state", String(data="fallen"))
    node.inject("fall/state", String(data="standing"))
    assert behaviour.state == "searching"
    node.advance(0.1)
    assert node.published("head/goal")[-1].position[1] == SEARCH_PITCH_RAD


def test_detector_draws_its_layers_stamped_with_the_image_only_while_someone_looks() -> None:
    from debug_probes import read_drawing
    from efficient_comm.testing import test_container
    from efficient_comm_interfaces.msg import ImageMarkerArray

    container = test_container()
    node = TestHandle("detector", container=container)
    detector = BallDetector(node)
    node.inject("camera/camera_info", _info())
    node.inject("camera/image_raw", _image((250, 60), radius=12, stamp_ns=41))
    assert detector.drawing.skipped == 1 and detector.drawing.published == 0  # nobody looks
    got: list[ImageMarkerArray] = []
    TestHandle("viewer", container=container).create_subscription(
        ImageMarkerArray, "ball/debug_markers", got.append)
    node.inject("camera/image_raw", _image((250, 60), radius=12, stamp_ns=42))
    (msg,) = got
    assert {(m.header.stamp.sec, m.header.stamp.nanosec) for m in msg.markers} == {(0, 42)}
    drawing = read_drawing(msg)
    assert drawing.stamp_ns == 42
    assert drawing.layers == ["contours", "candidates", "choice", "internals"]
    (chosen,) = [s for s in drawing.shapes if s.layer == "choice" and s.kind == "circle"]
    assert chosen.points[0] == pytest.approx((250, 60), abs=1.5)
    assert chosen.size == pytest.approx(12, abs=1.5)
    texts = [s.text for s in drawing.shapes if s.kind == "text"]
    assert texts[0] == "1 contours" and "hue 5..22" in texts[1]


def test_detector_thresholds_changed_at_run_time_apply_to_the_next_image() -> None:
    node = TestHandle("detector")
    detector = BallDetector(node)
    node.set_parameter("hue_range", [100, 120])  # blue: the orange ball is no longer seen
    node.inject("camera/image_raw", _image((250, 60), radius=12))
    assert node.published("ball/detection") == [] and detector.hue == [100, 120]
    with pytest.raises(Exception, match="hue_range"):
        node.set_parameter("hue_range", [30, 10])
    node.set_parameter("min_radius_px", 20.0)
    node.set_parameter("hue_range", [5, 22])
    node.inject("camera/image_raw", _image((250, 60), radius=12))
    assert node.published("ball/detection") == []  # 12 px < 20 px


def test_detector_thresholds_outside_the_pixel_range_are_refused() -> None:
    """HSV saturation and value are 0..255: the range is declared, so a tool sees it and
    the store refuses what no pixel can reach (which would silently detect nothing)."""
    node = TestHandle("detector")
    detector = BallDetector(node)
    for name in ("min_saturation", "min_value"):
        with pytest.raises(ParameterError, match=name):
            node.set_parameter(name, 256)
        node.set_parameter(name, 255)
    assert (detector.min_saturation, detector.min_value) == (255, 255)
    with pytest.raises(ParameterError, match="torso_height"):
        BallModel(TestHandle("ball_model", parameters={"torso_height": 3.0}))


def test_fall_detector_on_rclpys_logger_says_standing_again() -> None:
    # rclpy's logger refuses one call site logging at two severities: the warning of the
    # fall and the info of getting up must come from lines of their own, or getting up
    # raises before `standing` is published (the team match's robots lay "fallen" forever).
    with Container("fall_rclpy", dds=True, domain_id=isolated_domain_id(), clock=ManualClock(),
                   serve=False) as container:
        node = TestHandle("fall", container=container)
        FallDetector(node)
        t = _feed(node, 0.0, 0.5, tilt_deg=5.0)
        t = _feed(node, t, 0.1, tilt_deg=85.0, rate=3.0)
        t = _feed(node, t, 1.5, tilt_deg=5.0)
        assert _states(node) == ["standing", "fallen", "standing"]
