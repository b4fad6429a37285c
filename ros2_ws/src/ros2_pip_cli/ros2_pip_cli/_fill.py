"""YAML values into messages (``topic pub``, ``service call``), converted by the field's type.

ros2cli (rosidl_runtime_py's ``set_message_fields``) converts each value with the field's
Python type: ``'1.5'`` becomes 1.5, ``3.7`` in an integer field 3, and what does not convert
is refused. The generated setters of Jazzy check nothing unless ``ROS_PYTHON_CHECK_FIELDS``
is set, so a value of the wrong kind would otherwise reach the C conversion and go out as
garbage (a string as 1.5e-323) or fail there with a SystemError after "publishing #1". Here
every value is converted and range-checked before it is set, and a refusal names the field
by its path (``pose.position.x``).

Two deliberate differences from ros2cli, both where it would send a value nobody meant:
a string for a ``bool`` field must be a YAML truth word (``'yes'``, ``'false'``: ros2cli takes
any non-empty string, ``'false'`` too, as True), and a number for a ``byte`` field is that
byte (ros2cli's ``bytes(5)`` is five zero bytes).

``header: auto`` (a ``std_msgs/Header`` field) and ``stamp: now`` (a
``builtin_interfaces/Time`` field) are ros2cli's ``topic pub`` expansions: the returned
setters put the current time there before each publish.
"""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Callable, Mapping
from functools import partial
from typing import Any

import yaml
from rosidl_parser import definition as d  # type: ignore[import-untyped]

from ._main import offered_message
from ._messages import import_interface
from .errors import CliError, UsageError

#: Sets a stamp (``builtin_interfaces/Time``) on the message being filled.
StampSetter = Callable[[Any], None]

_INT_RANGES = {
    "int8": (-2**7, 2**7 - 1), "uint8": (0, 2**8 - 1), "char": (0, 2**8 - 1),
    "int16": (-2**15, 2**15 - 1), "uint16": (0, 2**16 - 1),
    "int32": (-2**31, 2**31 - 1), "uint32": (0, 2**32 - 1),
    "int64": (-2**63, 2**63 - 1), "uint64": (0, 2**64 - 1),
}
_FLOAT_MAX = {"float": 3.4028234663852886e38, "double": 1.7976931348623157e308,
              "long double": 1.7976931348623157e308}
_TRUE = {"true", "yes", "on"}
_FALSE = {"false", "no", "off"}


def read_values(args: argparse.Namespace) -> str | bytes | None:
    """The YAML text of ``topic pub`` and ``service call``: the argument, or with ``--stdin``
    everything on standard input (as ros2cli, the two exclude each other)."""
    if not args.stdin:
        return args.values  # type: ignore[no-any-return]
    if args.values is not None:
        raise UsageError(offered_message(args.parser,
                                         "argument --stdin: not allowed with argument values"))
    return sys.stdin.buffer.read()


def parse_values(text: str | bytes | None) -> dict[str, Any]:
    """The YAML dictionary of ``topic pub`` and ``service call``; ``{}`` when none."""
    if isinstance(text, bytes):
        text = text.decode(errors="replace")
    if text is None or not text.strip():
        return {}
    try:
        values = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise CliError(f"The passed value is not valid YAML: {exc}".splitlines()[0]) from exc
    if values is None:
        return {}
    if not isinstance(values, dict):
        raise CliError("The passed value needs to be a dictionary in YAML format")
    return values


def set_message_fields(msg: Any, values: Mapping[str, Any], *,
                       expand_stamps: bool = False) -> list[StampSetter]:
    """Fill ``msg`` from a dictionary, each value converted to its field's type.

    With ``expand_stamps``, ``header: auto`` and ``stamp: now`` are left to the returned
    setters (call each with a ``builtin_interfaces/Time`` before publishing).
    Raises CliError naming the field when a value does not convert or is out of range."""
    setters: list[StampSetter] = []
    _fill(msg, values, "", setters, expand_stamps)
    return setters


def _fill(msg: Any, values: Any, path: str, setters: list[StampSetter],
          expand: bool) -> None:
    if not isinstance(values, Mapping):
        raise CliError(f"Failed to populate field: {path or 'the message'} expects a "
                       f"dictionary of {type(msg).__name__}'s fields, got {values!r}")
    fields = list(msg.get_fields_and_field_types())
    slots = dict(zip(fields, msg.SLOT_TYPES, strict=True))
    for key, value in values.items():
        where = f"{path}.{key}" if path else str(key)
        if key not in slots:
            raise CliError(f"Failed to populate field: {type(msg).__name__} has no field "
                           f"{where!r} (fields: {', '.join(fields) or 'none'})")
        slot = slots[key]
        if isinstance(slot, d.NamespacedType):
            name = "/".join(slot.namespaced_name())
            if expand and value == "auto" and name == "std_msgs/msg/Header":
                setters.append(partial(setattr, getattr(msg, key), "stamp"))
                continue
            if expand and value == "now" and name == "builtin_interfaces/msg/Time":
                setters.append(partial(setattr, msg, key))
                continue
            _fill(getattr(msg, key), value, where, setters, expand)
            continue
        setattr(msg, key, _convert(slot, value, where, setters, expand))


