"""ROS 2 parameters of any node, through its standard ``rcl_interfaces`` services and the Hub.

The one place debug_gui talks to parameter services: the Parameters view's model and the
Foxglove endpoint both go through here. Any node has these services (ours, being rclpy
nodes, and plain rclpy or rclcpp ones alike): ``<node>/list_parameters``,
``describe_parameters``, ``get_parameters``, ``set_parameters``; every node of a domain
reports its changes on ``/parameter_events``.

Values: :func:`python_value` turns a ``ParameterValue`` into the Python value it holds,
:func:`to_ros` a Python value into a ``ParameterValue`` of the parameter's type (refusing
one that would change the type behind the user's back), :func:`parse` what a person typed
into one; :func:`check` validates a value against the parameter's descriptor (read-only,
integer and floating point ranges) before it is sent, so the user reads why at once
instead of a bare refusal.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Iterable, Mapping
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import Any

import yaml
from rcl_interfaces.msg import Parameter as RosParameter
from rcl_interfaces.msg import ParameterDescriptor, ParameterEvent, ParameterValue
from rcl_interfaces.msg import ParameterType as RosType
from rcl_interfaces.srv import (
    DescribeParameters,
    GetParameters,
    ListParameters,
    SetParameters,
)

from .errors import CallFailed, InvalidInput, RobotUnavailable
from .robots import RobotId
from .source import Source, Stream

#: Per node when every node's parameters are asked for: a node that hangs must not stall it.
LIST_TIMEOUT_S = 3.0
#: For one node's parameters (and sets): a loaded robot answers late, not never.
CALL_TIMEOUT_S = 5.0
#: Nodes asked at once by :func:`get_many`: one after the other, each new service client's
#: discovery adds up to seconds.
PARALLEL_GETS = 16
#: Where every node of a domain reports its parameter changes.
PARAMETER_EVENTS = "/parameter_events"
_LIST_SERVICE_TYPE = "rcl_interfaces/srv/ListParameters"
_FLOAT_TOLERANCE = 1e-9

#: Type names as ``ros2 param describe`` prints them.
TYPE_NAMES: dict[int, str] = {
    RosType.PARAMETER_NOT_SET: "not set",
    RosType.PARAMETER_BOOL: "boolean",
    RosType.PARAMETER_INTEGER: "integer",
    RosType.PARAMETER_DOUBLE: "double",
    RosType.PARAMETER_STRING: "string",
    RosType.PARAMETER_BYTE_ARRAY: "byte array",
    RosType.PARAMETER_BOOL_ARRAY: "boolean array",
    RosType.PARAMETER_INTEGER_ARRAY: "integer array",
    RosType.PARAMETER_DOUBLE_ARRAY: "double array",
    RosType.PARAMETER_STRING_ARRAY: "string array",
}
ARRAY_TYPES = frozenset({
    RosType.PARAMETER_BYTE_ARRAY, RosType.PARAMETER_BOOL_ARRAY,
    RosType.PARAMETER_INTEGER_ARRAY, RosType.PARAMETER_DOUBLE_ARRAY,
    RosType.PARAMETER_STRING_ARRAY,
})


# -- values ----------------------------------------------------------------------------------


def python_value(value: ParameterValue) -> Any:
    """The Python value a ``ParameterValue`` holds (bytes for a byte array, None if unset)."""
    kind = value.type
    if kind == RosType.PARAMETER_BOOL:
        return bool(value.bool_value)
    if kind == RosType.PARAMETER_INTEGER:
        return int(value.integer_value)
    if kind == RosType.PARAMETER_DOUBLE:
        return float(value.double_value)
    if kind == RosType.PARAMETER_STRING:
        return str(value.string_value)
    if kind == RosType.PARAMETER_BYTE_ARRAY:
        return bytes(b[0] if isinstance(b, bytes) else b for b in value.byte_array_value)
    if kind == RosType.PARAMETER_BOOL_ARRAY:
        return [bool(v) for v in value.bool_array_value]
    if kind == RosType.PARAMETER_INTEGER_ARRAY:
        return [int(v) for v in value.integer_array_value]
    if kind == RosType.PARAMETER_DOUBLE_ARRAY:
        return [float(v) for v in value.double_array_value]
    if kind == RosType.PARAMETER_STRING_ARRAY:
        return [str(v) for v in value.string_array_value]
    return None


def to_ros(value: object, *, current: int = RosType.PARAMETER_NOT_SET,
           doubles: bool = False) -> ParameterValue:
    """``value`` as a ``ParameterValue`` of the parameter's ``current`` type.

    JSON and number fields cannot tell 2 from 2.0, so a whole number given for a double
    parameter (or with ``doubles``, a hint the caller has) becomes a double; anything else
    that does not fit the current type is refused rather than changing the parameter's type
    behind the user's back. ``current=PARAMETER_NOT_SET`` takes the value's own type.
    """
    out = ParameterValue()
    wants_double = doubles or current == RosType.PARAMETER_DOUBLE
    wants_doubles = doubles or current == RosType.PARAMETER_DOUBLE_ARRAY
    if isinstance(value, bool):
        out.type, out.bool_value = RosType.PARAMETER_BOOL, value
    elif isinstance(value, int) and wants_double:
        out.type, out.double_value = RosType.PARAMETER_DOUBLE, float(value)
    elif isinstance(value, int):
        out.type, out.integer_value = RosType.PARAMETER_INTEGER, value
    elif isinstance(value, float):
        out.type, out.double_value = RosType.PARAMETER_DOUBLE, value
    elif isinstance(value, str):
        out.type, out.string_value = RosType.PARAMETER_STRING, value
    elif isinstance(value, bytes | bytearray):
        out.type = RosType.PARAMETER_BYTE_ARRAY
        out.byte_array_value = [bytes([b]) for b in value]
    elif isinstance(value, list) and not value:
        # [] has no element type: the parameter's own array type, else a boolean array.
        out.type = current if current in ARRAY_TYPES - {RosType.PARAMETER_BYTE_ARRAY} \
            else RosType.PARAMETER_BOOL_ARRAY
    elif isinstance(value, list) and all(isinstance(v, bool) for v in value):
        out.type, out.bool_array_value = RosType.PARAMETER_BOOL_ARRAY, value
    elif isinstance(value, list) and all(
        isinstance(v, int | float) and not isinstance(v, bool) for v in value
    ):
        if wants_doubles or any(isinstance(v, float) for v in value):
            out.type = RosType.PARAMETER_DOUBLE_ARRAY
            out.double_array_value = [float(v) for v in value]
        else:
            out.type, out.integer_array_value = RosType.PARAMETER_INTEGER_ARRAY, value
    elif isinstance(value, list) and all(isinstance(v, str) for v in value):
        out.type, out.string_array_value = RosType.PARAMETER_STRING_ARRAY, value
    else:
        raise InvalidInput(f"unsupported parameter value {value!r}")
    if current not in (RosType.PARAMETER_NOT_SET, out.type):
        raise InvalidInput(
            f"{_short(value)} is not a{_n(TYPE_NAMES[current])} {TYPE_NAMES[current]}"
        )
    return out


def _n(word: str) -> str:
    return "n" if word[:1] in "aeiou" else ""


def _short(value: object) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def format_value(value: Any) -> str:
    """A value as the view's text fields show it and :func:`parse` reads it back."""
    if isinstance(value, bytes):
        return json.dumps(list(value))
    if isinstance(value, list):
        return json.dumps(value)
    if isinstance(value, bool):
        return "true" if value else "false"
    return "" if value is None else str(value)


