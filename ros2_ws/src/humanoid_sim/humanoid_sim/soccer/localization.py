"""Where the robot is on the field: a particle filter, or noisy ground truth standing in.

Three sources publish the same topics, and each robot runs one of them
(:func:`add_localization`, ``compose(localization=...)``, the match's ``--localization``):

* ``particle_filter`` (:class:`Localization`): odometry moves the particles (the walk
  engine's ``odom`` for the steps, the IMU's yaw for the turns, each with noise in
  proportion), and what the camera sees weighs them (:mod:`.landmarks`): line points by
  how far each lands from the nearest field line (a likelihood field, precomputed from
  :data:`soccer_field.KIDSIZE`), goal posts' feet by bearing and range to the nearest post
  (the posts cannot be told apart: both goals are white). The field is point-symmetric
  about the centre mark, so a robot that knows nothing would have two equally good
  answers; at kick-off it knows its own half (``own_half``) or where it was placed
  (``initial_pose``), which removes the mirror image.
* ``noisy_ground_truth`` (:class:`NoisyTruthPose`): the simulator's ground truth with
  seeded Gaussian noise and a delay, the dissertation's substitution of a component by the
  simulation, for when the filter is not good enough for what is tested;
* ``ground_truth`` (:class:`TruthPose`): the simulator's ground truth as it is, claiming
  the sigma ``pose_sigma_m``: for what must not depend on localization at all.

A robot that knows its name (the ``robot`` parameter, e.g. ``red2``) also follows the
referee: the filter takes the kick-off spot as its pose when the referee placed it there
(:meth:`.game_control.GameControl.placed`, as the striker does). Neither the filter nor the
landmarks assume a side: the field model is the whole field in the one field frame both
teams share, and a red robot (starting at x > 0) gives ``own_half`` ``+x`` or its
``initial_pose``.

Published (relative to the robot's namespace): ``localization/pose``
(geometry_msgs/PoseWithCovarianceStamped, frame ``field``: x, y, heading as a yaw
quaternion; covariance in ROS's 6x6 order, x, y, yaw filled) at ``rate_hz``, and
``localization/source`` (std_msgs/String, transient local): which of the two ran, for
reports and logs. :mod:`.pose_error` measures any of them against ground truth.
"""

from __future__ import annotations

import functools
import math
import random
from collections import deque
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt
from geometry_msgs.msg import PoseStamped, PoseWithCovarianceStamped, Quaternion
from nav_msgs.msg import Odometry
from sensor_msgs.msg import Imu, PointCloud2
from std_msgs.msg import Bool, String

from efficient_comm import Container, bind_parameters, from_msg, latched_qos, to_msg
from efficient_comm.handle import NodeHandle
from soccer_field import KIDSIZE, FieldDimensions

from ..errors import SimConfigError
from .fall import STANDING
from .game_control import GameControl
from .landmarks import LandmarkDetector, read_points
from .pose_sources import GROUND_TRUTH as GROUND_TRUTH
from .pose_sources import NOISY_GROUND_TRUTH as NOISY_GROUND_TRUTH
from .pose_sources import PARTICLE_FILTER as PARTICLE_FILTER
from .pose_sources import SOURCES as SOURCES

Array = npt.NDArray[np.float64]
#: How sure the filter is of a kick-off spot the referee placed the robot on (m, rad).
PLACED_SIGMA = (0.1, 0.1)
LATCHED = latched_qos()
#: Motions during which the camera is not where the landmarks assume.
NOT_UPRIGHT_MOTIONS = ("kick", "getup")


def wrap(angle: float) -> float:
    return (angle + math.pi) % (2 * math.pi) - math.pi


def yaw_of(q: Quaternion) -> float:
    return math.atan2(2 * (q.w * q.z + q.x * q.y), 1 - 2 * (q.y * q.y + q.z * q.z))


