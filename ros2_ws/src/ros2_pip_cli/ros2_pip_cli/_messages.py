"""Messages as YAML, and from YAML: what ``topic echo`` prints and ``topic pub`` reads.

The wheels have no rosidl_runtime_py, so this follows its ``message_to_yaml`` and
``set_message_fields`` (the formats people script against): fields in definition order,
strings and arrays longer than ``truncate_length`` cut with ``'...'``, block style by
default, and YAML values converted to the field's type (an int given for a float field).
"""

from __future__ import annotations

import array
import importlib
import re
from collections.abc import Mapping
from typing import Any

import yaml

from .errors import CliError

_INT_RE = re.compile(r"^(u?int\d+|byte|char|octet)$")
_FLOAT_RE = re.compile(r"^(float\d+|double)$")


def import_interface(name: str, kind: str = "msg") -> Any:
    """``pkg/msg/Name`` (or ``pkg/Name``) to its Python class; CliError if there is none."""
    parts = name.split("/")
    if len(parts) == 2:
        parts = [parts[0], kind, parts[1]]
    if len(parts) != 3 or not all(parts):
        raise CliError(f"The passed {_KIND[kind]} type is invalid: {name!r} "
                       f"(expected pkg/{kind}/Name)")
    try:
        module = importlib.import_module(f"{parts[0]}.{parts[1]}")
        cls = getattr(module, parts[2])
    except (ImportError, AttributeError, ValueError) as exc:
        raise CliError(f"The passed {_KIND[kind]} type is invalid: {name} ({exc})") from exc
    if kind == "srv" and not hasattr(cls, "Request"):
        raise CliError(f"The passed type is not a service: {name}")
    return cls


_KIND = {"msg": "message", "srv": "service", "action": "action"}


def type_name(cls: type) -> str:
    """The ``pkg/msg/Name`` of a message class, as the graph spells it."""
    module = cls.__module__.split(".")
    return f"{module[0]}/{module[1]}/{cls.__name__}"


def is_message(value: Any) -> bool:
    return hasattr(value, "get_fields_and_field_types")


def to_plain(value: Any, *, truncate_length: int | None = None, no_arr: bool = False,
             no_str: bool = False, field_type: str = "") -> Any:
    """A message (or field value) as dicts, lists and scalars, ready for YAML.

    ``field_type`` is the field's type as the message class spells it
    (``sequence<uint8>``), for ``--no-arr``'s summary."""
    if is_message(value):
        return {
            field: to_plain(getattr(value, field), truncate_length=truncate_length,
                            no_arr=no_arr, no_str=no_str, field_type=field_type)
            for field, field_type in value.get_fields_and_field_types().items()
        }
    if isinstance(value, bytes):
        text = "".join(chr(c) for c in value)
        return _cut_str(text, truncate_length)
    if isinstance(value, str):
        if no_str:
            return f"<string length: <{len(value)}>>"
        return _cut_str(value, truncate_length)
    if isinstance(value, (list, tuple, array.array)) or type(value).__name__ == "ndarray":
        if no_arr:
            return f"<sequence type: {element_type(field_type)}, length: {len(value)}>"
        cut = truncate_length is not None and len(value) > truncate_length
        items = value[:truncate_length] if cut else value
        out = [to_plain(v, truncate_length=truncate_length, no_arr=no_arr, no_str=no_str)
               for v in (items.tolist() if hasattr(items, "tolist") else items)]
        if cut:
            out.append("...")
        return out
    if hasattr(value, "item"):  # numpy scalars
        return value.item()
    return value


def element_type(field_type: str) -> str:
    """The element type of an array or sequence field as ros2cli names it:
    ``sequence<uint8, 5>`` and ``uint8[3]`` -> ``uint8``; ``sequence<geometry_msgs/Point>``
    -> ``geometry_msgs/msg/Point``; ``string<=10`` -> ``string``."""
    inner = field_type
    if inner.startswith("sequence<"):
        inner = inner[len("sequence<"):].rsplit(">", 1)[0].split(",")[0].strip()
    inner = inner.split("[", 1)[0].split("<=", 1)[0]
    if "/" in inner:
        package, name = inner.split("/", 1)
        return f"{package}/msg/{name}"
    return inner or "unknown"


def _cut_str(text: str, truncate_length: int | None) -> str:
    if truncate_length is not None and len(text) > truncate_length:
        return text[:truncate_length] + "..."
    return text


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
