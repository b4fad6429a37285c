"""Fall detection from the IMU: is the robot standing, falling or lying on the ground?

A robot that has fallen must say so: its head cannot track anything from the ground, a walk
must not go on, and whoever watches the run (a report, a team mate, an operator) must know.
The detector reads ``imu/data`` (orientation and angular rate) and decides, with hysteresis
in angle and in time so that a wobble or a kicked ball never makes it flicker:

* **standing** -> **falling**: the torso tilts beyond ``fall_tilt_deg``, or beyond
  ``lean_tilt_deg`` while turning faster than ``fall_rate`` (a fall caught early: leaning
  and rotating, before it is far over);
* **falling** -> **fallen**: beyond ``fallen_tilt_deg`` (lying on the ground);
* **falling** or **fallen** -> **standing**: back within ``stand_tilt_deg`` and nearly still
  (below ``rest_rate``) for ``recover_s`` without a break (caught itself, or got up).

Tilt is the angle between the torso's up axis and the vertical, whatever the heading; the
times are the IMU messages' stamps, so lockstep and real time decide alike.

Published: ``fall/state`` (std_msgs/String: ``standing``, ``falling`` or ``fallen``; on
every change, transient local, so a late subscriber learns the current state at once), and
on ``/diagnostics`` once a second and at every change: OK standing, WARN falling, ERROR
fallen, with the tilt, the angular rate and the count of falls.
"""

from __future__ import annotations

import math

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from sensor_msgs.msg import Imu
from std_msgs.msg import String

from efficient_comm import from_msg, latched_qos, to_msg
from efficient_comm.handle import NodeHandle

from ..errors import SimConfigError

STANDING, FALLING, FALLEN = "standing", "falling", "fallen"
LEVELS = {STANDING: DiagnosticStatus.OK, FALLING: DiagnosticStatus.WARN,
          FALLEN: DiagnosticStatus.ERROR}
LATCHED = latched_qos()
DIAGNOSTICS_PERIOD_S = 1.0


def tilt_rad(imu: Imu) -> float:
    """Angle between the torso's up axis and the vertical (0 upright, pi upside down)."""
    q = imu.orientation
    norm = q.w * q.w + q.x * q.x + q.y * q.y + q.z * q.z
    if norm <= 0 or not math.isfinite(norm):
        return math.nan
    up_z = 1 - 2 * (q.x * q.x + q.y * q.y) / norm  # z of the body's z axis in the world
    return math.acos(max(-1.0, min(1.0, up_z)))


def rate_rad_s(imu: Imu) -> float:
    w = imu.angular_velocity
    return math.sqrt(w.x * w.x + w.y * w.y + w.z * w.z)


class FallDetector:
    def __init__(self, node: NodeHandle) -> None:
        self.node = node
        degrees = [node.declare_parameter(name, default) for name, default in (
            ("stand_tilt_deg", 15.0), ("lean_tilt_deg", 20.0),
            ("fall_tilt_deg", 40.0), ("fallen_tilt_deg", 60.0))]
        stand, lean, fall, fallen = map(math.radians, degrees)
        self.fall_rate = node.declare_parameter("fall_rate", 1.5)
        self.rest_rate = node.declare_parameter("rest_rate", 0.5)
        self.recover_ns = round(node.declare_parameter("recover_s", 1.0) * 1e9)
        if not 0 < stand < lean <= fall < fallen <= math.pi:
            raise SimConfigError(
                "need 0 < stand_tilt_deg < lean_tilt_deg <= fall_tilt_deg < fallen_tilt_deg "
                f"<= 180, got {', '.join(f'{d:g}' for d in degrees)}")
        if self.fall_rate <= 0 or self.rest_rate <= 0 or self.recover_ns < 0:
            raise SimConfigError(
                f"need fall_rate > 0, rest_rate > 0 and recover_s >= 0, got {self.fall_rate}, "
                f"{self.rest_rate}, {self.recover_ns / 1e9}")
        self.stand, self.lean, self.fall, self.fallen = stand, lean, fall, fallen
        self.state = STANDING
        #: How often the robot went down (entered ``fallen``), and when (IMU stamps, ns).
        self.falls = 0
        self.fell_at_ns: list[int] = []
        self.tilt = self.rate = 0.0
        self.rejected = 0
        self._calm_since_ns: int | None = None
        self.pub = node.create_publisher(String, "fall/state", qos=LATCHED)
        self.diag_pub = node.create_publisher(DiagnosticArray, "/diagnostics", qos=10)
        node.create_subscription(Imu, "imu/data", self._on_imu, qos=10)
        node.create_timer(DIAGNOSTICS_PERIOD_S, self._report)
        self.pub.publish(String(data=self.state))

    @property
    def down(self) -> bool:
        """Falling or fallen: nothing that needs the robot upright should go on."""
        return self.state != STANDING

    def _on_imu(self, imu: Imu) -> None:
        tilt, rate = tilt_rad(imu), rate_rad_s(imu)
        if not (math.isfinite(tilt) and math.isfinite(rate)):
            self.rejected += 1  # a zero or broken quaternion says nothing about the posture
            return
        self.tilt, self.rate = tilt, rate
        stamp = from_msg(imu.header.stamp)
        state = self.state
        if state == STANDING and (
                tilt >= self.fall or (tilt >= self.lean and rate >= self.fall_rate)):
            state = FALLING
        if state != STANDING:
            if tilt >= self.fallen:
                state = FALLEN
            if tilt <= self.stand and rate <= self.rest_rate:
                if self._calm_since_ns is None:
                    self._calm_since_ns = stamp
                if stamp - self._calm_since_ns >= self.recover_ns:
                    state = STANDING
            else:
                self._calm_since_ns = None
        if state != self.state:
            self._change(state, stamp)

    def _change(self, state: str, stamp_ns: int) -> None:
        if state == FALLEN and self.state != FALLEN:
            self.falls += 1
            self.fell_at_ns.append(stamp_ns)
        self.state = state
        self._calm_since_ns = None
        line = f"posture: {state} (tilt {math.degrees(self.tilt):.0f}°, {self.rate:.1f} rad/s)"
        # One call site per severity: rclpy's logger raises when a site changes severity.
        if state == STANDING:
            self.node.logger.info(line)
        else:
            self.node.logger.warning(line)
        self.pub.publish(String(data=state))
        self._report()

    def _report(self) -> None:
        array = DiagnosticArray()
        array.header.stamp = to_msg(self.node.clock.now_ns())
        array.status.append(DiagnosticStatus(
            level=LEVELS[self.state],
            name=f"{self.node.fully_qualified_name}: posture",
            message=self.state,
            hardware_id="imu",
            values=[KeyValue(key="tilt_deg", value=f"{math.degrees(self.tilt):.1f}"),
                    KeyValue(key="rate_rad_s", value=f"{self.rate:.2f}"),
                    KeyValue(key="falls", value=str(self.falls))],
        ))
        self.diag_pub.publish(array)
