"""Landmarks in the camera image: goal posts and points on the field lines, on the ground.

What localization needs from an image is where the field's fixed features lie relative to
the robot. Both kinds are white; what tells them apart is the horizon. The camera's pose
under the torso follows from the head's kinematics (the neck angles when the image was
taken, from ``joint_states``) and the torso's tilt (the IMU), as the ball model places the
ball; from that pose each image column has a horizon row (where rays are level). A goal
post stands on the ground and rises above the camera (1.3 m against the camera's 0.5 m), so
its white run in a column crosses the horizon; lines lie on the ground, always below it;
the crossbar stays above it. A post's foot (the lowest white pixel of its run) is projected
onto the ground; line points are the centres of white runs along every ``scan_step_px``-th
row and column below the horizon, projected alike.

Published, stamped with the image's stamp, frame ``base_footprint`` (the level frame under
the torso: x forward, y left, z up), as sensor_msgs/PointCloud2 of x, y, z float32 points on
the ground (z = 0; :func:`points_message` writes them, :func:`read_points` reads them: one
buffer per image, where an array of Pose messages cost more than finding the points):

* ``landmarks/posts``: the feet of the goal posts seen;
* ``landmarks/lines``: points on field lines, at most ``max_line_points``, nearer than
  ``max_range_m`` and further than ``min_range_m`` (nearer, what is white is more likely
  the robot's own feet than a line).

White is bright and unsaturated (``min_value``, ``max_saturation``, 10 of 255): line pixels
have a saturation near 0, the turf at least 36 even where the headlight makes it shine near
the robot, the robot's own light grey arms and legs 14 to 16 (at 70, both passed for lines
and pulled the filter off by up to 1.5 m as it walked past the centre circle).
Posts are followed in a laxer mask (``max_saturation_posts``, 70): far away, their feet
blend with the turf, and each row lost is decimetres of range.

Both are published for every image read (empty arrays say "looked, saw none", which a
filter needs as much as a sighting). While someone looks, ``landmarks/debug_markers``
draws the horizon, the posts and the line points in the image.
"""

from __future__ import annotations

import array
import math
from dataclasses import dataclass

import cv2
import numpy as np
import numpy.typing as npt
from builtin_interfaces.msg import Time
from geometry_msgs.msg import Quaternion
from sensor_msgs.msg import CameraInfo, Image, Imu, JointState, PointCloud2, PointField

from debug_probes import CYAN, MAGENTA, YELLOW, DebugDrawing
from efficient_comm import from_msg, latched_qos
from efficient_comm.handle import NodeHandle

from ..errors import SimConfigError
from .vision import FALLBACK_FOVY_DEG
from .world_model import (
    CAMERA_FROM_PITCH,
    MIN_DEPRESSION_RAD,
    NECK_PITCH_ABOVE_YAW,
    NECK_YAW_ABOVE_TORSO,
    TORSO_HEIGHT_M,
    NeckAngles,
)

Array = npt.NDArray[np.float64]


def _rot_z(angle: float) -> Array:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _rot_y(angle: float) -> Array:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def _level(orientation: Quaternion | None) -> Array:
    """The torso's tilt (roll and pitch, heading removed) from the IMU's quaternion."""
    if orientation is None:
        return np.eye(3)
    w, x, y, z = orientation.w, orientation.x, orientation.y, orientation.z
    norm = math.sqrt(w * w + x * x + y * y + z * z)
    if not math.isfinite(norm) or norm == 0:
        return np.eye(3)
    w, x, y, z = w / norm, x / norm, y / norm, z / norm
    rotation = np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])
    heading = math.atan2(rotation[1, 0], rotation[0, 0])
    level: Array = _rot_z(-heading) @ rotation
    return level


