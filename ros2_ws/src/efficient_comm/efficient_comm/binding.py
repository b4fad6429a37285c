"""A parameter dataclass bound to a node's parameters: declared, read back, kept current.

Components with many tunable figures keep them in one frozen dataclass (the walk's
``GaitParameters``, the kick's ``KickParameters``) whose ``check()`` knows which
combinations work. Binding that dataclass to ROS parameters is always the same code:
declare each field with its default (the type follows the default), build the instance
from the effective values, and on a change build a new instance, check it, and either
take it or veto the change. It lives here once so each component writes only its checks.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping
from typing import Generic, TypeVar

from .errors import ParameterError
from .handle import NodeHandle, ParameterRange, ParameterValue

__all__ = ["BoundParameters", "bind_parameters"]

T = TypeVar("T")


class BoundParameters(Generic[T]):
    """The current instance of a parameter dataclass (:attr:`value`), kept in step with the
    node's parameters. Made by :func:`bind_parameters`."""

    def __init__(self, node: NodeHandle, defaults: T, *,
                 check: Callable[[T], None] | None,
                 on_change: Callable[[T], None] | None,
                 ranges: Mapping[str, ParameterRange]) -> None:
        if not dataclasses.is_dataclass(defaults) or isinstance(defaults, type):
            raise TypeError(f"bind_parameters needs a dataclass instance, not {defaults!r}")
        self._fields = tuple(f.name for f in dataclasses.fields(defaults))
        unknown = set(ranges) - set(self._fields)
        if unknown:
            raise ParameterError(f"ranges for fields {type(defaults).__name__} does not have: "
                                 f"{sorted(unknown)}")
        self._check = check
        self._on_change = on_change
        values = {name: node.declare_parameter(name, getattr(defaults, name),
                                               range=ranges.get(name))
                  for name in self._fields}
        value = dataclasses.replace(defaults, **values)
        if check is not None:
            check(value)  # a bad deployment fails the component's construction
        self.value: T = value
        node.add_on_parameter_change(self._changed)

    def _changed(self, changes: Mapping[str, ParameterValue]) -> None:
        update = {name: value for name, value in changes.items() if name in self._fields}
        if not update:
            return
        value = dataclasses.replace(self.value, **update)  # type: ignore[type-var]
        if self._check is not None:
            self._check(value)  # raises: the store vetoes the change, nothing is taken
        self.value = value
        if self._on_change is not None:
            self._on_change(value)


def bind_parameters(node: NodeHandle, defaults: T, *,
                    check: Callable[[T], None] | None = None,
                    on_change: Callable[[T], None] | None = None,
                    ranges: Mapping[str, ParameterRange] | None = None,
                    ) -> BoundParameters[T]:
    """Declare every field of the dataclass instance ``defaults`` as a parameter of the same
    name, default and type (with ``ranges[name]`` where given), and keep the result current.

    ``check(instance)`` raises (a ValueError) for figures the component cannot use: at
    construction that fails the component, on a change it vetoes the change on every
    backend (``ros2 param set`` is told why). ``on_change(instance)`` is called with each
    accepted instance; :attr:`BoundParameters.value` is the current one.
    """
    return BoundParameters(node, defaults, check=check, on_change=on_change,
                           ranges=ranges or {})
