"""Messages as plain trees (dicts, lists, scalars): what ``ros2 topic echo`` prints.

The ``ros2`` command's ``topic echo`` and debug_gui's topic view show the same tree, so the
conversion lives at the bottom layer and both read it from here (the GUI once imported the
command line tool for it). Formats follow ros2cli's ``message_to_yaml``: fields in
definition order, strings and arrays longer than ``truncate_length`` cut with ``'...'``.
"""

from __future__ import annotations

import array
from typing import Any

__all__ = ["abbreviate_array", "element_type", "is_message", "to_plain"]


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