class FieldModel:
    """The field's lines and goal posts as localization sees them, from the dimensions.

    :meth:`line_distance` looks up how far a field point is from the nearest line's centre,
    in a grid of ``resolution_m`` over the field and its border strip (points beyond it are
    as far as the grid's largest distance).
    """

    def __init__(self, field: FieldDimensions = KIDSIZE, *, resolution_m: float = 0.02
                 ) -> None:
        hl, hw = field.half_length, field.half_width
        self.resolution = resolution_m
        margin = field.border_strip_width
        self.origin = (-hl - margin, -hw - margin)
        xs = np.arange(-hl - margin, hl + margin + resolution_m / 2, resolution_m)
        ys = np.arange(-hw - margin, hw + margin + resolution_m / 2, resolution_m)
        gx, gy = np.meshgrid(xs, ys, indexing="ij")
        segments = [((-hl, hw), (hl, hw)), ((-hl, -hw), (hl, -hw)),  # touch lines
                    ((0.0, -hw), (0.0, hw))]  # halfway line
        for side in (-1.0, 1.0):
            segments.append(((side * hl, -hw), (side * hl, hw)))  # goal line
            for length, width in ((field.goal_area_length, field.goal_area_width),
                                  (field.penalty_area_length, field.penalty_area_width)):
                front = side * (hl - length)
                segments += [((front, -width / 2), (front, width / 2)),
                             ((front, width / 2), (side * hl, width / 2)),
                             ((front, -width / 2), (side * hl, -width / 2))]
        distance = np.abs(np.hypot(gx, gy) - field.centre_circle_diameter / 2)
        for (ax, ay), (bx, by) in segments:
            dx, dy = bx - ax, by - ay
            t = np.clip(((gx - ax) * dx + (gy - ay) * dy) / (dx * dx + dy * dy), 0.0, 1.0)
            distance = np.minimum(distance, np.hypot(gx - ax - t * dx, gy - ay - t * dy))
        self.distance: Array = distance
        self.segments = segments
        #: The posts' feet (inner edges: the dimensions give the goal's clear width).
        self.posts: Array = np.array([(sx * hl, sy * field.goal_width / 2)
                                      for sx in (-1.0, 1.0) for sy in (-1.0, 1.0)])
        self.field = field

    def line_distance(self, x: Array, y: Array) -> Array:
        """Distance (m) from field points (any shape) to the nearest line."""
        n, m = self.distance.shape
        i = np.floor((x - self.origin[0]) / self.resolution + 0.5).astype(np.intp)
        j = np.floor((y - self.origin[1]) / self.resolution + 0.5).astype(np.intp)
        found: Array = self.distance[np.clip(i, 0, n - 1), np.clip(j, 0, m - 1)]
        return found


@dataclass(frozen=True, slots=True)
class FilterParameters:
    """The particle filter's figures; each is also a ROS parameter of the same name."""

    particles: int = 300
    #: Odometry noise, as the spread it adds over a whole metre walked (m, and rad of
    #: veering) or radian turned (rad); it grows with the square root of the way, so the
    #: spread does not depend on how often odometry arrives.
    odom_trans_noise: float = 0.1
    odom_rot_per_m: float = 0.15
    odom_rot_noise: float = 0.1
    #: A line point's spread (m) at the robot's feet, and its growth per m of range.
    line_sigma_m: float = 0.1
    line_sigma_per_m: float = 0.05
    #: A point further than this from any line counts as this far (an outlier: the
    #: robot's own feet, a mark the model leaves out).
    line_outlier_m: float = 0.5
    #: One image's line points count as at most this many independent ones (neighbouring
    #: points share the same error of the camera's pose).
    line_points_weight: float = 6.0
    #: A post's bearing spread (rad) and range spread per m of range.
    post_bearing_sigma: float = 0.08
    post_range_sigma_per_m: float = 0.2
    #: Spread added to each resampled particle, which keeps a standing robot's cloud alive.
    jitter_m: float = 0.01
    jitter_rad: float = 0.01
    #: Resample when the effective number of particles falls below this share.
    resample_below: float = 0.5

    def check(self) -> None:
        """Raise :class:`SimConfigError` naming the first figure the filter cannot use."""
        for name in self.__slots__:
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise SimConfigError(f"localization parameter {name} = {value} is out of range")
        if not 10 <= self.particles <= 100_000 or not 0 < self.resample_below <= 1:
            raise SimConfigError(f"need 10 <= particles <= 100000 and 0 < resample_below <= 1, "
                                 f"got {self.particles}, {self.resample_below}")
        if min(self.line_sigma_m, self.post_bearing_sigma, self.line_points_weight) <= 0:
            raise SimConfigError("line_sigma_m, post_bearing_sigma and line_points_weight "
                                 "must be > 0")


