"""Mutation guard: finds the callback that changed a message shared by reference.

By-reference delivery is only safe while nobody modifies a received message. With the
guard on (``Container(guard_mutation=True)``, or ``EFFICIENT_COMM_GUARD=1``), every message
is fingerprinted when published and checked again after each callback that received it and
before each queued delivery; a difference is reported with the callback (or publisher)
responsible. A fingerprint hashes every field value, so it is a debugging mode.
"""

from __future__ import annotations

import array
import hashlib
from dataclasses import dataclass
from typing import Any


def _feed(h: Any, value: Any) -> None:
    """Hash a message by its field values (CDR bytes would not do: rclpy's serializer
    leaves alignment padding uninitialised, so one unchanged message can serialize to
    different bytes twice in a row)."""
    fields = getattr(value, "get_fields_and_field_types", None)
    if fields is not None:
        h.update(type(value).__name__.encode())
        for name in fields():
            _feed(h, getattr(value, name))
    elif isinstance(value, bytes | bytearray):
        h.update(b"b%d:" % len(value))
        h.update(value)
    elif isinstance(value, array.array) or hasattr(value, "tobytes"):
        data = value.tobytes()
        h.update(b"a%d:" % len(data))
        h.update(data)
    elif isinstance(value, list | tuple):
        h.update(b"[%d:" % len(value))
        for item in value:
            _feed(h, item)
    elif isinstance(value, str):
        encoded = value.encode()
        h.update(b"s%d:" % len(encoded))
        h.update(encoded)
    else:
        h.update(repr(value).encode())
        h.update(b";")


def fingerprint(msg: Any) -> bytes:
    h = hashlib.blake2b(digest_size=16)
    _feed(h, msg)
    return h.digest()


@dataclass(frozen=True, slots=True)
class MutationReport:
    """A message on ``topic`` changed; ``culprit`` names who held it at the time."""

    topic: str
    culprit: str

    def __str__(self) -> str:
        return (
            f"message on {self.topic} was modified by {self.culprit}; messages are shared "
            "by reference: copy before changing"
        )