@dataclass(frozen=True)
class CameraPose:
    """The camera in ``base_footprint``: ``rotation`` turns a ray given in the head's axes
    (x forward, y left, z up) into the level frame; ``position`` is the camera's (m)."""

    rotation: Array
    position: Array

    @classmethod
    def from_kinematics(cls, *, neck_yaw: float, neck_pitch: float,
                        orientation: Quaternion | None = None,
                        torso_height: float = TORSO_HEIGHT_M) -> CameraPose:
        """The head camera of ``models/robot.xml`` for these neck angles and torso tilt."""
        head = _rot_z(neck_yaw) @ _rot_y(neck_pitch)
        camera = (np.array([0.0, 0.0, NECK_YAW_ABOVE_TORSO])
                  + _rot_z(neck_yaw) @ (np.array([0.0, 0.0, NECK_PITCH_ABOVE_YAW])
                                        + _rot_y(neck_pitch) @ np.array(
                                            [CAMERA_FROM_PITCH[0], 0.0, CAMERA_FROM_PITCH[1]])))
        level = _level(orientation)
        return cls(rotation=level @ head,
                   position=level @ camera + np.array([0.0, 0.0, torso_height]))

    def rays(self, u: Array, v: Array, *, k: tuple[float, float, float, float]) -> Array:
        """Unit-free rays (n x 3, level frame) through pixels (u, v); k = fx, fy, cx, cy."""
        fx, fy, cx, cy = k
        head = np.stack([np.ones_like(u), (cx - u) / fx, (cy - v) / fy], axis=1)
        return head @ self.rotation.T

    def on_ground(self, u: Array, v: Array, *, k: tuple[float, float, float, float],
                  height: float = 0.0) -> tuple[Array, npt.NDArray[np.bool_]]:
        """Where the rays through (u, v) meet the plane ``height`` above the ground:
        (n x 2 points x, y; mask of the rays that do, steeper than MIN_DEPRESSION_RAD)."""
        rays = self.rays(u, v, k=k)
        norms = np.linalg.norm(rays, axis=1)
        ok = rays[:, 2] < -math.sin(MIN_DEPRESSION_RAD) * norms
        t = np.where(ok, (height - self.position[2]) / np.where(ok, rays[:, 2], -1.0), 0.0)
        return self.position[:2] + t[:, None] * rays[:, :2], ok

    def down_image(self, *, k: tuple[float, float, float, float]) -> Array:
        """The vertical vanishing point (where the images of vertical lines meet, below),
        homogeneous: (u w, v w, w); w may be 0 or negative (looking up, or level)."""
        fx, fy, cx, cy = k
        d = self.rotation.T @ np.array([0.0, 0.0, -1.0])  # down, in the head's axes
        point: Array = np.array([cx * d[0] - fx * d[1], cy * d[0] - fy * d[2], d[0]])
        return point

    def horizon_rows(self, width: int, *, k: tuple[float, float, float, float]) -> Array:
        """For each image column, the row where rays are level (may lie outside the image);
        rows below it (larger) look at the ground. Assumes an upright camera."""
        fx, fy, cx, cy = k
        a = (cx - np.arange(width, dtype=float)) / fx
        r = self.rotation
        # level z of (1, a, b) is r20 + r21 a + r22 b = 0 -> b; row = cy - fy b
        b = -(r[2, 0] + r[2, 1] * a) / (r[2, 2] if abs(r[2, 2]) > 1e-9 else 1e-9)
        rows: Array = cy - fy * b
        return rows


@dataclass(frozen=True)
class Landmarks:
    """What one image showed: post feet and line points (n x 2, m, base_footprint), and
    the pixels they came from (for drawing)."""

    posts: Array
    lines: Array
    post_pixels: Array
    line_pixels: Array


def white_masks(rgb: npt.NDArray[np.uint8], *, min_value: int, max_saturation: int,
                max_saturation_posts: int
                ) -> tuple[npt.NDArray[np.bool_], npt.NDArray[np.bool_]]:
    """The white pixels for posts and for lines: a post's foot on the far goal line is a
    blend of white and turf, one row of which is decimetres of range at 7 m."""
    hsv = cv2.cvtColor(rgb, cv2.COLOR_RGB2HSV)
    bright = hsv[..., 2] >= min_value
    return bright & (hsv[..., 1] <= max_saturation_posts), bright & (hsv[..., 1] <= max_saturation)