@dataclass(frozen=True, slots=True)
class Estimate:
    """The filter's answer: pose on the field and its spread (m, rad)."""

    x: float
    y: float
    heading: float
    covariance: tuple[float, float, float, float]  # xx, xy, yy, heading-heading


class ParticleFilter:
    """The filter itself, free of ROS: odometry steps and observations in, a pose out."""

    def __init__(self, parameters: FilterParameters | None = None, *,
                 field: FieldModel | None = None, seed: int = 0) -> None:
        self.p = parameters or FilterParameters()
        self.p.check()
        self.field = field or FieldModel()
        self.rng = np.random.default_rng(seed)
        n = self.p.particles
        self.x, self.y, self.heading = np.zeros(n), np.zeros(n), np.zeros(n)
        self.weights = np.full(n, 1.0 / n)
        self.resamples = 0

    def reset_around(self, x: float, y: float, heading: float, *, sigma_m: float,
                     sigma_rad: float) -> None:
        """Particles spread around a known pose (where the robot was placed)."""
        n = self.p.particles
        self.x = x + self.rng.normal(0.0, sigma_m, n)
        self.y = y + self.rng.normal(0.0, sigma_m, n)
        self.heading = heading + self.rng.normal(0.0, sigma_rad, n)
        self.weights = np.full(n, 1.0 / n)

    def reset_in_half(self, side: float) -> None:
        """Particles anywhere in one half (``side`` -1: x < 0, +1: x > 0), any heading."""
        n, f = self.p.particles, self.field.field
        self.x = side * self.rng.uniform(0.0, f.half_length, n)
        self.y = self.rng.uniform(-f.half_width, f.half_width, n)
        self.heading = self.rng.uniform(-math.pi, math.pi, n)
        self.weights = np.full(n, 1.0 / n)

    def predict(self, forward: float, left: float, turn: float) -> None:
        """Move every particle by one odometry step (robot frame), with noise."""
        p, n = self.p, self.p.particles
        distance = math.hypot(forward, left)
        if distance == 0 and turn == 0:
            return
        sigma_t = p.odom_trans_noise * math.sqrt(distance)
        f = forward + self.rng.normal(0.0, sigma_t, n)
        lt = left + self.rng.normal(0.0, sigma_t, n)
        c, s = np.cos(self.heading), np.sin(self.heading)
        self.x = self.x + c * f - s * lt
        self.y = self.y + s * f + c * lt
        sigma_r = math.hypot(p.odom_rot_noise * math.sqrt(abs(turn)),
                             p.odom_rot_per_m * math.sqrt(distance))
        self.heading = self.heading + turn + self.rng.normal(0.0, sigma_r, n)

    def spread(self, sigma_m: float, sigma_rad: float) -> None:
        """Widen the cloud (after a fall: the robot lands somewhere near)."""
        n = self.p.particles
        self.x = self.x + self.rng.normal(0.0, sigma_m, n)
        self.y = self.y + self.rng.normal(0.0, sigma_m, n)
        self.heading = self.heading + self.rng.normal(0.0, sigma_rad, n)

    def _to_field(self, points: Array) -> tuple[Array, Array]:
        """Robot-frame points (m x 2) seen from every particle: (n x m) field x and y."""
        c, s = np.cos(self.heading)[:, None], np.sin(self.heading)[:, None]
        px, py = points[None, :, 0], points[None, :, 1]
        return self.x[:, None] + c * px - s * py, self.y[:, None] + s * px + c * py

    def update_lines(self, points: Array) -> None:
        """Weigh the particles by how near the line points (robot frame, m x 2) fall to
        the field's lines."""
        if len(points) == 0:
            return
        p = self.p
        fx, fy = self._to_field(points)
        d = np.minimum(self.field.line_distance(fx, fy), p.line_outlier_m)
        sigma = p.line_sigma_m + p.line_sigma_per_m * np.hypot(points[:, 0], points[:, 1])
        cost = 0.5 * np.sum((d / sigma[None, :]) ** 2, axis=1)
        self._weigh(cost * min(1.0, p.line_points_weight / len(points)))

    def update_posts(self, points: Array) -> None:
        """Weigh the particles by the goal posts' feet seen (robot frame, m x 2), each
        matched to the post that fits it best."""
        if len(points) == 0:
            return
        p = self.p
        posts = self.field.posts
        dx = posts[None, :, 0] - self.x[:, None]  # n x 4
        dy = posts[None, :, 1] - self.y[:, None]
        expected_range = np.hypot(dx, dy)
        expected_bearing = np.arctan2(dy, dx) - self.heading[:, None]
        cost = np.zeros(len(self.x))
        for x, y in points:
            r, b = math.hypot(x, y), math.atan2(y, x)
            db = (expected_bearing - b + np.pi) % (2 * np.pi) - np.pi
            dr = expected_range - r
            per_post = ((db / p.post_bearing_sigma) ** 2
                        + (dr / (0.05 + p.post_range_sigma_per_m * r)) ** 2)
            cost += 0.5 * np.minimum(per_post.min(axis=1), 25.0)
        self._weigh(cost)

    def _weigh(self, cost: Array) -> None:
        weights = self.weights * np.exp(-(cost - cost.min()))
        total = weights.sum()
        if not math.isfinite(total) or total <= 0:
            return
        self.weights = weights / total
        if 1.0 / float(np.sum(self.weights ** 2)) < self.p.resample_below * self.p.particles:
            self._resample()

    def _resample(self) -> None:
        """Systematic (low-variance) resampling, then a little jitter."""
        n = self.p.particles
        positions = (self.rng.uniform() + np.arange(n)) / n
        index = np.minimum(np.searchsorted(np.cumsum(self.weights), positions), n - 1)
        self.x, self.y, self.heading = self.x[index], self.y[index], self.heading[index]
        self.weights = np.full(n, 1.0 / n)
        self.spread(self.p.jitter_m, self.p.jitter_rad)
        self.resamples += 1

    def estimate(self) -> Estimate:
        w = self.weights
        x, y = float(w @ self.x), float(w @ self.y)
        sin, cos = float(w @ np.sin(self.heading)), float(w @ np.cos(self.heading))
        heading = math.atan2(sin, cos)
        dx, dy = self.x - x, self.y - y
        dh = (self.heading - heading + np.pi) % (2 * np.pi) - np.pi
        return Estimate(x=x, y=y, heading=heading,
                        covariance=(float(w @ (dx * dx)), float(w @ (dx * dy)),
                                    float(w @ (dy * dy)), float(w @ (dh * dh))))


