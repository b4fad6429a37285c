"""Message translators between ROS 2 message objects and ROS 1 dict messages.

A translator is compiled once per (ROS 1 type, ROS 2 class) pair into a list of field
steps. Fields pair up by name (exactly, then ignoring case: ROS 2 lowercased some), nested
types recursively, ``time``/``duration`` with ``builtin_interfaces``; a :class:`TypeRule`
from the YAML file renames fields where the names differ. Fields only one side has are left
at their defaults (ROS 1's ``Header.seq``, for example) and listed in :attr:`unmatched`.
"""

from __future__ import annotations

import array
import struct
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

from ..errors import OutOfRangeError, TranslationError
from .ros1_types import (
    BYTE_TYPES,
    ROS2_PRIMITIVES,
    STRUCT_CODES,
    Field,
    TypeRegistry,
    ros2_class,
    ros2_type_name,
    split_ros2_type,
)

Convert = Callable[[Any], Any]

#: ROS 2 element types whose arrays are not ``array.array`` in rclpy (bools, bytes, text).
_NOT_ARRAY_CODED = frozenset({"boolean", "octet", "char", "byte", "string", "wstring"})


def _array_code(elem: str) -> str | None:
    """The ``array.array`` typecode rclpy uses for an unbounded array of ``elem``, if any."""
    if elem in _NOT_ARRAY_CODED:
        return None
    return STRUCT_CODES.get(ROS2_PRIMITIVES.get(elem, ""))
_TIME_TYPES = {"builtin_interfaces/Time": "time", "builtin_interfaces/Duration": "duration"}


@dataclass(frozen=True, slots=True)
class TypeRule:
    """A YAML rule pairing a ROS 1 type with a ROS 2 type whose names do not match.

    ``fields`` maps ROS 2 field names to ROS 1 field names; ``ros1_definition`` gives the
    ROS 1 ``.msg`` text when no peer will tell it (needed to publish a custom type).
    """

    ros1: str
    ros2: str
    fields: Mapping[str, str] = field(default_factory=dict)
    ros1_definition: str | None = None


def _base(ros2_type: str) -> str:
    return "string" if ros2_type.startswith(("string<", "wstring<")) else ros2_type