def _runs(line: npt.NDArray[np.bool_]) -> tuple[npt.NDArray[np.intp], npt.NDArray[np.intp]]:
    """Starts and ends (exclusive) of the True runs of a 1-d mask."""
    edges = np.flatnonzero(np.diff(np.concatenate(([0], line.view(np.int8), [0]))))
    return edges[0::2], edges[1::2]


def _run_centres(mask: npt.NDArray[np.bool_], *, max_run_px: int
                 ) -> tuple[npt.NDArray[np.intp], Array]:
    """The white runs of each row of ``mask`` no longer than ``max_run_px``: their rows
    and centres (all rows at once: starts and ends come in the same row-major order)."""
    padded = np.zeros((mask.shape[0], mask.shape[1] + 2), dtype=np.int8)
    padded[:, 1:-1] = mask
    edges = np.diff(padded, axis=1)
    rows, starts = np.nonzero(edges == 1)
    _, ends = np.nonzero(edges == -1)
    keep = ends - starts <= max_run_px
    return rows[keep], (starts[keep] + ends[keep] - 1) / 2


def _march(mask: npt.NDArray[np.bool_], u: float, v: float, du: float, dv: float, *,
           limit: int) -> tuple[float, float, int] | None:
    """From (u, v), step by (du, dv) while the mask is white, at most ``limit`` steps:
    the last white pixel and the steps taken; None if (u, v) itself is not white."""
    height, width = mask.shape
    last: tuple[float, float, int] | None = None
    for step in range(limit + 1):
        x, y = u + step * du, v + step * dv
        i, j = round(y), round(x)
        if not (0 <= i < height and 0 <= j < width) or not mask[i, j]:
            break
        last = (x, y, step)
    return last


def find_landmarks(mask: npt.NDArray[np.bool_], camera: CameraPose, *,
                   k: tuple[float, float, float, float],
                   line_mask: npt.NDArray[np.bool_] | None = None, scan_step_px: int = 6,
                   max_run_px: int = 60, min_range_m: float = 0.35, max_range_m: float = 5.0,
                   max_line_points: int = 80,
                   above_px: int = 4, below_px: int = 2) -> Landmarks:
    """Goal posts in a white ``mask`` and line points in ``line_mask`` (default: the same)
    seen from ``camera`` (see the module docstring for how they are told apart)."""
    height, width = mask.shape
    horizon = camera.horizon_rows(width, k=k)
    # Posts: white runs along the horizon whose whiteness goes on above_px above it and at
    # least below_px below it, followed along the image of a vertical line (posts lean in
    # the image when the head is pitched or turned) down to the foot.
    on_horizon = np.zeros(width, dtype=bool)
    rows = np.round(horizon).astype(np.intp)
    inside = (rows >= 0) & (rows < height)
    on_horizon[inside] = mask[rows[inside], np.flatnonzero(inside)]
    down = camera.down_image(k=k)
    posts_px: list[tuple[float, float]] = []
    ground = (mask if line_mask is None else line_mask).copy()
    ground &= np.arange(height)[:, None] > horizon[None, :] + below_px
    for start, end in zip(*_runs(on_horizon), strict=True):
        u0 = (start + end - 1) / 2
        v0 = float(horizon[round(u0)])
        # The direction "down" at (u0, v0): towards the vertical vanishing point.
        du, dv = down[0] - u0 * down[2], down[1] - v0 * down[2]
        norm = math.hypot(du, dv)
        if norm == 0:
            continue
        du, dv = du / norm, dv / norm
        top = _march(mask, u0, v0, -du, -dv, limit=above_px)
        foot = _march(mask, u0, v0, du, dv, limit=height + width)
        if top is None or top[2] < above_px or foot is None or foot[2] < below_px:
            continue
        if not (1 <= foot[0] < width - 2 and foot[1] < height - 2):
            continue  # the foot is not in the image (or the post leaves it sideways)
        posts_px.append((foot[0], foot[1]))
        # Its pixels are no line: blank the post (as wide as its run and a margin).
        cv2.line(ground.view(np.uint8), (round(u0), round(v0)),
                 (round(foot[0]), round(foot[1])), 0, thickness=int(end - start) + 4)
    post_pixels = np.array(posts_px, dtype=float).reshape(-1, 2)
    # Lines: run centres along scan rows and columns, below the horizon, off the posts.
    first = scan_step_px // 2
    rows, across = _run_centres(ground[first::scan_step_px], max_run_px=max_run_px)
    columns, along = _run_centres(ground[:, first::scan_step_px].T, max_run_px=max_run_px)
    line_pixels = np.concatenate([
        np.stack([across, first + rows * scan_step_px], axis=1),
        np.stack([first + columns * scan_step_px, along], axis=1)]).astype(float)
    lines, ok = camera.on_ground(line_pixels[:, 0], line_pixels[:, 1], k=k)
    ranges = np.hypot(lines[:, 0], lines[:, 1])
    ok &= (ranges >= min_range_m) & (ranges <= max_range_m)
    lines, line_pixels = lines[ok], line_pixels[ok]
    if len(lines) > max_line_points:  # evenly thinned, the same for the same image
        pick = np.linspace(0, len(lines) - 1, max_line_points).round().astype(int)
        lines, line_pixels = lines[pick], line_pixels[pick]
    posts, ok = camera.on_ground(post_pixels[:, 0], post_pixels[:, 1], k=k)
    return Landmarks(posts=posts[ok], lines=lines, post_pixels=post_pixels[ok],
                     line_pixels=line_pixels)