def _pose_message(estimate: Estimate, stamp_ns: int) -> PoseWithCovarianceStamped:
    out = PoseWithCovarianceStamped()
    out.header.stamp = to_msg(stamp_ns)
    out.header.frame_id = "field"
    out.pose.pose.position.x, out.pose.pose.position.y = estimate.x, estimate.y
    out.pose.pose.orientation = Quaternion(w=math.cos(estimate.heading / 2), x=0.0, y=0.0,
                                           z=math.sin(estimate.heading / 2))
    xx, xy, yy, hh = estimate.covariance
    covariance = [0.0] * 36
    covariance[0], covariance[1], covariance[6], covariance[7], covariance[35] = (
        xx, xy, xy, yy, hh)
    out.pose.covariance = covariance
    return out


def _common(node: NodeHandle) -> tuple[int, float]:
    """The parameters both sources have: the seed of their noise, the publishing period."""
    seed = node.declare_parameter("seed", 0)
    return seed, 1.0 / node.declare_parameter("rate_hz", 10.0, range=(0.1, 1000.0))


class Localization:
    """The particle filter component (see the module's docstring).

    Parameters besides the filter's figures (:class:`FilterParameters`): ``initial_pose``
    ([x, y, heading] where the robot was placed; empty: unknown), ``initial_sigma``
    ([m, rad] around it), ``own_half`` (``-x`` or ``+x``: where the particles start when
    the pose is unknown), ``seed``, ``rate_hz``, ``heading_from_imu`` (turns from the IMU's
    yaw rather than the commanded steps'), ``robot`` (its name: placements by the referee
    move the particles, see the module's docstring; empty: no referee).
    """

    def __init__(self, node: NodeHandle) -> None:
        self.node = node
        seed, period = _common(node)
        initial = node.declare_parameter("initial_pose", [0.0])
        sigma = node.declare_parameter("initial_sigma", [0.2, 0.1])
        own_half = node.declare_parameter("own_half", "-x")
        self.heading_from_imu = node.declare_parameter("heading_from_imu", True)
        if (len(initial) not in (1, 3) or len(sigma) != 2 or own_half not in ("-x", "+x")
                or not all(math.isfinite(v) and v >= 0 for v in sigma)):
            raise SimConfigError(
                f"initial_pose is [x, y, heading] (or [0.0]: unknown, start in own_half), "
                f"initial_sigma [m, rad], own_half '-x' or '+x'; got {initial}, {sigma}, "
                f"{own_half!r}")
        bound = bind_parameters(node, FilterParameters(), check=FilterParameters.check)
        self.filter = ParticleFilter(bound.value, seed=seed)
        if len(initial) == 3:
            self.filter.reset_around(*initial, sigma_m=sigma[0], sigma_rad=sigma[1])
        else:
            self.filter.reset_in_half(-1.0 if own_half == "-x" else 1.0)
        self.standing = True
        #: Whether the camera's pose is what the landmarks assume (not on one leg kicking).
        self.upright = True
        self._moving: set[str] = set()
        self.fell = False
        self.lines_used = self.posts_used = 0
        self._odom: tuple[float, float, float] | None = None
        self._imu_yaw: float | None = None
        self._imu_turn = 0.0
        #: Kick-off spots the referee placed the robot on, taken as the pose.
        self.placements = 0
        self._placed: tuple[float, float, float] | None = None
        self.game = GameControl(node)
        self.pub = node.create_publisher(PoseWithCovarianceStamped, "localization/pose", qos=10)
        node.create_publisher(String, "localization/source", qos=LATCHED).publish(
            String(data=PARTICLE_FILTER))
        node.create_subscription(Odometry, "odom", self._on_odom, qos=10)
        node.create_subscription(Imu, "imu/data", self._on_imu, qos=10)
        node.create_subscription(String, "fall/state", self._on_posture, qos=LATCHED)
        for motion in NOT_UPRIGHT_MOTIONS:
            node.create_subscription(Bool, f"motion/{motion}/active",
                                     functools.partial(self._on_motion, motion), qos=LATCHED)
        node.create_subscription(PointCloud2, "landmarks/lines", self._on_lines, qos=10)
        node.create_subscription(PointCloud2, "landmarks/posts", self._on_posts, qos=10)
        node.create_timer(period, self.publish)

    def _on_posture(self, posture: String) -> None:
        standing = posture.data == STANDING
        if standing and not self.standing and self.fell:
            self.filter.spread(0.15, 0.3)  # where a fall and a get-up left it, roughly
        self.fell = self.fell or not standing
        self.standing = standing

    def _on_motion(self, motion: str, active: Bool) -> None:
        """A kick stands on one leg and a get-up on none: the camera is not where the
        landmark detector assumes it (the walk's crouch), so nothing seen then is weighed.

        Each motion's own ``active`` flag, not the arbiter's ``motion/state``: composed
        depth-first, a ``stand`` that caused a kick request reached later subscribers after
        the ``kick`` it caused, so the last state seen there was the stale one."""
        if active.data:
            self._moving.add(motion)
        else:
            self._moving.discard(motion)
        self.upright = not self._moving

    def _on_imu(self, imu: Imu) -> None:
        q = imu.orientation
        if not all(map(math.isfinite, (q.x, q.y, q.z, q.w))) or not any((q.x, q.y, q.z, q.w)):
            return
        yaw = yaw_of(q)
        if self._imu_yaw is not None:
            self._imu_turn += wrap(yaw - self._imu_yaw)
        self._imu_yaw = yaw

    def _on_odom(self, odom: Odometry) -> None:
        q = odom.pose.pose.orientation
        now = (odom.pose.pose.position.x, odom.pose.pose.position.y, yaw_of(q))
        if not all(map(math.isfinite, now)):
            return
        last, self._odom = self._odom, now
        if last is None:
            self._imu_turn = 0.0
            return
        dx, dy = now[0] - last[0], now[1] - last[1]
        c, s = math.cos(last[2]), math.sin(last[2])
        turn = (self._imu_turn if self.heading_from_imu and self._imu_yaw is not None
                else wrap(now[2] - last[2]))
        self._imu_turn = 0.0
        self.filter.predict(c * dx + s * dy, -s * dx + c * dy, turn)

    def _points(self, cloud: PointCloud2) -> Array | None:
        """The points, or None for a message that holds none we can read (logged)."""
        try:
            return read_points(cloud)
        except SimConfigError as exc:
            self.node.logger.error(str(exc))
            return None

    def _on_lines(self, lines: PointCloud2) -> None:
        # A robot on the ground sees the field from nowhere we know: nothing is weighed.
        if self.standing and self.upright and (points := self._points(lines)) is not None:
            self.lines_used += len(points)
            self.filter.update_lines(points)

    def _on_posts(self, posts: PointCloud2) -> None:
        if self.standing and self.upright and (points := self._points(posts)) is not None:
            self.posts_used += len(points)
            self.filter.update_posts(points)

    def publish(self) -> None:
        estimate = self.filter.estimate()
        placed = self.game.placed(estimate.x, estimate.y)
        if placed is not None and placed != self._placed:
            self.filter.reset_around(*placed, sigma_m=PLACED_SIGMA[0], sigma_rad=PLACED_SIGMA[1])
            self.placements += 1
            estimate = self.filter.estimate()
        self._placed = placed
        self.pub.publish(_pose_message(estimate, self.node.clock.now_ns()))