class Translator:
    """Converts one ROS 1 type to one ROS 2 class and back."""

    def __init__(
        self,
        registry: TypeRegistry,
        ros1_type: str,
        ros2_cls: type,
        *,
        rules: Mapping[tuple[str, str], TypeRule] | None = None,
    ) -> None:
        self.ros1_type = ros1_type
        self.ros2_cls = ros2_cls
        self.unmatched: list[str] = []
        self._registry = registry
        self._rules = rules or {}
        self._to_ros2 = self._plan_to_ros2(ros1_type, ros2_cls, "")
        self._to_ros1 = self._plan_to_ros1(ros1_type, ros2_cls, "")

    def to_ros2(self, value: dict[str, Any]) -> Any:
        """The ROS 2 message; OutOfRangeError when a value does not fit its ROS 2 field
        (a ROS 1 ``time`` beyond 2^31 s in ROS 2's int32 seconds): rclpy's setters check
        every range, so nothing is wrapped or cut silently."""
        try:
            return self._to_ros2(value)
        except (AssertionError, OverflowError) as exc:
            raise OutOfRangeError(f"{self.ros1_type} -> ROS 2: {exc}") from exc
        except (TypeError, ValueError, KeyError) as exc:
            raise TranslationError(f"{self.ros1_type} -> ROS 2: {exc}") from exc

    def to_ros1(self, msg: Any) -> dict[str, Any]:
        try:
            result: dict[str, Any] = self._to_ros1(msg)
            return result
        except (TypeError, ValueError, AttributeError) as exc:
            raise TranslationError(f"ROS 2 -> {self.ros1_type}: {exc}") from exc

    # --- pairing -----------------------------------------------------------------------

    def _pairs(self, ros1_type: str, ros2_cls: type, where: str) -> list[tuple[str, str, Field]]:
        spec = self._registry.get(ros1_type)
        ros2_fields: dict[str, str] = ros2_cls.get_fields_and_field_types()  # type: ignore[attr-defined]
        rule = self._rules.get((ros1_type, ros2_type_name(ros2_cls)))
        renames = dict(rule.fields) if rule else {}
        by_name = {f.name: f for f in spec.fields}
        by_lower = {f.name.lower(): f for f in spec.fields}
        pairs: list[tuple[str, str, Field]] = []
        used: set[str] = set()
        for name, ros2_type in ros2_fields.items():
            if name in renames:
                f = by_name.get(renames[name])
                if f is None:
                    raise TranslationError(
                        f"rule for {ros1_type}: ROS 1 field {renames[name]!r} does not exist"
                    )
            else:
                f = by_name.get(name) or by_lower.get(name.lower())
            if f is None:
                self._note(f"{where}{name} (ROS 2 only)")
                continue
            used.add(f.name)
            pairs.append((name, ros2_type, f))
        for f in spec.fields:
            if f.name not in used:
                self._note(f"{where}{f.name} (ROS 1 only)")
        return pairs

    def _note(self, text: str) -> None:
        if text not in self.unmatched:
            self.unmatched.append(text)

    # --- ROS 1 -> ROS 2 ----------------------------------------------------------------

    def _plan_to_ros2(self, ros1_type: str, ros2_cls: type, where: str) -> Convert:
        steps = [
            (name, f.name, self._conv_to_ros2(ros2_type, f, f"{where}{name}."))
            for name, ros2_type, f in self._pairs(ros1_type, ros2_cls, where)
        ]

        def convert(value: dict[str, Any]) -> Any:
            msg = ros2_cls()
            for attr, key, conv in steps:
                setattr(msg, attr, conv(value[key]))
            return msg

        return convert

    def _conv_to_ros2(self, ros2_type: str, f: Field, where: str) -> Convert:
        elem, arr = split_ros2_type(ros2_type)
        elem = _base(elem)
        if (arr is None) != (f.array is None):
            raise TranslationError(
                f"{where[:-1]}: array on one side only ({ros2_type} vs {f.spec_type()})"
            )
        one = self._elem_to_ros2(elem, f, where)
        if arr is None:
            return one
        if elem in ("uint8", "octet", "char", "byte") and f.type in BYTE_TYPES:
            if elem == "octet" or elem == "byte":
                return lambda v: [bytes((b,)) for b in v]
            return lambda v: v if arr == -1 else list(v)
        code = _array_code(elem)
        if code is not None and arr == -1:
            return lambda v: array.array(code, v)
        if one is _identity:
            return _identity
        return lambda v: [one(x) for x in v]

    def _elem_to_ros2(self, elem: str, f: Field, where: str) -> Convert:
        if elem in _TIME_TYPES:
            if f.type != _TIME_TYPES[elem]:
                raise TranslationError(f"{where[:-1]}: {elem} vs ROS 1 {f.type}")
            cls = ros2_class(elem)
            label = where[:-1]

            def stamp(v: tuple[int, int]) -> Any:
                sec, nanosec = v
                if not 0 <= nanosec < 1_000_000_000:  # the same instant, normalised
                    sec, nanosec = divmod(sec * 1_000_000_000 + nanosec, 1_000_000_000)
                if not _INT32[0] <= sec <= _INT32[1]:
                    raise OutOfRangeError(f"{label}: {sec} s does not fit ROS 2's int32 seconds")
                return cls(sec=sec, nanosec=nanosec)

            return stamp
        if elem in ROS2_PRIMITIVES:
            if not f.is_primitive or f.type in ("time", "duration"):
                raise TranslationError(f"{where[:-1]}: {elem} vs ROS 1 {f.type}")
            if (elem == "string") != (f.type == "string"):
                raise TranslationError(f"{where[:-1]}: {elem} vs ROS 1 {f.type}")
            if elem == "boolean":
                return bool
            if elem in ("octet", "byte") and f.array is None:
                return lambda v: bytes((v & 0xFF,))
            theirs, mine = _int_range(f.type), _int_range(ROS2_PRIMITIVES[elem])
            if theirs and mine and (theirs[0] < mine[0] or theirs[1] > mine[1]):
                return _range_check(mine, where[:-1])  # rclpy does not check by default
            return _identity
        if f.is_primitive:
            raise TranslationError(f"{where[:-1]}: {elem} vs ROS 1 {f.type}")
        pkg, _, name = elem.partition("/")
        return self._plan_to_ros2(f.type, ros2_class(f"{pkg}/msg/{name}"), where)

    # --- ROS 2 -> ROS 1 ----------------------------------------------------------------

    def _plan_to_ros1(self, ros1_type: str, ros2_cls: type, where: str) -> Convert:
        spec = self._registry.get(ros1_type)
        pairs = {
            f.name: (name, ros2_type)
            for name, ros2_type, f in self._pairs(ros1_type, ros2_cls, where)
        }
        steps: list[tuple[str, str | None, Any]] = []
        for f in spec.fields:
            if f.name in pairs:
                name, ros2_type = pairs[f.name]
                steps.append((f.name, name, self._conv_to_ros1(ros2_type, f, f"{where}{name}.")))
            else:
                steps.append((f.name, None, self._default(f)))

        def convert(msg: Any) -> dict[str, Any]:
            out: dict[str, Any] = {}
            for key, attr, conv in steps:
                out[key] = conv(getattr(msg, attr)) if attr is not None else conv()
            return out

        return convert

    def _conv_to_ros1(self, ros2_type: str, f: Field, where: str) -> Convert:
        elem, arr = split_ros2_type(ros2_type)
        elem = _base(elem)
        if arr is not None and f.type in BYTE_TYPES:
            if elem in ("octet", "byte"):
                return lambda v: b"".join(v)
            return _to_bytes
        if elem in _TIME_TYPES:
            one: Convert = lambda v: (v.sec, v.nanosec)  # noqa: E731
        elif elem in ROS2_PRIMITIVES:
            if elem in ("octet", "byte"):
                # The octet crosses unchanged, as on the wire: into ROS 1's ``byte``/``int8``
                # (signed) 200 reads as -56, and -56 comes back as 200.
                one = _signed_octet if f.type in ("byte", "int8") else _octet
            else:
                one = _identity
        else:
            pkg, _, name = elem.partition("/")
            one = self._plan_to_ros1(f.type, ros2_class(f"{pkg}/msg/{name}"), where)
        if arr is None:
            return one
        if one is _identity:
            return _identity
        return lambda v: [one(x) for x in v]

    def _default(self, f: Field) -> Callable[[], Any]:
        if f.array is not None:
            if f.array < 0:
                return bytes if f.type in BYTE_TYPES else list
            if f.type in BYTE_TYPES:
                return lambda: bytes(f.array or 0)
            zero = self._default(Field(f.name, f.type))
            return lambda: [zero() for _ in range(f.array or 0)]
        if f.type == "string":
            return str
        if f.type in ("time", "duration"):
            return lambda: (0, 0)
        if f.type in ("float32", "float64"):
            return float
        if f.type == "bool":
            return bool
        if f.is_primitive:
            return int
        spec = self._registry.get(f.type)
        parts = [(g.name, self._default(g)) for g in spec.fields]
        return lambda: {name: make() for name, make in parts}


