"""Messages as text: what ``topic echo`` prints (YAML, or CSV with ``--csv``).

The wheels have no rosidl_runtime_py, so this follows its ``message_to_yaml`` and
``message_to_csv`` (the formats people script against): fields in definition order,
strings and arrays longer than ``truncate_length`` cut with ``'...'``, block style by
default. The other direction (YAML values into a message) is ``_fill``.
"""

from __future__ import annotations

import array
from typing import Any

import yaml

from efficient_comm import EfficientCommError, abbreviate_array, import_type, is_message, to_plain

from .errors import CliError


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