#: The fields of a landmark message's points: x, y, z as float32, 12 bytes a point.
POINT_FIELDS = [PointField(name=name, offset=4 * i, datatype=PointField.FLOAT32, count=1)
                for i, name in enumerate("xyz")]


def points_message(points: Array, *, stamp: Time, frame_id: str = "base_footprint"
                   ) -> PointCloud2:
    """Ground points (n x 2, m) as a PointCloud2 (z = 0): one buffer, not n messages."""
    xyz = np.zeros((len(points), 3), dtype=np.float32)
    xyz[:, :2] = points
    out = PointCloud2(height=1, width=len(points), fields=POINT_FIELDS, is_bigendian=False,
                      point_step=12, row_step=12 * len(points), is_dense=True)
    out.header.stamp = stamp  # shared, never modified
    out.header.frame_id = frame_id
    out.data = array.array("B", xyz.tobytes())
    return out


def read_points(cloud: PointCloud2) -> Array:
    """The ground points (n x 2, m) of a message from :func:`points_message`."""
    if (cloud.point_step != 12 or [f.name for f in cloud.fields][:3] != ["x", "y", "z"]
            or len(cloud.data) != cloud.width * cloud.height * 12):
        raise SimConfigError(f"landmark points: need x, y, z float32 (12 bytes a point), got "
                             f"{[f.name for f in cloud.fields]} with point_step "
                             f"{cloud.point_step} and {len(cloud.data)} bytes")
    xyz = np.frombuffer(bytes(cloud.data), dtype=np.float32).reshape(-1, 3)
    return xyz[:, :2].astype(float)


