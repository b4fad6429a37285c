"""QoS normalisation and the compatibility rules DDS applies between two endpoints."""

from __future__ import annotations

from collections.abc import Callable, Sequence

from rclpy.event_handler import QoSMessageLostInfo, SubscriptionEventCallbacks
from rclpy.qos import (
    DurabilityPolicy,
    HistoryPolicy,
    QoSProfile,
    ReliabilityPolicy,
)

from .handle import QoSLike


def latched_qos(*, depth: int = 1) -> QoSProfile:
    """The latched profile: reliable, transient local, the last ``depth`` messages.

    What ROS 1 called latching: a late subscriber (one that asks for transient local too)
    gets the last message at once. Every latched topic of ours uses this one profile, so a
    publisher and its subscribers cannot disagree on it. A new object each call: QoSProfile
    is mutable.
    """
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=depth,
                      reliability=ReliabilityPolicy.RELIABLE,
                      durability=DurabilityPolicy.TRANSIENT_LOCAL)


def to_profile(qos: QoSLike) -> QoSProfile:
    if isinstance(qos, QoSProfile):
        return qos
    if isinstance(qos, bool) or not isinstance(qos, int) or qos < 0:
        raise TypeError(f"qos must be a QoSProfile or a non-negative depth, not {qos!r}")
    return QoSProfile(depth=qos)


def queue_limit(profile: QoSProfile) -> int | None:
    """How many messages a subscriber may hold: None for KEEP_ALL."""
    if profile.history == HistoryPolicy.KEEP_ALL:
        return None
    return max(1, int(profile.depth))


def is_transient_local(profile: QoSProfile) -> bool:
    return bool(profile.durability == DurabilityPolicy.TRANSIENT_LOCAL)


def compatible(pub: QoSProfile, sub: QoSProfile) -> bool:
    """DDS request/offer: a subscriber may not ask for more than the publisher offers."""
    return incompatible_policy(pub, sub) is None


def incompatible_policy(pub: QoSProfile, sub: QoSProfile) -> str | None:
    """The policy (as DDS names it) for which ``sub`` asks more than ``pub`` offers."""
    if (
        sub.reliability == ReliabilityPolicy.RELIABLE
        and pub.reliability == ReliabilityPolicy.BEST_EFFORT
    ):
        return "RELIABILITY"
    if is_transient_local(sub) and not is_transient_local(pub):
        return "DURABILITY"
    return None


def matching_qos(offered: Sequence[QoSProfile], *, depth: int = 10) -> QoSProfile:
    """The QoS a reader takes to receive from publishers offering ``offered``.

    Reliable unless a publisher is best effort (a reliable reader would get nothing from
    it); transient local when every publisher offers it, so a latched publisher's last
    message arrives (a transient-local reader would not match a volatile publisher, so
    one volatile publisher makes it volatile). Pass ``node.graph.publishers_qos(topic)``.
    """
    best_effort = any(q.reliability == ReliabilityPolicy.BEST_EFFORT for q in offered)
    latched = bool(offered) and all(is_transient_local(q) for q in offered)
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST, depth=depth,
        reliability=ReliabilityPolicy.BEST_EFFORT if best_effort else ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE,
    )


def lost_events(on_lost: Callable[[int], None] | None) -> SubscriptionEventCallbacks | None:
    """rclpy's event callbacks that tell ``on_lost`` how many more messages DDS lost."""
    if on_lost is None:
        return None

    def lost(info: QoSMessageLostInfo) -> None:
        on_lost(int(info.total_count_change))

    return SubscriptionEventCallbacks(message_lost=lost)
