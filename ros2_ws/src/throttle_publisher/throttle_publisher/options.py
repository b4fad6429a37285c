"""What a subscriber may ask a publisher for, and how the options combine.

Options (protocol version 1):

* ``max_rate_hz`` — at most this many samples per second on average; ``0`` means no limit.
* ``every_nth`` — only every n-th sample the publisher produces (the 1st, n+1-th, ...).
* ``paused`` — nothing at all until the subscriber changes its request.

They combine as filters in this order: ``paused`` stops everything; otherwise a sample must
be one of every ``every_nth`` samples produced, and of those, ``max_rate_hz`` keeps as many as
its rate allows. So ``every_nth=10, max_rate_hz=1`` on a 30 Hz source gives 1 Hz (every 30th
sample), and on a 5 Hz source 0.5 Hz (every 10th).

On the wire, options travel by name (``ThrottleOption``), so newer options do not break
older peers: :func:`from_wire` ignores unknown names with a warning and rejects invalid
values; the caller keeps the subscriber's previous request in that case.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass, fields
from typing import Any

from .errors import InvalidOptionsError

PROTOCOL_VERSION = 1


@dataclass(frozen=True, slots=True, kw_only=True)
class ThrottleOptions:
    """A subscriber's request; the defaults ask for everything."""

    max_rate_hz: float = 0.0
    every_nth: int = 1
    paused: bool = False

    def __post_init__(self) -> None:
        rate = self.max_rate_hz
        if isinstance(rate, bool) or not isinstance(rate, int | float):
            raise InvalidOptionsError(f"max_rate_hz must be a number, not {rate!r}")
        if math.isnan(rate) or rate < 0 or math.isinf(rate):
            raise InvalidOptionsError(
                f"max_rate_hz must be finite and >= 0 (0 = no limit), not {rate!r}"
            )
        n = self.every_nth
        if isinstance(n, bool) or not isinstance(n, int) or n < 1:
            raise InvalidOptionsError(f"every_nth must be an integer >= 1, not {n!r}")
        if not isinstance(self.paused, bool):
            raise InvalidOptionsError(f"paused must be True or False, not {self.paused!r}")

    @property
    def unlimited(self) -> bool:
        """True if these options ask for every sample (a plain subscriber would do)."""
        return not self.paused and self.every_nth == 1 and self.max_rate_hz == 0.0

    def to_wire(self) -> list[tuple[str, float]]:
        """``(name, value)`` pairs for ``ThrottleOption`` messages; defaults are left out."""
        out: list[tuple[str, float]] = []
        for f in fields(self):
            value = getattr(self, f.name)
            if value != f.default:
                out.append((f.name, float(value)))
        return out


_NAMES = {f.name for f in fields(ThrottleOptions)}


def from_wire(pairs: Iterable[tuple[str, float]]) -> tuple[ThrottleOptions, list[str]]:
    """Options from ``(name, value)`` pairs received over the wire.

    Returns the options and warnings about names this version does not know (those are
    ignored). Raises InvalidOptionsError for a known option with an invalid value.
    """
    values: dict[str, Any] = {}
    warnings: list[str] = []
    for name, value in pairs:
        if name not in _NAMES:
            warnings.append(f"unknown throttle option {name!r} ignored")
            continue
        if name in values:
            raise InvalidOptionsError(f"throttle option {name!r} given twice")
        if name == "every_nth":
            if not math.isfinite(value) or value != int(value):
                raise InvalidOptionsError(f"every_nth must be an integer, not {value!r}")
            values[name] = int(value)
        elif name == "paused":
            if value not in (0.0, 1.0):
                raise InvalidOptionsError(f"paused must be 0 or 1, not {value!r}")
            values[name] = value == 1.0
        else:
            values[name] = float(value)
    return ThrottleOptions(**values), warnings


def request_msg(subscriber_id: str, topic: str, options: ThrottleOptions) -> Any:
    """The ``ThrottleRequest`` message a subscriber publishes for ``options``."""
    from efficient_comm_interfaces.msg import ThrottleOption, ThrottleRequest

    return ThrottleRequest(
        subscriber_id=subscriber_id,
        topic=topic,
        options=[ThrottleOption(name=n, value=v) for n, v in options.to_wire()],
    )


def options_from_msg(msg: Any) -> tuple[ThrottleOptions, list[str]]:
    """Options of a received ``ThrottleRequest`` (see :func:`from_wire`)."""
    return from_wire((o.name, o.value) for o in msg.options)
