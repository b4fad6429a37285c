"""The exact CDR length of a message, to cut what ``serialize_message`` adds past its end.

``rclpy.serialization.serialize_message`` returns the buffer length rmw_fastrtps *estimated*
for the message, which can exceed the bytes actually serialized (a ``JointState`` with one
position: 52 bytes, 44 on the wire), the rest being uninitialised memory. rosbag2 records
what arrives from DDS, i.e. the exact length, and strict readers (rosbags) refuse trailing
bytes. So the writer computes the length from the message object (plain CDR, XCDR1 little
endian: every primitive aligned to its size from the start of the payload) and cuts there.

Types it does not know (wstring, long double) make :func:`cdr_length` return None; the
caller then keeps the bytes as they are.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from rosidl_parser import definition as d  # type: ignore[import-untyped]

from .errors import UnsupportedFieldError

__all__ = ["cdr_length", "trim"]

_SIZES = {
    "boolean": 1, "octet": 1, "char": 1, "uint8": 1, "int8": 1,
    "int16": 2, "uint16": 2, "int32": 4, "uint32": 4, "float": 4,
    "int64": 8, "uint64": 8, "double": 8,
}
_ENCAPSULATION = 4
_PLANS: dict[type, Callable[[Any, int], int]] = {}

# A step takes (message or value, offset) and returns the offset after it.
_Step = Callable[[Any, int], int]


def _align(offset: int, size: int) -> int:
    return offset + (-offset % size)


def _value_step(slot: Any) -> _Step:
    """Size of one value of the IDL type ``slot``."""
    if isinstance(slot, d.BasicType):
        size = _SIZES.get(slot.typename)
        if size is None:
            raise UnsupportedFieldError(slot.typename)
        return lambda _v, o: _align(o, size) + size
    if isinstance(slot, d.AbstractWString):
        raise UnsupportedFieldError("wstring")
    if isinstance(slot, d.AbstractString):
        return lambda v, o: _align(o, 4) + 4 + len(v.encode("utf-8")) + 1
    if isinstance(slot, d.NamespacedType):
        return _message_step(_import(slot))
    if isinstance(slot, d.Array):
        return _elements_step(slot.value_type, prefixed=False)
    if isinstance(slot, d.AbstractSequence):
        return _elements_step(slot.value_type, prefixed=True)
    raise UnsupportedFieldError(type(slot).__name__)


def _elements_step(value_type: Any, *, prefixed: bool) -> _Step:
    basic = _SIZES.get(value_type.typename) if isinstance(value_type, d.BasicType) else None
    if isinstance(value_type, d.BasicType) and basic is None:
        raise UnsupportedFieldError(value_type.typename)
    if basic is not None:
        size = basic

        def primitives(v: Any, o: int) -> int:
            if prefixed:
                o = _align(o, 4) + 4
            n = len(v)
            return _align(o, size) + n * size if n else o

        return primitives
    each = _value_step(value_type)

    def items(v: Any, o: int) -> int:
        if prefixed:
            o = _align(o, 4) + 4
        for item in v:
            o = each(item, o)
        return o

    return items


def _import(slot: Any) -> type:
    """A nested field's class (``slot.namespaces`` is ``[pkg, "msg"]``), named as efficient_comm
    names types."""
    import efficient_comm

    return efficient_comm.import_type("/".join([*slot.namespaces, slot.name]),
                                      kind=slot.namespaces[-1])


def _plan(msg_type: type) -> _Step:
    plan = _PLANS.get(msg_type)
    if plan is None:
        plan = _PLANS[msg_type] = _make_plan(msg_type)
    return plan


def _make_plan(msg_type: type) -> _Step:
    names = list(msg_type.get_fields_and_field_types())  # type: ignore[attr-defined]
    slots = list(msg_type.SLOT_TYPES)  # type: ignore[attr-defined]
    if not names:  # an empty message carries one placeholder byte
        return lambda _m, o: o + 1
    steps = [(name, _value_step(slot)) for name, slot in zip(names, slots, strict=True)]

    def walk(msg: Any, o: int) -> int:
        for name, step in steps:
            o = step(getattr(msg, name), o)
        return o

    return walk


def _message_step(msg_type: type) -> _Step:
    def nested(v: Any, o: int) -> int:
        return _plan(type(v))(v, o)

    _plan(msg_type)  # fail early on unsupported nested types
    return nested


def cdr_length(msg: Any) -> int | None:
    """Bytes of ``msg`` serialized as CDR with its 4-byte header; None if not computable."""
    try:
        return _ENCAPSULATION + _plan(type(msg))(msg, 0)
    except UnsupportedFieldError:
        return None


def trim(msg: Any, data: bytes) -> bytes:
    """``data`` (from ``serialize_message(msg)``) cut to the message's exact CDR length."""
    length = cdr_length(msg)
    if length is None or length >= len(data):
        return data
    return data[:length]
