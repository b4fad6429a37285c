"""Parameters: one behaviour on two stores (an rclpy node's, or a local one with no DDS).

Both stores follow rclpy's rules, so a component cannot tell them apart: a parameter has
the type of its default, a deployment override wins over the default, setting another type
or an undeclared name fails, and on-change callbacks can veto a change by raising.
"""

from __future__ import annotations

import array
import math
import re
from collections.abc import Mapping
from typing import Any, cast

from rcl_interfaces.msg import (
    FloatingPointRange,
    IntegerRange,
    ParameterDescriptor,
    SetParametersResult,
)
from rclpy.exceptions import (
    InvalidParameterTypeException,
    InvalidParameterValueException,
    ParameterAlreadyDeclaredException,
    ParameterImmutableException,
    ParameterNotDeclaredException,
)
from rclpy.node import Node
from rclpy.parameter import Parameter

from .errors import ConfigError, ParameterError
from .handle import P, ParameterCallback, ParameterRange, ParameterValue

# -- the ROS 2 params-file layout -------------------------------------------------------


def _node_pattern(key: str) -> re.Pattern[str]:
    """rcl's node-name wildcards: ``*`` one token, ``**`` any number of tokens."""
    key = key if key.startswith("/") else "/" + key
    parts = []
    for token in key.split("/")[1:]:
        if token == "**":
            parts.append(r"(/[^/]+)*")
        else:
            parts.append("/" + re.escape(token).replace(r"\*", "[^/]+"))
    return re.compile("".join(parts) + "$")


def _flatten(prefix: str, values: Mapping[str, Any], out: dict[str, Any]) -> None:
    for key, value in values.items():
        name = f"{prefix}{key}"
        if isinstance(value, Mapping):
            _flatten(name + ".", value, out)
        else:
            out[name] = value


def overrides_for(document: Any, node_fqn: str, *, source: str) -> dict[str, Any]:
    """Parameters a params-file ``document`` gives the node ``node_fqn``.

    ``document`` is the parsed YAML of a ROS 2 params file::

        /**:                      # or a node name, /ns/name, /ns/*, ...
          ros__parameters:
            rate_hz: 20.0

    Later matching keys override earlier ones.
    """
    if document is None:
        return {}
    if not isinstance(document, Mapping):
        raise ConfigError(f"{source}: parameters must be a mapping in the params-file layout")
    out: dict[str, Any] = {}
    for key, section in document.items():
        if not isinstance(section, Mapping) or "ros__parameters" not in section:
            raise ConfigError(
                f"{source}: entry {key!r} has no 'ros__parameters' (params-file layout: "
                "'<node>: {ros__parameters: {name: value}}')"
            )
        if _node_pattern(str(key)).match(node_fqn):
            values = section["ros__parameters"] or {}
            if not isinstance(values, Mapping):
                raise ConfigError(f"{source}: {key}.ros__parameters must be a mapping")
            _flatten("", values, out)
    return out


# -- the two stores -----------------------------------------------------------------------


def parameter_type(name: str, value: Any) -> Parameter.Type:
    """rclpy's type of ``value``; ParameterError for what ROS parameters cannot hold."""
    try:
        return cast(Parameter.Type, Parameter.Type.from_parameter_value(value))
    except TypeError as exc:
        raise ParameterError(f"parameter {name!r}: {exc}") from None


def refuse_unset(name: str, value: Any) -> None:
    """An override with no value (YAML null) is refused, naming the parameter.

    It is what ``-p prefix:=#`` gives (``#`` starts a YAML comment), or ``prefix:`` with
    nothing after it in a params file. rclpy would declare the parameter with no type and
    hand the component ``None`` where it declared a string; refuse it on every backend.
    """
    if value is None:
        raise ParameterError(
            f"parameter {name!r}: the override has no value (YAML null: on a command "
            f"line, -p {name}:=# reads # as a comment; quote the value, e.g. "
            f"-p \"{name}:='#'\")"
        )


#: rclpy's tolerance for a float on a range's end or step grid (Node.PARAM_REL_TOL).
_REL_TOL = 1e-6


