"""Which topics to record and how much of each: parsed, validated, comparable.

The parameter form is one string per topic, tokens separated by spaces::

    /robot/joint_states
    /robot/camera/image sensor_msgs/msg/Image max_rate_hz=5
    /robot/camera/image every_nth=3

The type is optional (the recorder finds it on the graph). ``max_rate_hz`` and ``every_nth``
make the recorder subscribe through throttle_publisher, so the samples it does not record
are never sent by a ThrottledPublisher; a plain publisher's surplus the recorder drops
itself.
"""

from __future__ import annotations

from dataclasses import dataclass

from throttle_publisher import InvalidOptionsError, ThrottleOptions

from .errors import RecorderConfigError

__all__ = ["TopicSelection", "parse_selection"]


@dataclass(frozen=True, slots=True, kw_only=True)
class TopicSelection:
    """One recorded topic: name, optional type, optional throttle."""

    name: str
    type: str = ""
    max_rate_hz: float = 0.0
    every_nth: int = 1

    def __post_init__(self) -> None:
        if not self.name or any(c.isspace() for c in self.name):
            raise RecorderConfigError(f"invalid topic name {self.name!r}")
        try:
            self.throttle()
        except InvalidOptionsError as exc:
            raise RecorderConfigError(f"{self.name}: {exc}") from exc

    def throttle(self) -> ThrottleOptions | None:
        """Options for a ThrottledSubscription, or None when every sample is recorded."""
        options = ThrottleOptions(max_rate_hz=self.max_rate_hz, every_nth=self.every_nth)
        return None if options.unlimited else options


def parse_selection(text: str) -> TopicSelection:
    """``"NAME [TYPE] [max_rate_hz=R] [every_nth=N]"`` as a :class:`TopicSelection`."""
    tokens = text.split()
    if not tokens:
        raise RecorderConfigError("empty topic entry")
    name, rest = tokens[0], tokens[1:]
    msg_type = ""
    options: dict[str, float | int] = {}
    for token in rest:
        key, sep, value = token.partition("=")
        if not sep:
            if msg_type:
                raise RecorderConfigError(f"{text!r}: two types given ({msg_type}, {token})")
            msg_type = token
            continue
        if key not in ("max_rate_hz", "every_nth"):
            # Checked apart from the value: RecorderConfigError is a ValueError too.
            raise RecorderConfigError(f"{text!r}: unknown option {key!r} (max_rate_hz, every_nth)")
        try:
            options[key] = float(value) if key == "max_rate_hz" else int(value)
        except ValueError as exc:
            raise RecorderConfigError(f"{text!r}: {key} has an invalid value {value!r}") from exc
    return TopicSelection(name=name, type=msg_type, **options)  # type: ignore[arg-type]
