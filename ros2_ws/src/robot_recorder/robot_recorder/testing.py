"""Helpers for testing code that records: read a bag back with independent decoders, wait
for the writer thread.

Decoding with rosbags and with the mcap reader plus mcap-ros2-support (both only from the
schemas stored in the bag, never from the installed message classes) proves a bag is what
other ROS tools read, not just what our own reader accepts. Both are test dependencies,
imported when a helper is called.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from .writer import RecordWriter

__all__ = ["drained", "read_mcap", "read_rosbags"]


def read_rosbags(bag: Path) -> list[tuple[str, Any]]:
    """(topic, message) of every message, decoded by rosbags from the schemas in the bag."""
    from rosbags.rosbag2 import Reader
    from rosbags.typesys import Stores, get_typestore
    from rosbags.typesys.msg import get_types_from_msg

    store = get_typestore(Stores.EMPTY)
    out = []
    with Reader(bag) as reader:
        for conn in reader.connections:
            assert conn.msgdef is not None and conn.msgdef.data, conn.topic
            store.register(get_types_from_msg(conn.msgdef.data, conn.msgtype))
        for conn, _, raw in reader.messages():
            out.append((conn.topic, store.deserialize_cdr(raw, conn.msgtype)))
    return out


def read_mcap(path: Path) -> list[tuple[str, Any]]:
    """(topic, message) decoded by the mcap reader with mcap-ros2-support, for one file."""
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    with open(path, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        header = reader.get_header()
        assert header.profile == "ros2"
        out = []
        for schema, channel, _, decoded in reader.iter_decoded_messages(log_time_order=False):
            assert schema is not None and schema.encoding == "ros2msg"
            assert channel.message_encoding == "cdr"
            out.append((channel.topic, decoded))
        return out


def drained(writer: RecordWriter) -> None:
    """Wait until the writer thread has handled everything enqueued so far."""
    writer.drain().result(10)