class Limits:
    """A numeric parameter's range, checked as rclpy checks a descriptor's range.

    Both ends are included; with a step, a value must also lie on the grid ``low + k*step``
    (or be ``high``). The local store applies it itself, so every backend refuses the same
    values, and it becomes the descriptor's ``integer_range`` or ``floating_point_range``
    where an rclpy node holds the parameter, so tools can show it.
    """

    __slots__ = ("high", "integer", "low", "step")

    def __init__(self, name: str, default: Any, limits: ParameterRange) -> None:
        integer = isinstance(default, int) and not isinstance(default, bool)
        if not integer and not isinstance(default, float):
            raise ParameterError(f"parameter {name!r}: a range needs an int or float "
                                 f"default, not {default!r}")
        if not isinstance(limits, tuple) or len(limits) not in (2, 3) or not all(
                isinstance(v, (int, float)) and not isinstance(v, bool) for v in limits):
            raise ParameterError(f"parameter {name!r}: range must be (low, high) or "
                                 f"(low, high, step), not {limits!r}")
        if integer and not all(isinstance(v, int) for v in limits):
            raise ParameterError(f"parameter {name!r} is an integer: its range must be "
                                 f"integers, not {limits!r}")
        low, high, step = (*limits, 0) if len(limits) == 2 else limits
        if not low <= high or step < 0:
            raise ParameterError(f"parameter {name!r}: range {limits!r} needs low <= high "
                                 "and a step >= 0")
        self.integer = integer
        self.low, self.high, self.step = low, high, step

    def check(self, name: str, value: Any) -> None:
        """ParameterError when ``value`` is outside the range or off its step grid."""
        on_end = (value in (self.low, self.high) if self.integer else
                  any(math.isclose(value, end, rel_tol=_REL_TOL)
                      for end in (self.low, self.high)))
        if on_end:
            return
        if not self.low < value < self.high:
            raise ParameterError(f"parameter {name!r}: {value!r} is out of range "
                                 f"[{self.low}, {self.high}]")
        if self.step:
            steps = (value - self.low) / self.step
            if (self.integer and (value - self.low) % self.step) or (
                    not self.integer and not math.isclose(steps, round(steps),
                                                          rel_tol=_REL_TOL)):
                raise ParameterError(f"parameter {name!r}: {value!r} is not on the step "
                                     f"{self.step} from {self.low}")

    def descriptor_fields(self) -> dict[str, Any]:
        """``integer_range`` or ``floating_point_range`` for a ParameterDescriptor."""
        if self.integer:
            return {"integer_range": [IntegerRange(
                from_value=int(self.low), to_value=int(self.high), step=int(self.step))]}
        return {"floating_point_range": [FloatingPointRange(
            from_value=float(self.low), to_value=float(self.high), step=float(self.step))]}


def _run_callbacks(callbacks: list[ParameterCallback], changes: Mapping[str, Any]) -> None:
    for callback in callbacks:
        try:
            callback(changes)
        except Exception as exc:  # a veto (ValueError), or a bug: either way, no change
            raise ParameterError(f"parameter change {dict(changes)} rejected: {exc!r}") from exc


class LocalParameters:
    """Parameters of a node that has no rcl node behind it (test and DDS-free backends).

    Mirrors rclpy: the type is the default's ``Parameter.Type`` (so ``[1, 2.5]`` is
    refused and ``[]`` is a byte array), declaring counts as setting (on-change callbacks
    see it and may veto it), and every failure is a ParameterError.
    """

    def __init__(self, overrides: Mapping[str, Any]) -> None:
        self._overrides = dict(overrides)
        self._values: dict[str, Any] = {}
        self._read_only: set[str] = set()
        self._limits: dict[str, Limits] = {}
        self._callbacks: list[ParameterCallback] = []

    def declare(self, name: str, default: P, *, description: str, read_only: bool,
                limits: Limits | None = None) -> P:
        del description  # kept by the rclpy store, where ros2 param describe shows it
        if name in self._values:
            raise ParameterError(f"parameter {name!r} is already declared")
        declared = parameter_type(name, default)
        value = self._overrides.get(name, default)
        refuse_unset(name, value)
        if parameter_type(name, value) != declared:
            raise ParameterError(
                f"parameter {name!r}: override {value!r} is not of the declared type "
                f"{declared.name}"
            )
        if limits is not None:
            limits.check(name, value)
            self._limits[name] = limits
        _run_callbacks(self._callbacks, {name: value})
        self._values[name] = value
        if read_only:
            self._read_only.add(name)
        return cast(P, value)

    def get(self, name: str) -> ParameterValue:
        try:
            return cast(ParameterValue, self._values[name])
        except KeyError:
            raise ParameterError(f"parameter {name!r} is not declared") from None

    def set(self, name: str, value: ParameterValue) -> None:
        current = self.get(name)
        if name in self._read_only:
            raise ParameterError(f"parameter {name!r} is read-only")
        declared = parameter_type(name, current)
        if parameter_type(name, value) != declared:
            raise ParameterError(f"parameter {name!r} is {declared.name}, cannot set {value!r}")
        if name in self._limits:
            self._limits[name].check(name, value)
        _run_callbacks(self._callbacks, {name: value})
        self._values[name] = value

    def add_callback(self, callback: ParameterCallback) -> None:
        self._callbacks.append(callback)