class NoisyTruthPose:
    """Ground truth with seeded noise and delay, on the filter's topics (module docstring).

    Parameters: ``truth_topic`` (the world's pose of this robot, PoseStamped in the field
    frame), ``sigma_m``, ``sigma_rad`` (Gaussian noise on x, y and heading), ``delay_s``
    (each pose published this long after the moment it shows, stamped with that moment),
    ``seed``, ``rate_hz``.

    The delay counts from each sample's arrival on this robot's clock; the stamp stays the
    truth's own (the moment it shows, on the clock of whoever measured it). The truth comes
    from outside the robot (a simulator, a motion-capture system) whose clock is not the
    robot's: compared with the stamp, a robot whose clock runs ahead by more than the delay
    would publish every sample at once, one behind by more would publish none.
    """

    def __init__(self, node: NodeHandle) -> None:
        self.node = node
        seed, period = _common(node)
        topic = node.declare_parameter("truth_topic", "ground_truth/robot")
        self.sigma_m = node.declare_parameter("sigma_m", 0.05, range=(0.0, 10.0))
        self.sigma_rad = node.declare_parameter("sigma_rad", 0.03, range=(0.0, 3.2))
        self.delay_ns = round(node.declare_parameter("delay_s", 0.1, range=(0.0, 10.0)) * 1e9)
        self.rng = random.Random(seed)
        #: Truth samples not yet published: arrival (ns, own clock), stamp (ns), x, y, heading.
        self.pending: deque[tuple[int, int, float, float, float]] = deque()
        self.pub = node.create_publisher(PoseWithCovarianceStamped, "localization/pose", qos=10)
        node.create_publisher(String, "localization/source", qos=LATCHED).publish(
            String(data=NOISY_GROUND_TRUTH))
        node.create_subscription(PoseStamped, topic, self._on_truth, qos=10)
        node.create_timer(period, self.publish)

    def _on_truth(self, truth: PoseStamped) -> None:
        p = truth.pose
        now = self.node.clock.now_ns()
        sample = (now, from_msg(truth.header.stamp), p.position.x, p.position.y,
                  yaw_of(p.orientation))
        if all(map(math.isfinite, sample[2:])):
            self.pending.append(sample)
        while len(self.pending) > 2 and self.pending[1][0] <= now - self.delay_ns:
            self.pending.popleft()  # only the newest sample old enough is ever published

    def publish(self) -> None:
        due = self.node.clock.now_ns() - self.delay_ns
        if not self.pending or self.pending[0][0] > due:
            return
        while len(self.pending) > 1 and self.pending[1][0] <= due:
            self.pending.popleft()
        _, stamp, x, y, heading = self.pending.popleft()
        g, sm, sr = self.rng.gauss, self.sigma_m, self.sigma_rad
        estimate = Estimate(x=x + g(0.0, sm), y=y + g(0.0, sm),
                            heading=wrap(heading + g(0.0, sr)),
                            covariance=(sm * sm, 0.0, sm * sm, sr * sr))
        self.pub.publish(_pose_message(estimate, stamp))