def _convert(slot: Any, value: Any, where: str, setters: list[StampSetter],
             expand: bool) -> Any:
    """``value`` as the Python value of a field of type ``slot`` (not a nested message)."""
    if not isinstance(slot, d.AbstractNestedType):
        return _scalar(slot, value, where)
    if isinstance(value, (bytes, bytearray)) and _typename(slot.value_type) in (
            "octet", "uint8", "char"):
        value = list(value)  # YAML's !!binary for a byte array
    if not isinstance(value, list):
        raise CliError(f"Failed to populate field: {where} ({_describe(slot)}) expects a "
                       f"list, got {value!r}")
    if isinstance(slot, d.Array) and len(value) != slot.size:
        raise CliError(f"Failed to populate field: {where} ({_describe(slot)}) expects "
                       f"{slot.size} values, got {len(value)}")
    if isinstance(slot, d.BoundedSequence) and len(value) > slot.maximum_size:
        raise CliError(f"Failed to populate field: {where} ({_describe(slot)}) takes at most "
                       f"{slot.maximum_size} values, got {len(value)}")
    element = slot.value_type
    if isinstance(element, d.NamespacedType):
        cls = import_interface("/".join(element.namespaced_name()))
        items = []
        for i, item in enumerate(value):
            sub = cls()
            _fill(sub, item, f"{where}[{i}]", setters, expand)
            items.append(sub)
        return items
    return [_scalar(element, item, f"{where}[{i}]") for i, item in enumerate(value)]


def _scalar(slot: Any, value: Any, where: str) -> Any:
    kind = _typename(slot)
    try:
        return _SCALARS[kind](slot, value)
    except KeyError:
        raise CliError(f"Failed to populate field: {where} has a type this command cannot "
                       f"fill ({kind})") from None
    except (ValueError, TypeError, OverflowError) as exc:
        raise CliError(f"Failed to populate field: {where} ({kind}): {exc}") from None


def _typename(slot: Any) -> str:
    if isinstance(slot, d.AbstractString):
        return "string"
    if isinstance(slot, d.AbstractWString):
        return "wstring"
    return str(slot.typename)


def _describe(slot: Any) -> str:
    element = slot.value_type
    name = ("/".join(element.namespaced_name()) if isinstance(element, d.NamespacedType)
            else _typename(element))
    if isinstance(slot, d.Array):
        return f"{name}[{slot.size}]"
    if isinstance(slot, d.BoundedSequence):
        return f"sequence<{name}, {slot.maximum_size}>"
    return f"sequence<{name}>"


def _no_container(value: Any) -> None:
    if isinstance(value, (dict, list)) or value is None:
        raise TypeError(f"cannot convert {value!r}")


def _to_int(slot: Any, value: Any) -> int:
    _no_container(value)
    kind = _typename(slot)
    if kind == "char" and isinstance(value, str) and len(value) == 1:
        value = ord(value)
    try:
        number = int(value)  # 3.7 -> 3 and '12' -> 12, as ros2cli; 'abc' and '1.5' refused
    except ValueError:
        raise ValueError(f"cannot convert {value!r} to an integer") from None
    low, high = _INT_RANGES[kind]
    if not low <= number <= high:
        raise ValueError(f"{value!r} is out of range [{low}, {high}]")
    return number


def _to_float(slot: Any, value: Any) -> float:
    _no_container(value)
    try:
        number = float(value)  # '1.5' -> 1.5, as ros2cli; 'abc' refused
    except ValueError:
        raise ValueError(f"cannot convert {value!r} to a number") from None
    limit = _FLOAT_MAX[_typename(slot)]
    if math.isfinite(number) and abs(number) > limit:
        raise ValueError(f"{value!r} is out of range for {_typename(slot)}")
    return number


def _to_bool(_slot: Any, value: Any) -> bool:
    _no_container(value)
    if isinstance(value, str):
        word = value.strip().lower()
        if word in _TRUE:
            return True
        if word in _FALSE:
            return False
        raise ValueError(f"{value!r} is not a truth value (true/false, yes/no, on/off)")
    return bool(value)


def _to_byte(_slot: Any, value: Any) -> bytes:
    _no_container(value)
    if isinstance(value, (bytes, bytearray)) and len(value) == 1:
        return bytes(value)
    if isinstance(value, str) and len(value) == 1 and ord(value) < 256:
        return bytes([ord(value)])
    if isinstance(value, int) and not isinstance(value, bool) and 0 <= value <= 255:
        return bytes([value])
    raise ValueError(f"{value!r} is not one byte (0..255 or one character)")


def _to_str(slot: Any, value: Any) -> str:
    _no_container(value)
    text = value if isinstance(value, str) else str(value)  # 5 -> '5', as ros2cli
    bound = getattr(slot, "maximum_size", None)
    if bound is not None and len(text) > bound:
        raise ValueError(f"{value!r} is longer than {bound} characters")
    return text


_SCALARS: dict[str, Callable[[Any, Any], Any]] = {
    **dict.fromkeys(_INT_RANGES, _to_int),
    **dict.fromkeys(_FLOAT_MAX, _to_float),
    "boolean": _to_bool,
    "octet": _to_byte,
    "string": _to_str,
    "wstring": _to_str,
}