def _identity(v: Any) -> Any:
    return v


_INT32 = (-(1 << 31), (1 << 31) - 1)


def _int_range(ros1_type: str) -> tuple[int, int] | None:
    """Smallest and largest value of a ROS 1 integer type; None for other types."""
    code = STRUCT_CODES.get(ros1_type)
    if code is None or code in "?fd":
        return None
    bits = 8 * struct.calcsize(code)
    return (-(1 << (bits - 1)), (1 << (bits - 1)) - 1) if code.islower() else (0, (1 << bits) - 1)


def _range_check(bounds: tuple[int, int], label: str) -> Convert:
    low, high = bounds

    def check(v: int) -> int:
        if not low <= v <= high:
            raise OutOfRangeError(f"{label}: {v} is outside [{low}, {high}] of its ROS 2 type")
        return v

    return check


def _octet(v: bytes) -> int:
    return v[0]


def _signed_octet(v: bytes) -> int:
    return v[0] - 256 if v[0] > 127 else v[0]


def _to_bytes(v: Any) -> bytes:
    if isinstance(v, bytes):
        return v
    tobytes = getattr(v, "tobytes", None)
    if tobytes is not None and getattr(v, "itemsize", 1) == 1:
        data: bytes = tobytes()
        return data
    return bytes(v)