class TruthPose:
    """Ground truth as it is, on the filter's topics, claiming the sigma ``pose_sigma_m``
    (default 0.1 m) in its covariance; published as each truth sample (``truth_topic``)
    arrives, with its stamp."""

    def __init__(self, node: NodeHandle) -> None:
        topic = node.declare_parameter("truth_topic", "ground_truth/robot")
        sigma = node.declare_parameter("pose_sigma_m", 0.1, range=(0.0, 10.0))
        self.variance = sigma * sigma
        self.pub = node.create_publisher(PoseWithCovarianceStamped, "localization/pose", qos=10)
        node.create_publisher(String, "localization/source", qos=LATCHED).publish(
            String(data=GROUND_TRUTH))
        node.create_subscription(PoseStamped, topic, self._on_truth, qos=10)

    def _on_truth(self, truth: PoseStamped) -> None:
        p = truth.pose
        estimate = Estimate(x=p.position.x, y=p.position.y, heading=yaw_of(p.orientation),
                            covariance=(self.variance, 0.0, self.variance, 0.0))
        if all(map(math.isfinite, (estimate.x, estimate.y, estimate.heading))):
            self.pub.publish(_pose_message(estimate, from_msg(truth.header.stamp)))


def add_localization(container: Container, *, namespace: str, source: str,
                     parameters: Mapping[str, Any] | None = None
                     ) -> Localization | NoisyTruthPose | TruthPose:
    """Add one robot's localization: ``particle_filter`` (with the landmark detector it
    needs), ``noisy_ground_truth`` or ``ground_truth``; ``parameters`` go to the
    localization component."""
    if source == PARTICLE_FILTER:
        container.add(LandmarkDetector, name="landmarks", namespace=namespace)
        filter_: Localization = container.add(Localization, name="localization",
                                              namespace=namespace,
                                              parameters=dict(parameters or {}))
        return filter_
    if source == NOISY_GROUND_TRUTH:
        truth: NoisyTruthPose = container.add(NoisyTruthPose, name="localization",
                                              namespace=namespace,
                                              parameters=dict(parameters or {}))
        return truth
    if source == GROUND_TRUTH:
        exact: TruthPose = container.add(TruthPose, name="localization", namespace=namespace,
                                         parameters=dict(parameters or {}))
        return exact
    raise SimConfigError(f"localization source {source!r} is not one of {', '.join(SOURCES)}")