def parse(raw: object, kind: int) -> ParameterValue:
    """What a person entered (a widget's value or text) as a value of type ``kind``.

    Strings are taken verbatim; numbers and booleans from their widgets or as text; arrays
    as a YAML/JSON list (``[1, 2, 3]``, ``[a, "b c"]``), as ``ros2 param set`` reads them.
    InvalidInput, with a message saying what was expected, for anything else.
    """
    what = TYPE_NAMES.get(kind, str(kind))
    if raw is None:
        raise InvalidInput(f"expected a{_n(what)} {what}, got nothing")
    if kind == RosType.PARAMETER_STRING:
        if not isinstance(raw, str):
            raise InvalidInput(f"expected a string, got {_short(raw)}")
        return to_ros(raw, current=kind)
    if kind == RosType.PARAMETER_NOT_SET:
        raise InvalidInput("this parameter has no type yet: set it with ros2 param set")
    value = raw
    if isinstance(raw, str):
        text = raw.strip()
        if not text:
            raise InvalidInput(f"expected a{_n(what)} {what}, got nothing")
        try:
            value = yaml.safe_load(text)
        except yaml.YAMLError:
            raise InvalidInput(f"expected a{_n(what)} {what}, got {_short(raw)}") from None
    if kind == RosType.PARAMETER_INTEGER and isinstance(value, float) and value.is_integer():
        value = int(value)  # a number field's 140.0
    if kind == RosType.PARAMETER_DOUBLE and isinstance(value, float) and not math.isfinite(
        value
    ):
        raise InvalidInput(f"{value} is not a finite number")
    if kind == RosType.PARAMETER_BYTE_ARRAY:
        if not (isinstance(value, list) and all(
            isinstance(v, int) and not isinstance(v, bool) and 0 <= v <= 255 for v in value
        )):
            raise InvalidInput(f"expected a list of bytes 0..255, got {_short(raw)}")
        value = bytes(value)
    if kind in ARRAY_TYPES and not isinstance(value, list | bytes):
        raise InvalidInput(f"expected a{_n(what)} {what} such as [1, 2], got {_short(raw)}")
    try:
        return to_ros(value, current=kind)
    except InvalidInput:
        raise InvalidInput(f"expected a{_n(what)} {what}, got {_short(raw)}") from None


