"""Messages as text: what ``topic echo`` prints (YAML, or CSV with ``--csv``).

The wheels have no rosidl_runtime_py, so this follows its ``message_to_yaml`` and
``message_to_csv`` (the formats people script against): fields in definition order,
strings and arrays longer than ``truncate_length`` cut with ``'...'``, block style by
default. The other direction (YAML values into a message) is ``_fill``.
"""

from __future__ import annotations

import array
import importlib
from typing import Any

import yaml

from .errors import CliError


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
            return abbreviate_array(value, field_type)
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


def abbreviate_array(value: Any, field_type: str) -> str:
    """What ``--no-arr`` prints instead of an array field, as rosidl_runtime_py words it."""
    element = element_type(field_type)
    if field_type.startswith("sequence<"):
        bound = field_type[len("sequence<"):].rsplit(">", 1)[0].partition(",")[2].strip()
        if bound:
            return f"<sequence type: {element}[{bound}], length: {len(value)}>"
        return f"<sequence type: {element}, length: {len(value)}>"
    size = field_type.rsplit("[", 1)[-1].rstrip("]")
    return f"<array type: {element}[{size}]>"


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


def message_to_csv(msg: Any, *, truncate_length: int | None = 128, no_arr: bool = False,
                   no_str: bool = False) -> str:
    """The line ``ros2 topic echo --csv`` prints for one message: every field, nested ones
    flattened, in definition order, separated by commas (values are not quoted)."""
    return ",".join(
        _csv_value(getattr(msg, field), field_type, truncate_length, no_arr, no_str)
        for field, field_type in msg.get_fields_and_field_types().items())


def _csv_value(value: Any, field_type: str | None, truncate_length: int | None,
               no_arr: bool, no_str: bool) -> str:
    if isinstance(value, (list, tuple, array.array)) or type(value).__name__ == "ndarray":
        if no_arr and field_type is not None:
            return abbreviate_array(value, field_type)
        parts = []
        for i, item in enumerate(value):
            if truncate_length is not None and i >= truncate_length:
                parts.append("...")
                break
            parts.append(_csv_value(item, None, truncate_length, no_arr, no_str))
        return ",".join(parts)
    if is_message(value):
        return message_to_csv(value, truncate_length=truncate_length, no_arr=no_arr,
                              no_str=no_str)
    if isinstance(value, str) and no_str:
        return f"<string length: <{len(value)}>>"
    if truncate_length is not None and isinstance(value, str) and len(value) > truncate_length:
        value = value[:truncate_length] + "..."
    if truncate_length is not None and isinstance(value, bytes) \
            and len(value) > truncate_length:
        value = value[:truncate_length] + b"..."
    return str(value)
