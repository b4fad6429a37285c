"""The subscriber side: ask the publishers of a topic for only what this callback needs."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from efficient_comm.handle import NodeHandle, QoSLike

from .errors import InvalidOptionsError
from .options import ThrottleOptions, request_msg
from .protocol import REQUEST_QOS, REQUEST_SUFFIX, new_subscriber_id, reply_topic


class ThrottledSubscription:
    """Receives from throttle-aware publishers of ``topic`` only what ``options`` ask for.

    Invalid options raise :class:`~throttle_publisher.InvalidOptionsError` here, before
    anything is sent. :meth:`update` changes them at run time.
    """

    def __init__(
        self,
        node: NodeHandle,
        msg_type: type,
        topic: str,
        callback: Callable[[Any], None],
        *,
        options: ThrottleOptions,
        qos: QoSLike = 10,
    ) -> None:
        from efficient_comm_interfaces.msg import ThrottleRequest

        _check(options)
        self._node = node
        self.subscriber_id = new_subscriber_id()
        self._requests = node.create_publisher(
            ThrottleRequest, f"{topic.rstrip('/')}/{REQUEST_SUFFIX}", qos=REQUEST_QOS
        )
        self.topic_name = self._requests.topic_name.rsplit("/", 1)[0]
        self._data = node.create_subscription(
            msg_type, reply_topic(self.topic_name, self.subscriber_id), callback, qos=qos
        )
        self.options = options
        self._send()

    def _send(self) -> None:
        self._requests.publish(request_msg(self.subscriber_id, self.topic_name, self.options))

    @property
    def answered(self) -> bool:
        """Whether a throttle-aware publisher hears this subscriber's requests (one
        subscribes to the request topic). A plain publisher never does and never sends on
        the reply topic: a subscriber that finds none must take the plain topic's samples
        and drop the surplus itself (robot_recorder does)."""
        return self._requests.get_subscription_count() > 0

    def update(self, options: ThrottleOptions) -> None:
        """Ask for something else from now on (publishers adapt without restarting)."""
        _check(options)
        self.options = options
        self._send()

    def close(self) -> None:
        """Stop receiving; publishers stop sending at once (the reply reader is gone)."""
        self._node.destroy_subscription(self._data)
        self._node.destroy_publisher(self._requests)


def _check(options: object) -> None:
    if not isinstance(options, ThrottleOptions):
        raise InvalidOptionsError(f"options must be ThrottleOptions, not {options!r}")
