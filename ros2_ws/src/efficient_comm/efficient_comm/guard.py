"""Mutation guard: finds the callback that changed a message shared by reference.

By-reference delivery is only safe while nobody modifies a received message. With the
guard on (``Container(guard_mutation=True)``, or ``EFFICIENT_COMM_GUARD=1``), every message
is fingerprinted when published and checked again after each callback that received it and
before each queued delivery; a difference is reported with the callback (or publisher)
responsible. It costs a serialization per check, so it is a debugging mode.
"""

from __future__ import annotations

import hashlib
import pickle
from dataclasses import dataclass
from typing import Any

from rclpy.serialization import serialize_message


def fingerprint(msg: Any) -> bytes:
    try:
        data = serialize_message(msg)
    except Exception:  # not a ROS message: fall back to Python's own serialization
        data = pickle.dumps(msg)
    return hashlib.blake2b(data, digest_size=16).digest()


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