class LandmarkDetector:
    """The landmark detector component (topics in the module's docstring)."""

    def __init__(self, node: NodeHandle) -> None:
        self.node = node
        self.min_value = node.declare_parameter("min_value", 140, range=(0, 255))
        self.max_saturation = node.declare_parameter("max_saturation", 10, range=(0, 255))
        self.max_saturation_posts = node.declare_parameter("max_saturation_posts", 70,
                                                           range=(0, 255))
        self.scan_step_px = node.declare_parameter("scan_step_px", 6, range=(1, 64))
        self.min_range_m = node.declare_parameter("min_range_m", 0.35, range=(0.0, 5.0))
        self.max_range_m = node.declare_parameter("max_range_m", 5.0, range=(0.5, 20.0))
        self.max_line_points = node.declare_parameter("max_line_points", 80, range=(0, 1000))
        self.torso_height = node.declare_parameter("torso_height", TORSO_HEIGHT_M,
                                                   range=(0.1, 2.0))
        self.k: tuple[float, float, float, float] | None = None
        self.orientation: Quaternion | None = None
        self.neck = NeckAngles()
        self.frames = self.rejected = self.posts_seen = 0
        #: What the last image showed (for inspection and tests).
        self.last: Landmarks | None = None
        self.posts_pub = node.create_publisher(PointCloud2, "landmarks/posts", qos=10)
        self.lines_pub = node.create_publisher(PointCloud2, "landmarks/lines", qos=10)
        self.drawing = DebugDrawing(node, "landmarks/debug_markers")
        node.create_subscription(CameraInfo, "camera/camera_info", self._on_info,
                                 qos=latched_qos())
        node.create_subscription(JointState, "joint_states", self.neck.update, qos=10)
        node.create_subscription(Imu, "imu/data", self._on_imu, qos=10)
        node.create_subscription(Image, "camera/image_raw", self._on_image, qos=1)

    def _on_info(self, info: CameraInfo) -> None:
        if info.k[0] > 0 and info.k[4] > 0:
            self.k = (info.k[0], info.k[4], info.k[2], info.k[5])

    def _on_imu(self, imu: Imu) -> None:
        self.orientation = imu.orientation  # shared, only read

    def _on_image(self, image: Image) -> None:
        if image.encoding != "rgb8" or len(image.data) != image.height * image.step:
            self.rejected += 1
            self.node.logger.warning(
                f"landmarks: skipping a {image.width}x{image.height} {image.encoding!r} "
                f"image with {len(image.data)} bytes: need rgb8 with height * step bytes")
            return
        self.frames += 1
        if self.k is None:  # until camera_info arrives: the head camera's view
            f = image.height / (2 * math.tan(math.radians(FALLBACK_FOVY_DEG / 2)))
            self.k = (f, f, image.width / 2, image.height / 2)
        stamp = from_msg(image.header.stamp)
        camera = CameraPose.from_kinematics(
            neck_yaw=self.neck.at("neck_yaw", stamp), neck_pitch=self.neck.at("neck_pitch", stamp),
            orientation=self.orientation, torso_height=self.torso_height)
        pixels = np.frombuffer(image.data, dtype=np.uint8).reshape(
            image.height, image.step // 3, 3)[:, : image.width]
        posts, lines = white_masks(pixels, min_value=self.min_value,
                                   max_saturation=self.max_saturation,
                                   max_saturation_posts=self.max_saturation_posts)
        found = find_landmarks(
            posts, camera, k=self.k, line_mask=lines, scan_step_px=self.scan_step_px,
            min_range_m=self.min_range_m, max_range_m=self.max_range_m,
            max_line_points=self.max_line_points)
        self.posts_seen += len(found.posts)
        self.last = found
        self.posts_pub.publish(points_message(found.posts, stamp=image.header.stamp))
        self.lines_pub.publish(points_message(found.lines, stamp=image.header.stamp))
        if self.drawing.wants():
            self._draw(camera, image.width, found)
            self.drawing.publish(image.header.stamp, frame_id=image.header.frame_id)

    def _draw(self, camera: CameraPose, width: int, found: Landmarks) -> None:
        assert self.k is not None
        d = self.drawing
        horizon = camera.horizon_rows(width, k=self.k)
        d.line("horizon", 0.0, float(horizon[0]), float(width - 1), float(horizon[-1]),
               color=CYAN)
        d.points("lines", [(float(u), float(v)) for u, v in found.line_pixels], color=YELLOW)
        for (u, v), (x, y) in zip(found.post_pixels, found.posts, strict=True):
            d.circle("posts", float(u), float(v), 4.0, color=MAGENTA, width=2.0)
            d.text("posts", float(u) + 5, float(v), f"{math.hypot(x, y):.1f} m", color=MAGENTA)