@dataclass(frozen=True, slots=True)
class Described:
    """One parameter: its value and what its descriptor says about it."""

    name: str
    type: int
    value: Any
    description: str = ""
    additional_constraints: str = ""
    read_only: bool = False
    dynamic_typing: bool = False
    #: (from, to, step) when the descriptor gives an integer range (step 0: any).
    integer_range: tuple[int, int, int] | None = None
    #: (from, to, step) when the descriptor gives a floating point range (step 0: any).
    floating_point_range: tuple[float, float, float] | None = None

    @property
    def type_name(self) -> str:
        return TYPE_NAMES.get(self.type, str(self.type))

    @property
    def text(self) -> str:
        return format_value(self.value)

    def constraints(self) -> str:
        """The descriptor's limits in words (empty when there are none)."""
        parts = []
        rng = self.integer_range or self.floating_point_range
        if rng is not None:
            low, high, step = rng
            parts.append(f"{low:g}..{high:g}" + (f" step {step:g}" if step else ""))
        if self.additional_constraints:
            parts.append(self.additional_constraints)
        if self.read_only:
            parts.append("read-only")
        return "; ".join(parts)

    def with_value(self, value: ParameterValue) -> Described:
        return Described(
            self.name, value.type, python_value(value), self.description,
            self.additional_constraints, self.read_only, self.dynamic_typing,
            self.integer_range, self.floating_point_range,
        )


def described(name: str, value: ParameterValue, descriptor: ParameterDescriptor) -> Described:
    ints = list(descriptor.integer_range)
    floats = list(descriptor.floating_point_range)
    return Described(
        name=name, type=value.type, value=python_value(value),
        description=str(descriptor.description),
        additional_constraints=str(descriptor.additional_constraints),
        read_only=bool(descriptor.read_only), dynamic_typing=bool(descriptor.dynamic_typing),
        integer_range=(int(ints[0].from_value), int(ints[0].to_value), int(ints[0].step))
        if ints else None,
        floating_point_range=(float(floats[0].from_value), float(floats[0].to_value),
                              float(floats[0].step)) if floats else None,
    )


def check(param: Described, value: ParameterValue) -> None:
    """InvalidInput unless ``value`` may be set on ``param`` by its descriptor (as rclpy
    judges it: read-only, type unless dynamically typed, ranges and their steps)."""
    if param.read_only:
        raise InvalidInput(f"{param.name} is read-only")
    if value.type != param.type and not param.dynamic_typing:
        raise InvalidInput(
            f"{param.name} is a{_n(param.type_name)} {param.type_name}, not a"
            f"{_n(TYPE_NAMES.get(value.type, ''))} {TYPE_NAMES.get(value.type, value.type)}"
        )
    if param.integer_range is not None and value.type == RosType.PARAMETER_INTEGER:
        _in_range(param.name, int(value.integer_value), param.integer_range, 0)
    if param.floating_point_range is not None and value.type == RosType.PARAMETER_DOUBLE:
        _in_range(param.name, float(value.double_value), param.floating_point_range,
                  _FLOAT_TOLERANCE)


def _in_range(name: str, value: float, rng: tuple[float, float, float], tol: float) -> None:
    low, high = min(rng[0], rng[1]), max(rng[0], rng[1])
    step = rng[2]
    if value < low - tol or value > high + tol:
        raise InvalidInput(f"{name} must be within {low:g}..{high:g}, not {value:g}")
    if step and abs(value - high) > tol:
        steps = (value - low) / step
        if abs(steps - round(steps)) * step > max(tol, 0.0):
            raise InvalidInput(f"{name} must be {low:g} plus a multiple of {step:g}, "
                               f"not {value:g}")


# -- the services, through the Hub -----------------------------------------------------------


@dataclass(frozen=True, slots=True)
class SetOutcome:
    """What a node answered to one set: ``reason`` is the node's own words on a veto."""

    name: str
    successful: bool
    reason: str


def parameter_nodes(hub: Source, robot: RobotId) -> list[str]:
    """The robot's nodes that offer parameter services (fully qualified, sorted; the GUI's
    own node left out)."""
    services = hub.services(robot)
    return [node for node in hub.nodes(robot)
            if _LIST_SERVICE_TYPE in services.get(f"{node}/list_parameters", [])]


