"""A recorded robot's local time mapped to team reference time.

The clock-sync component publishes its estimate on ``/team_clock/offset`` about once a
second; a recorder on the robot records that topic, and may also store the estimate it held
when a file was written as an MCAP metadata record named ``team_clock`` (keys as the
:class:`ClockOffset` fields, see :func:`offset_metadata`). :class:`OffsetModel` turns either
into a function ``to_reference(local_ns)``: between two estimates it blends their linear
models (offset plus drift) by position, so the mapping is continuous even when the estimate
moves or switches source; before the first and after the last it extrapolates with drift.
"""

from __future__ import annotations

import bisect
import itertools
import math
import os
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from builtin_interfaces.msg import Time

from efficient_comm import from_msg, to_msg

from .errors import LogFormatError, NoEstimateError, OtherRobotError

__all__ = ["METADATA_NAME", "Knot", "OffsetModel", "offset_metadata"]

#: Name of the MCAP metadata record holding a recording's clock estimate.
METADATA_NAME = "team_clock"
#: The topic the estimates are recorded from (any namespace prefix is accepted).
OFFSET_SUFFIX = "/team_clock/offset"


@dataclass(frozen=True, slots=True)
class Knot:
    """One estimate: ``reference = local + offset_ns + drift_ppm * 1e-6 * (local - stamp_ns)``."""

    stamp_ns: int
    offset_ns: int
    drift_ppm: float
    uncertainty_ns: int
    hops: int = 0
    source: str = ""

    def offset_at(self, local_ns: int) -> float:
        return self.offset_ns + self.drift_ppm * 1e-6 * (local_ns - self.stamp_ns)


def offset_metadata(msg: Any) -> dict[str, str]:
    """A :class:`ClockOffset` as the string key/values of a ``team_clock`` metadata record."""
    stamp = from_msg(msg.stamp)
    return {
        "robot": str(msg.robot),
        "reference": str(msg.reference),
        "source": str(msg.source),
        "stamp_ns": str(stamp),
        "offset_ns": str(int(msg.offset_ns)),
        "drift_ppm": repr(float(msg.drift_ppm)),
        "uncertainty_ns": str(int(msg.uncertainty_ns)),
        "hops": str(int(msg.hops)),
        "samples": str(int(msg.samples)),
        "valid": "true" if msg.valid else "false",
    }


