"""The throttle protocol (version 1): topics, QoS and timing, precisely enough to reimplement.

For a data topic ``T`` (fully qualified, e.g. ``/camera/image``):

* **Request topic** ``T/_throttle`` carries ``efficient_comm_interfaces/msg/ThrottleRequest``
  from each throttled subscriber to every publisher of ``T``. QoS: reliable, transient
  local; writers keep last 1, readers keep all (a keyless topic: with keep-last-1 readers,
  requests of several subscribers arriving together would overwrite each other). Each
  subscriber has its own writer, so a publisher that starts later receives the current
  request of every subscriber still alive. A subscriber changes its options by publishing
  a new request with the same ``subscriber_id``.
* **Reply topic** ``T/_throttle_<subscriber_id>`` carries the samples meant for that one
  subscriber, with the data topic's type and the subscriber's data QoS. A throttled
  subscriber reads only its reply topic, never ``T`` itself; so the bytes a publisher sends
  it are exactly the samples it asked for. ``subscriber_id`` is a ROS name token
  (letters, digits, underscores; it starts with a letter).
* Plain subscribers (``ros2 topic echo``, rosbag, plain rclpy) read ``T`` as always and get
  every sample.

Topic tokens that start with ``_`` are hidden from ``ros2 topic list`` by default.

Publisher behaviour: for each sample it produces, a publisher decides per subscriber with
the options' rules (:mod:`throttle_publisher.options`, :mod:`throttle_publisher.gate`) and
writes the sample to that subscriber's reply topic; it writes ``T`` as usual. A request
with an invalid value is ignored with a warning (the subscriber's previous request stays in
effect); unknown option names are ignored with a warning.

Departure: a subscriber that goes away cleanly removes its reply reader, and the
publisher stops writing for it at once (its reply writer has no matched reader). A
subscriber killed with SIGKILL stops costing bandwidth when DDS drops the match, which is
after the participant's lease duration (Fast DDS default: 20 s), and the publisher forgets
its request :data:`FORGET_AFTER_S` seconds later.
"""

from __future__ import annotations

import uuid

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from efficient_comm import latched_qos

PROTOCOL_VERSION = 1
REQUEST_SUFFIX = "_throttle"
#: A request whose reply topic has had no reader this long is dropped by the publisher.
FORGET_AFTER_S = 30.0

#: The subscriber's request writer.
REQUEST_QOS = latched_qos()
#: The publisher's request reader.
REQUEST_READER_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_ALL,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
)


def request_topic(topic: str) -> str:
    return f"{topic.rstrip('/')}/{REQUEST_SUFFIX}"


def reply_topic(topic: str, subscriber_id: str) -> str:
    return f"{topic.rstrip('/')}/{REQUEST_SUFFIX}_{subscriber_id}"


def new_subscriber_id() -> str:
    """A fresh id that is also a valid ROS name token."""
    return "s" + uuid.uuid4().hex


def valid_subscriber_id(subscriber_id: str) -> bool:
    return (
        bool(subscriber_id)
        and subscriber_id[0].isalpha()
        and subscriber_id.isascii()
        and all(c.isalnum() or c == "_" for c in subscriber_id)
    )