def list_names(hub: Source, robot: RobotId, node: str, *,
               timeout_s: float = CALL_TIMEOUT_S) -> list[str]:
    listed = hub.call(robot, f"{node}/list_parameters", ListParameters,
                      ListParameters.Request(), timeout_s=timeout_s)
    return sorted(str(n) for n in listed.result.names)


def get_values(hub: Source, robot: RobotId, node: str, names: list[str], *,
               timeout_s: float = CALL_TIMEOUT_S) -> dict[str, ParameterValue]:
    """The named parameters' values (ones the node does not have are left out)."""
    if not names:
        return {}
    got = hub.call(robot, f"{node}/get_parameters", GetParameters,
                   GetParameters.Request(names=names), timeout_s=timeout_s)
    return {name: value for name, value in zip(names, got.values, strict=False)
            if value.type != RosType.PARAMETER_NOT_SET}


def get(hub: Source, robot: RobotId, node: str, *, names: list[str] | None = None,
        timeout_s: float | None = None) -> dict[str, ParameterValue]:
    """Named parameters of ``node``, or all of them (``names=None``, sooner given up)."""
    wait = timeout_s if timeout_s is not None else (
        CALL_TIMEOUT_S if names is not None else LIST_TIMEOUT_S)
    if names is None:
        names = list_names(hub, robot, node, timeout_s=wait)
    return get_values(hub, robot, node, names, timeout_s=wait)


def get_many(hub: Source, targets: Iterable[tuple[RobotId, str]]
             ) -> list[tuple[RobotId, str, dict[str, ParameterValue]]]:
    """Every parameter of each (robot, node), the nodes asked in parallel (as
    foxglove_bridge does); a node without parameter services, or one that hangs, is
    left out."""
    nodes = list(targets)

    def one(target: tuple[RobotId, str]) -> tuple[RobotId, str, dict[str, ParameterValue]]:
        try:
            return (*target, get(hub, *target))
        except (RobotUnavailable, CallFailed):
            return (*target, {})

    if not nodes:
        return []
    with ThreadPoolExecutor(max_workers=min(len(nodes), PARALLEL_GETS),
                            thread_name_prefix="debug_gui-params") as pool:
        return list(pool.map(one, nodes))


def describe(hub: Source, robot: RobotId, node: str, *, names: list[str] | None = None,
             timeout_s: float = CALL_TIMEOUT_S) -> list[Described]:
    """The node's parameters (all, or the named ones) with values and descriptors, by name."""
    if names is None:
        names = list_names(hub, robot, node, timeout_s=timeout_s)
    if not names:
        return []
    descriptors = hub.call(robot, f"{node}/describe_parameters", DescribeParameters,
                           DescribeParameters.Request(names=names),
                           timeout_s=timeout_s).descriptors
    values = get_values(hub, robot, node, names, timeout_s=timeout_s)
    return sorted(
        (described(name, values[name], descriptor)
         for name, descriptor in zip(names, descriptors, strict=False) if name in values),
        key=lambda d: d.name,
    )


def set_values(hub: Source, robot: RobotId, node: str, values: Mapping[str, ParameterValue], *,
               timeout_s: float = CALL_TIMEOUT_S) -> list[SetOutcome]:
    """Set each parameter (one at a time, as ``ros2 param set``: one veto stops only its
    own); the node's answer for each, its veto's reason verbatim."""
    if not values:
        return []
    request = SetParameters.Request(
        parameters=[RosParameter(name=name, value=value) for name, value in values.items()])
    result = hub.call(robot, f"{node}/set_parameters", SetParameters, request,
                      timeout_s=timeout_s)
    return [SetOutcome(sent.name, bool(outcome.successful), str(outcome.reason))
            for sent, outcome in zip(request.parameters, result.results, strict=False)]


def watch(hub: Source, robot: RobotId, callback: Callable[[ParameterEvent], None]) -> Stream:
    """Every parameter change in the robot's domain (new, changed, deleted), as the nodes
    report it on ``/parameter_events``; ``callback`` runs on the Hub's thread (no
    :meth:`Hub.call` there). Close the feed to stop."""
    return hub.subscribe(robot, PARAMETER_EVENTS, ParameterEvent, callback,
                         qos=_events_qos())


def _events_qos() -> Any:
    from rclpy.qos import qos_profile_parameter_events

    return qos_profile_parameter_events


__all__ = [
    "ARRAY_TYPES", "CALL_TIMEOUT_S", "LIST_TIMEOUT_S", "PARALLEL_GETS", "PARAMETER_EVENTS",
    "TYPE_NAMES", "Described", "SetOutcome", "check", "describe", "described",
    "format_value", "get", "get_many", "get_values", "list_names", "parameter_nodes",
    "parse", "python_value", "set_values", "to_ros", "watch",
]
