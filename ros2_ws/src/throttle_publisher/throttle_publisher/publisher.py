"""The publisher side: one data topic, and per throttled subscriber only what it asked for."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from rclpy.serialization import serialize_message

from efficient_comm.handle import NodeHandle, Publisher, QoSLike

from .errors import InvalidOptionsError
from .gate import Gate
from .options import ThrottleOptions, options_from_msg
from .protocol import (
    FORGET_AFTER_S,
    REQUEST_READER_QOS,
    reply_topic,
    request_topic,
    valid_subscriber_id,
)


@dataclass
class _Reply:
    gate: Gate
    publisher: Publisher
    unread_since_ns: int | None = None
    sent: int = 0
    sent_bytes: int = 0


@dataclass(frozen=True)
class SubscriberStats:
    """What a publisher sent one throttled subscriber (bytes: serialized payload size)."""

    options: ThrottleOptions
    sent: int
    sent_bytes: int


class ThrottledPublisher:
    """Publishes on ``topic`` for plain subscribers, and to each throttled subscriber only
    the samples its request lets through.

    Ask :meth:`wants` before computing an expensive sample; if nobody wants it, call
    :meth:`skip` instead of :meth:`publish` so that ``every_nth`` keeps counting::

        if camera_debug.wants():
            camera_debug.publish(render_debug_image())
        else:
            camera_debug.skip()
    """

    def __init__(
        self,
        node: NodeHandle,
        msg_type: type,
        topic: str,
        *,
        qos: QoSLike = 10,
        count_bytes: bool = False,
    ) -> None:
        """``count_bytes`` serializes each sent sample once to count its size (measuring)."""
        from efficient_comm_interfaces.msg import ThrottleRequest

        self._node = node
        self._msg_type = msg_type
        self._qos = qos
        self._pub = node.create_publisher(msg_type, topic, qos=qos)
        self.topic_name = self._pub.topic_name
        self._replies: dict[str, _Reply] = {}
        self._count_bytes = count_bytes
        self._requests = node.create_subscription(
            ThrottleRequest,
            request_topic(self.topic_name),
            self._on_request,
            qos=REQUEST_READER_QOS,
        )

    # -- requests -----------------------------------------------------------------------

    def _on_request(self, msg: Any) -> None:
        log = self._node.logger
        sid = msg.subscriber_id
        if msg.topic != self.topic_name or not valid_subscriber_id(sid):
            log.warning(
                f"throttle request for {msg.topic!r} from {sid!r} ignored: expected topic "
                f"{self.topic_name} and a subscriber id that is a name token"
            )
            return
        try:
            options, warnings = options_from_msg(msg)
        except InvalidOptionsError as exc:
            log.warning(f"throttle request from {sid} on {self.topic_name} ignored: {exc}")
            return
        for warning in warnings:
            log.warning(f"throttle request from {sid} on {self.topic_name}: {warning}")
        reply = self._replies.get(sid)
        if reply is None:
            pub = self._node.create_publisher(
                self._msg_type, reply_topic(self.topic_name, sid), qos=self._qos
            )
            self._replies[sid] = _Reply(Gate(options), pub)
        elif reply.gate.options != options:
            reply.gate.update(options)

    def requests(self) -> dict[str, ThrottleOptions]:
        """The current request of every throttled subscriber, by subscriber id."""
        return {sid: r.gate.options for sid, r in self._replies.items()}

    def stats(self) -> dict[str, SubscriberStats]:
        """Samples (and bytes, with ``count_bytes``) sent to each throttled subscriber."""
        return {
            sid: SubscriberStats(r.gate.options, r.sent, r.sent_bytes)
            for sid, r in self._replies.items()
        }

    # -- demand -------------------------------------------------------------------------

    def wants(self) -> bool:
        """Would a sample produced now go to anyone (plain or throttled subscriber)?"""
        if self._pub.get_subscription_count():
            return True
        now = self._node.clock.now_ns()
        return any(
            r.gate.wants(now) for r in self._replies.values()
            if r.publisher.get_subscription_count()
        )

    def next_due_ns(self) -> int | None:
        """Earliest time a sample would go to anyone; None if nobody wants any for now."""
        now = self._node.clock.now_ns()
        if self._pub.get_subscription_count():
            return now
        dues = [
            due for r in self._replies.values()
            if r.publisher.get_subscription_count()
            and (due := r.gate.next_due_ns(now)) is not None
        ]
        return min(dues, default=None)

    # -- samples ------------------------------------------------------------------------

    def publish(self, msg: Any) -> None:
        """Send ``msg`` to plain subscribers and to each throttled one that takes it."""
        self._pub.publish(msg)
        self._offer(msg)

    def skip(self) -> None:
        """A sample was due but not computed (nobody wanted it): count it all the same."""
        self._offer(None)

    def _offer(self, msg: Any) -> None:
        now = self._node.clock.now_ns()
        forget = []
        size = -1
        for sid, reply in self._replies.items():
            take = reply.gate.offer(now)
            if reply.publisher.get_subscription_count():
                reply.unread_since_ns = None
                if take and msg is not None:
                    reply.publisher.publish(msg)
                    reply.sent += 1
                    if self._count_bytes:
                        if size < 0:
                            size = len(serialize_message(msg))
                        reply.sent_bytes += size
            elif reply.unread_since_ns is None:
                reply.unread_since_ns = now
            elif now - reply.unread_since_ns > FORGET_AFTER_S * 1e9:
                forget.append(sid)
        for sid in forget:
            self._node.destroy_publisher(self._replies.pop(sid).publisher)
            self._node.logger.info(f"forgot throttled subscriber {sid} on {self.topic_name}")