class OffsetModel:
    """Local time of one robot -> team reference time, from its recorded estimates."""

    def __init__(self, knots: Iterable[Knot], *, robot: str = "", reference: str = "",
                 holdover_ppm: float = 0.5) -> None:
        self.knots = sorted(knots, key=lambda k: k.stamp_ns)
        if not self.knots:
            raise NoEstimateError(f"no clock estimate for robot {robot or '?'}")
        self.robot = robot
        self.reference = reference
        self.holdover_ppm = holdover_ppm
        self._stamps = [k.stamp_ns for k in self.knots]

    def __repr__(self) -> str:
        first = self.knots[0]
        return (f"OffsetModel(robot={self.robot!r}, reference={self.reference!r}, "
                f"knots={len(self.knots)}, offset_ns={first.offset_ns}, "
                f"drift_ppm={first.drift_ppm:.3f})")

    @classmethod
    def identity(cls, *, robot: str = "", reference: str = "") -> OffsetModel:
        """For a log whose clock is the reference, or is said to be on reference time.

        Without ``reference`` the reference robot is left unnamed: the claim is the
        caller's (a log synchronised by other means), so a merge cannot hold it against the
        other logs' reference. With it (a log of the reference itself, such as a simulated
        world whose time the robots synchronise to, which measures nothing and so records
        no estimate), a merge refuses logs aligned to any other reference. Its bound is
        zero at every time (no holdover growth): nothing was estimated that could drift
        away, and a bound grown from the epoch (±900 s today) would say nothing.
        """
        return cls([Knot(0, 0, 0.0, 0)], robot=robot, reference=reference, holdover_ppm=0.0)

    @classmethod
    def constant(cls, offset_ns: int, *, drift_ppm: float = 0.0, stamp_ns: int = 0,
                 uncertainty_ns: int = 0, robot: str = "") -> OffsetModel:
        """One known offset (measured some other way)."""
        return cls([Knot(stamp_ns, offset_ns, drift_ppm, uncertainty_ns)], robot=robot)

    def to_reference(self, local_ns: int) -> int:
        """Team reference time at this robot's local time ``local_ns``."""
        return local_ns + round(self.offset_at(local_ns))

    def offset_at(self, local_ns: int) -> float:
        """Reference minus local time at ``local_ns`` (the blend of the two nearest lines)."""
        i = bisect.bisect_right(self._stamps, local_ns)
        if i == 0:
            return self.knots[0].offset_at(local_ns)
        if i == len(self.knots):
            return self.knots[-1].offset_at(local_ns)
        before, after = self.knots[i - 1], self.knots[i]
        w = (local_ns - before.stamp_ns) / (after.stamp_ns - before.stamp_ns)
        return (1.0 - w) * before.offset_at(local_ns) + w * after.offset_at(local_ns)

    def uncertainty_at(self, local_ns: int) -> int:
        """Error bound of :meth:`to_reference` at ``local_ns``.

        Each estimate's line is within its own bound, grown by holdover away from its
        stamp; a blend of two lines is within the same blend of their bounds (not within
        the smaller one: the looser estimate still weighs in).
        """
        rate = self.holdover_ppm * 1e-6

        def bound(knot: Knot) -> float:
            return knot.uncertainty_ns + rate * abs(local_ns - knot.stamp_ns)

        i = bisect.bisect_right(self._stamps, local_ns)
        if i == 0:
            return math.ceil(bound(self.knots[0]))
        if i == len(self.knots):
            return math.ceil(bound(self.knots[-1]))
        before, after = self.knots[i - 1], self.knots[i]
        w = (local_ns - before.stamp_ns) / (after.stamp_ns - before.stamp_ns)
        return math.ceil((1.0 - w) * bound(before) + w * bound(after))

    def max_uncertainty(self, start_ns: int, end_ns: int) -> int:
        """Largest :meth:`uncertainty_at` over ``[start_ns, end_ns]`` (local times).

        Outside the estimates the bound grows away from them, so only the ends count.
        Between two estimates ``d`` apart, at fraction ``w``, it is ``(1-w)·u₀ + w·u₁ +
        2·rate·d·w(1-w)``: concave, largest at ``w = 1/2 + (u₁-u₀)/(4·rate·d)``.
        """
        points = {start_ns, end_ns}
        rate = self.holdover_ppm * 1e-6
        for before, after in itertools.pairwise(self.knots):
            span = after.stamp_ns - before.stamp_ns
            points.update((before.stamp_ns, after.stamp_ns))
            if span > 0 and rate > 0:
                w = 0.5 + (after.uncertainty_ns - before.uncertainty_ns) / (4 * rate * span)
                points.add(before.stamp_ns + round(min(max(w, 0.0), 1.0) * span))
        return max(self.uncertainty_at(min(max(t, start_ns), end_ns)) for t in points)

    # -- from recordings ------------------------------------------------------------------

    @classmethod
    def from_messages(cls, messages: Iterable[Any], *, robot: str | None = None) -> OffsetModel:
        """From ClockOffset messages (any objects with its fields); invalid ones are skipped.

        ``robot`` picks one robot's estimates when the messages hold several (a shared
        domain records everybody's); without it, there must be exactly one.
        """
        by_robot: dict[str, list[Knot]] = {}
        references: dict[str, str] = {}
        for msg in messages:
            if not getattr(msg, "valid", True):
                by_robot.setdefault(str(msg.robot), [])
                continue
            stamp = from_msg(msg.stamp)
            by_robot.setdefault(str(msg.robot), []).append(Knot(
                stamp, int(msg.offset_ns), float(msg.drift_ppm), int(msg.uncertainty_ns),
                int(getattr(msg, "hops", 0)), str(getattr(msg, "source", "")),
            ))
            references[str(msg.robot)] = str(msg.reference)
        name = _pick_robot(by_robot, robot)
        if not by_robot.get(name):
            raise NoEstimateError(
                f"robot {name!r} never had a clock estimate (no path to the reference?)"
            )
        return cls(by_robot[name], robot=name, reference=references.get(name, ""))

    @classmethod
    def from_metadata(cls, records: Iterable[Mapping[str, str]], *,
                      robot: str | None = None) -> OffsetModel:
        """From ``team_clock`` metadata records (see :func:`offset_metadata`).

        Also accepts the message flattened field by field (``stamp.sec``, ``stamp.nanosec``,
        ``valid`` as ``True``/``False``), as a recorder that stores any message would.
        """
        messages = []
        for values in records:
            try:
                if "stamp_ns" in values:
                    stamp = int(values["stamp_ns"])
                else:
                    stamp = from_msg(Time(sec=int(values["stamp.sec"]),
                                          nanosec=int(values["stamp.nanosec"])))
                messages.append(_Record(
                    robot=values.get("robot", ""), reference=values.get("reference", ""),
                    source=values.get("source", ""), stamp=to_msg(stamp),
                    offset_ns=int(values["offset_ns"]),
                    drift_ppm=float(values.get("drift_ppm", "0")),
                    uncertainty_ns=int(values.get("uncertainty_ns", "0")),
                    hops=int(values.get("hops", "0")),
                    valid=values.get("valid", "true").lower() in ("true", "1"),
                ))
            except (KeyError, ValueError) as exc:
                raise LogFormatError(f"malformed {METADATA_NAME} metadata {dict(values)}: "
                                     f"{exc}") from exc
        return cls.from_messages(messages, robot=robot)

    @classmethod
    def from_mcap(cls, path: str | os.PathLike[str], *, robot: str | None = None) -> OffsetModel:
        """From the ``/team_clock/offset`` messages recorded in an MCAP file or bag directory.

        Falls back to ``team_clock`` metadata records when no estimate was recorded as
        messages. Raises :class:`NoEstimateError` when the log holds neither (or only
        ``valid = false`` ones), :class:`LogFormatError` when it cannot be read.
        """
        from .bag import LogReader

        reader = LogReader(Path(path))
        meta = [values for name, values in reader.metadata() if name == METADATA_NAME]
        if robot is None:
            named = {m.get("robot", "") for m in meta} - {""}
            if len(named) == 1:
                robot = named.pop()
        messages = []
        decoders: dict[int, Any] = {}
        topics = [t for t in reader.topics() if t == OFFSET_SUFFIX or t.endswith(OFFSET_SUFFIX)]
        for schema, channel, message in reader.records(topics=topics) if topics else ():
            decode = decoders.get(channel.id)
            if decode is None:
                decode = decoders[channel.id] = _decoder(schema, path)
            try:
                messages.append(decode(message.data))
            except Exception as exc:  # malformed CDR: say which file, keep nothing wrong
                raise LogFormatError(f"{path}: undecodable {channel.topic} message at "
                                     f"{message.log_time}: {exc}") from exc
        try:
            if messages:
                return cls.from_messages(messages, robot=robot)
        except NoEstimateError:
            if not meta:
                raise
        if meta:
            return cls.from_metadata(meta, robot=robot)
        raise NoEstimateError(f"{path} holds no {OFFSET_SUFFIX} messages and no "
                              f"{METADATA_NAME!r} metadata: cannot align it")


