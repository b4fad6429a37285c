"""QoS mapping between ROS 2 profiles and what other systems can express.

ROS 1 has one knob that matters, latching, which is ROS 2's TRANSIENT_LOCAL durability:
a bridged publisher latches exactly when its ROS 2 side is TRANSIENT_LOCAL (configure that for
ROS 1 topics that are latched, so late ROS 2 joiners get the last value too); everything else
in ROS 1 is reliable TCP. The team link maps reliability onto the
engine's (best-effort samples may be dropped under congestion, reliable ones are resent).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from ..errors import ConfigError

_RELIABILITY = {
    "reliable": ReliabilityPolicy.RELIABLE,
    "best_effort": ReliabilityPolicy.BEST_EFFORT,
}
_DURABILITY = {
    "volatile": DurabilityPolicy.VOLATILE,
    "transient_local": DurabilityPolicy.TRANSIENT_LOCAL,
}


def profile_from_config(spec: Mapping[str, Any] | int | None, *, where: str) -> QoSProfile:
    """``{depth, reliability, durability}`` (or a depth) to a profile; KEEP_LAST always."""
    if spec is None:
        spec = {}
    if isinstance(spec, int) and not isinstance(spec, bool):
        spec = {"depth": spec}
    if not isinstance(spec, Mapping):
        raise ConfigError(f"{where}: qos must be a depth or a mapping, not {spec!r}")
    unknown = set(spec) - {"depth", "reliability", "durability"}
    if unknown:
        raise ConfigError(f"{where}: unknown qos keys {sorted(unknown)}")
    depth = spec.get("depth", 10)
    if isinstance(depth, bool) or not isinstance(depth, int) or depth < 1:
        raise ConfigError(f"{where}: qos depth must be an integer >= 1, not {depth!r}")
    try:
        reliability = _RELIABILITY[spec.get("reliability", "reliable")]
        durability = _DURABILITY[spec.get("durability", "volatile")]
    except KeyError as exc:
        raise ConfigError(f"{where}: unknown qos value {exc}") from None
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST, depth=depth, reliability=reliability, durability=durability
    )


def ros1_latch(profile: QoSProfile) -> bool:
    """A ROS 1 publisher latches exactly when the ROS 2 side keeps history for late joiners."""
    return bool(profile.durability == DurabilityPolicy.TRANSIENT_LOCAL)