def _plain(value: Any) -> Any:
    """rclpy hands arrays set over the parameter services (``ros2 param set``, a GUI) out as
    ``array.array``; a component gets a list, as it declared it and as the local store
    gives it (an ``isinstance(value, list)`` check must not veto a valid change)."""
    return list(value) if isinstance(value, array.array) else value


class RclpyParameters:
    """The same behaviour on a real rclpy node, so ``ros2 param`` sees and sets them."""

    def __init__(self, node: Node) -> None:
        self._node = node
        self._callbacks: list[ParameterCallback] = []
        node.add_on_set_parameters_callback(self._on_set)

    def _on_set(self, params: list[Parameter]) -> SetParametersResult:
        try:
            _run_callbacks(self._callbacks, {p.name: _plain(p.value) for p in params})
        except ParameterError as exc:
            return SetParametersResult(successful=False, reason=str(exc))
        return SetParametersResult(successful=True)

    def declare(self, name: str, default: P, *, description: str, read_only: bool,
                limits: Limits | None = None) -> P:
        descriptor = ParameterDescriptor(description=description, read_only=read_only,
                                         **(limits.descriptor_fields() if limits else {}))
        # rclpy keeps the node's overrides (--ros-args -p, params files) in this dict only.
        override = self._node._parameter_overrides.get(name)
        if override is not None and override.type_ == Parameter.Type.NOT_SET:
            refuse_unset(name, None)
        try:
            param = self._node.declare_parameter(name, default, descriptor)
        except (
            ParameterAlreadyDeclaredException,
            InvalidParameterTypeException,
            InvalidParameterValueException,
        ) as exc:
            raise ParameterError(f"parameter {name!r}: {exc}") from exc
        return cast(P, param.value)

    def get(self, name: str) -> ParameterValue:
        try:
            return cast(ParameterValue, _plain(self._node.get_parameter(name).value))
        except ParameterNotDeclaredException:
            raise ParameterError(f"parameter {name!r} is not declared") from None

    def set(self, name: str, value: ParameterValue) -> None:
        self.get(name)
        try:
            result = self._node.set_parameters([Parameter(name, value=value)])[0]
        except (
            ParameterImmutableException,
            InvalidParameterTypeException,
            InvalidParameterValueException,
            TypeError,
        ) as exc:
            raise ParameterError(f"parameter {name!r}: {exc}") from exc
        if not result.successful:
            raise ParameterError(result.reason or f"parameter {name!r} rejected")

    def add_callback(self, callback: ParameterCallback) -> None:
        self._callbacks.append(callback)


class ParameterMethods:
    """The handle's parameter methods, for handles that keep their store in ``_params``."""

    _params: LocalParameters | RclpyParameters

    def declare_parameter(
        self,
        name: str,
        default: P,
        *,
        description: str = "",
        read_only: bool = False,
        range: ParameterRange | None = None,
    ) -> P:
        limits = None if range is None else Limits(name, default, range)
        return self._params.declare(name, default, description=description,
                                    read_only=read_only, limits=limits)

    def get_parameter(self, name: str) -> ParameterValue:
        return self._params.get(name)

    def set_parameter(self, name: str, value: ParameterValue) -> None:
        self._params.set(name, value)

    def add_on_parameter_change(self, callback: ParameterCallback) -> None:
        self._params.add_callback(callback)
