"""Type name <-> class for ROS 2 interfaces: the one place that spells ``pkg/msg/Name``.

The graph, rosbag2 and the ``ros2`` command all name a message ``pkg/msg/Name`` and a
service ``pkg/srv/Name``; a generated class lives in module ``pkg.msg._name`` (or
``pkg.srv._name``). Everything that turns one into the other goes through here, so no
package can drift to another spelling (``bus.py`` once wrote ``pkg/Name``). The short form
``pkg/Name`` is accepted on input, with the kind the caller expects.
"""

from __future__ import annotations

import importlib
import re

from .errors import UnknownTypeError

__all__ = ["KINDS", "import_type", "type_name"]

#: The interface kinds rosidl generates Python classes for.
KINDS = ("msg", "srv", "action")
_NAME = re.compile(r"^([A-Za-z][A-Za-z0-9_]*)/(?:(msg|srv|action)/)?([A-Za-z][A-Za-z0-9_]*)$")


def type_name(cls: type) -> str:
    """``pkg/msg/Name`` (``pkg/srv/Name``, ``pkg/action/Name``) of a generated class."""
    module = getattr(cls, "__module__", "").split(".")
    if len(module) < 2 or module[1] not in KINDS:
        raise UnknownTypeError(
            f"{cls!r} is not a generated ROS interface class (module {'.'.join(module)!r})")
    return f"{module[0]}/{module[1]}/{cls.__name__}"


def import_type(name: str, *, kind: str = "msg") -> type:
    """The class of ``pkg/<kind>/Name`` (or ``pkg/Name``): a message, or a service class
    with ``Request`` and ``Response``. :class:`UnknownTypeError` names what is wrong."""
    if kind not in KINDS:
        raise ValueError(f"kind must be one of {KINDS}, not {kind!r}")
    match = _NAME.match(name) if isinstance(name, str) else None
    if match is None:
        raise UnknownTypeError(f"type name must be pkg/{kind}/Name, not {name!r}")
    package, given_kind, short = match.groups()
    if given_kind is not None and given_kind != kind:
        raise UnknownTypeError(f"{name!r} is a {given_kind} type, expected pkg/{kind}/Name")
    try:
        module = importlib.import_module(f"{package}.{kind}")
    except ImportError:
        raise UnknownTypeError(
            f"{kind} package {package!r} of {name!r} is not installed") from None
    cls = getattr(module, short, None)
    generated = (hasattr(cls, "get_fields_and_field_types") if kind == "msg"
                 else hasattr(cls, "Request") and hasattr(cls, "Response") if kind == "srv"
                 else hasattr(cls, "Goal"))
    if not isinstance(cls, type) or not generated:
        raise UnknownTypeError(f"{package}.{kind} has no {kind} type {short!r} ({name!r})")
    return cls
