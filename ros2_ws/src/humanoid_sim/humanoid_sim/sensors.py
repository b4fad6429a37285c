"""What a simulated robot's sensors send, read from MuJoCo: IMU, camera image and info, poses.

One owner for the messages both simulator components publish (:mod:`.simulator`, one robot;
:mod:`.world_simulator`, several), so a robot's topics look the same whichever world it is
in. Names of the robot's model are passed with its prefix (``blue1/`` in a shared world,
empty in the one-robot model).
"""

from __future__ import annotations

import array
import math

import mujoco
import numpy as np
import numpy.typing as npt
from geometry_msgs.msg import Point, Pose, PoseStamped, Quaternion
from sensor_msgs.msg import CameraInfo, Image, Imu

from efficient_comm import to_msg

from .render import OffscreenRenderer

CAMERA = "head_camera"


def pose(position: npt.ArrayLike, quat_wxyz: npt.ArrayLike) -> Pose:
    p, q = np.asarray(position, dtype=float), np.asarray(quat_wxyz, dtype=float)
    return Pose(position=Point(x=p[0], y=p[1], z=p[2]),
                orientation=Quaternion(w=q[0], x=q[1], y=q[2], z=q[3]))


def pose_stamped(position: npt.ArrayLike, quat_wxyz: npt.ArrayLike, *, stamp_ns: int
                 ) -> PoseStamped:
    """A pose in the field frame (ground truth)."""
    msg = PoseStamped(pose=pose(position, quat_wxyz))
    msg.header.stamp = to_msg(stamp_ns)
    msg.header.frame_id = "field"
    return msg


def heading_of(quat_wxyz: Quaternion) -> float:
    """The yaw (rad) of an orientation: where a placed robot faces."""
    q = quat_wxyz
    return math.atan2(2 * (q.w * q.z + q.x * q.y), 1 - 2 * (q.y * q.y + q.z * q.z))


def camera_info(model: mujoco.MjModel, *, camera: str, width: int, height: int,
                frame_id: str = CAMERA) -> CameraInfo:
    """The pinhole model of ``camera`` (MJCF ``fovy``) at ``width`` x ``height``."""
    fovy = math.radians(float(model.cam_fovy[model.camera(camera).id]))
    f = (height / 2) / math.tan(fovy / 2)
    info = CameraInfo(width=width, height=height, distortion_model="plumb_bob")
    info.header.frame_id = frame_id
    info.k = [f, 0.0, width / 2, 0.0, f, height / 2, 0.0, 0.0, 1.0]
    info.p = [f, 0.0, width / 2, 0.0, 0.0, f, height / 2, 0.0, 0.0, 0.0, 1.0, 0.0]
    info.d = [0.0] * 5
    return info


def imu(data: mujoco.MjData, *, prefix: str = "", stamp_ns: int) -> Imu:
    """The robot's IMU site: orientation, gyro and accelerometer (``models/robot.xml``)."""
    msg = Imu()
    msg.header.stamp = to_msg(stamp_ns)
    msg.header.frame_id = "imu"
    w, x, y, z = data.sensor(prefix + "imu_orientation").data
    msg.orientation = Quaternion(w=float(w), x=float(x), y=float(y), z=float(z))
    gx, gy, gz = data.sensor(prefix + "imu_gyro").data
    msg.angular_velocity.x, msg.angular_velocity.y, msg.angular_velocity.z = (
        float(gx), float(gy), float(gz))
    ax, ay, az = data.sensor(prefix + "imu_accel").data
    msg.linear_acceleration.x, msg.linear_acceleration.y, msg.linear_acceleration.z = (
        float(ax), float(ay), float(az))
    return msg


def image(renderer: OffscreenRenderer, data: mujoco.MjData, *, camera: str, stamp_ns: int,
          frame_id: str = CAMERA) -> Image:
    """Render ``camera`` into a new rgb8 Image."""
    w, h = renderer.width, renderer.height
    buffer = array.array("B", bytes(w * h * 3))
    renderer.render(data, np.frombuffer(buffer, dtype=np.uint8).reshape(h, w, 3), camera=camera)
    return rgb8_image(buffer, width=w, height=h, stamp_ns=stamp_ns, frame_id=frame_id)


def rgb8_image(buffer: array.array[int], *, width: int, height: int, stamp_ns: int,
               frame_id: str = CAMERA) -> Image:
    """An rgb8 Image around a drawn frame (rows top-down), which it keeps: no copy."""
    msg = Image(height=height, width=width, encoding="rgb8", step=width * 3)
    msg.header.stamp = to_msg(stamp_ns)
    msg.header.frame_id = frame_id
    msg.data = buffer  # an array.array is taken as is: no copy, no per-byte check
    return msg