class _Record:
    """A ClockOffset look-alike built from a metadata record."""

    def __init__(self, *, robot: str, reference: str, source: str, stamp: Time,
                 offset_ns: int, drift_ppm: float, uncertainty_ns: int, hops: int,
                 valid: bool) -> None:
        self.robot, self.reference, self.source = robot, reference, source
        self.stamp = stamp
        self.offset_ns, self.drift_ppm = offset_ns, drift_ppm
        self.uncertainty_ns, self.hops, self.valid = uncertainty_ns, hops, valid


def _pick_robot(by_robot: Mapping[str, list[Knot]], robot: str | None) -> str:
    if robot is not None:
        if robot not in by_robot:
            if by_robot:
                raise OtherRobotError(f"no clock estimates of robot {robot!r}; the log has "
                                      f"those of {sorted(by_robot)}", wanted=robot,
                                      found=sorted(by_robot))
            raise NoEstimateError(f"no clock estimates of robot {robot!r}; the log has none")
        return robot
    if len(by_robot) != 1:
        raise NoEstimateError(
            f"the log holds clock estimates of {sorted(by_robot) or 'no robot'}; "
            "say which robot recorded it (robot=...)"
        )
    return next(iter(by_robot))


def _decoder(schema: Any, path: Any) -> Any:
    """Decode ClockOffset CDR by the recorded schema, else by the installed type."""
    if schema is not None and schema.data and schema.encoding == "ros2msg":
        from mcap_ros2.decoder import DecoderFactory

        decoder = DecoderFactory().decoder_for("cdr", schema)
        if decoder is not None:
            return decoder
    from rclpy.serialization import deserialize_message

    from team_clock_interfaces.msg import ClockOffset

    return lambda data: deserialize_message(data, ClockOffset)
