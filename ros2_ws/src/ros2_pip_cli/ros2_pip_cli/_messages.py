"""Messages as YAML, and from YAML: what ``topic echo`` prints and ``topic pub`` reads.

The wheels have no rosidl_runtime_py, so this follows its ``message_to_yaml`` and
``set_message_fields`` (the formats people script against): fields in definition order,
strings and arrays longer than ``truncate_length`` cut with ``'...'``, block style by
default, and YAML values converted to the field's type (an int given for a float field).
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from typing import Any

import yaml

from efficient_comm import EfficientCommError, import_type, to_plain

from .errors import CliError

_INT_RE = re.compile(r"^(u?int\d+|byte|char|octet)$")
_FLOAT_RE = re.compile(r"^(float\d+|double)$")


def import_interface(name: str, kind: str = "msg") -> Any:
    """``pkg/msg/Name`` (or ``pkg/Name``) to its Python class; CliError if there is none.
    efficient_comm's :func:`~efficient_comm.import_type` owns the spelling; this keeps
    ros2cli's wording."""
    try:
        return import_type(name, kind=kind)
    except EfficientCommError as exc:
        raise CliError(f"The passed {_KIND[kind]} type is invalid: {name} ({exc})") from exc


_KIND = {"msg": "message", "srv": "service", "action": "action"}


def message_to_yaml(msg: Any, *, truncate_length: int | None = 128, no_arr: bool = False,
                    no_str: bool = False, flow_style: bool = False) -> str:
    """The YAML text ``ros2 topic echo`` prints for one message (without the ``---``)."""
    plain = to_plain(msg, truncate_length=truncate_length, no_arr=no_arr, no_str=no_str)
    return yaml.dump(plain, Dumper=_DUMPER, allow_unicode=True, width=_WIDTH,
                     default_flow_style=flow_style, sort_keys=False)


# libyaml's emitter, when PyYAML has it, is five times faster than the pure-Python one and
# writes the same text: what lets `topic echo` keep up with a 1 kHz topic. Its width is a C int.
_DUMPER: Any = getattr(yaml, "CSafeDumper", yaml.SafeDumper)
_WIDTH = 2**31 - 1


def parse_values(text: str | None) -> dict[str, Any]:
    """The YAML dictionary of ``topic pub`` and ``service call``; ``{}`` when none."""
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


def set_message_fields(msg: Any, values: Mapping[str, Any]) -> None:
    """Fill ``msg`` from a dictionary; CliError naming the field when a value does not fit."""
    fields = msg.get_fields_and_field_types()
    for key, value in values.items():
        if key not in fields:
            raise CliError(f"Failed to populate field: {type(msg).__name__!r} has no field "
                           f"{key!r} (fields: {', '.join(fields) or 'none'})")
        try:
            _set_field(msg, key, fields[key], value)
        except CliError:
            raise
        except (AssertionError, TypeError, ValueError, AttributeError) as exc:
            raise CliError(f"Failed to populate field {key!r} ({fields[key]}) with {value!r}: "
                           f"{exc or 'wrong type'}") from exc


def _set_field(msg: Any, key: str, field_type: str, value: Any) -> None:
    element, is_sequence = _element_type(field_type)
    if "/" in element:  # nested message(s)
        cls = import_interface(element)
        if is_sequence:
            if not isinstance(value, list):
                raise CliError(f"Failed to populate field {key!r}: expected a list")
            items = []
            for item in value:
                sub = cls()
                set_message_fields(sub, item or {})
                items.append(sub)
            setattr(msg, key, items)
        else:
            if not isinstance(value, Mapping):
                raise CliError(f"Failed to populate field {key!r}: expected a dictionary "
                               f"of {element}")
            set_message_fields(getattr(msg, key), value)
        return
    if is_sequence:
        if not isinstance(value, list):
            raise CliError(f"Failed to populate field {key!r}: expected a list")
        value = [_scalar(element, v) for v in value]
    else:
        value = _scalar(element, value)
    setattr(msg, key, value)


def _scalar(element: str, value: Any) -> Any:
    if _FLOAT_RE.match(element) and isinstance(value, int) and not isinstance(value, bool):
        return float(value)
    if element in ("string", "wstring") or element.startswith(("string<", "wstring<")):
        return value if isinstance(value, str) else str(value)
    if element == "byte" and isinstance(value, int):
        return bytes([value])
    if element == "char" and isinstance(value, str) and len(value) == 1:
        return ord(value)
    return value


def _element_type(field_type: str) -> tuple[str, bool]:
    """``sequence<geometry_msgs/Point, 3>`` -> (``geometry_msgs/msg/Point``, True)."""
    seq = False
    t = field_type
    if t.startswith("sequence<"):
        t, seq = t[len("sequence<"):-1].split(",")[0].strip(), True
    elif t.endswith("]"):
        t, seq = t[: t.index("[")], True
    if "/" in t and t.count("/") == 1:
        pkg, name = t.split("/")
        t = f"{pkg}/msg/{name}"
    return t, seq
