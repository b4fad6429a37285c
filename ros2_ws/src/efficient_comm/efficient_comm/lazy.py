"""Public names of a package loaded on first use (PEP 562), so that a command importing the
package for one light name does not pay for every heavy module it re-exports.

A package's ``__init__`` lists its names and their modules in a table and hands it here;
type checkers read the same names from ordinary imports under ``TYPE_CHECKING``::

    _EXPORTS = {"Container": ".container", "type_name": ".typenames"}
    if not TYPE_CHECKING:
        __getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
    else:
        from .container import Container as Container
        from .typenames import type_name as type_name
"""

from __future__ import annotations

import importlib
import sys
from collections.abc import Callable, Mapping
from typing import Any


def lazy_exports(package: str, table: Mapping[str, str]
                 ) -> tuple[Callable[[str], Any], Callable[[], list[str]]]:
    """The module ``__getattr__`` and ``__dir__`` of ``package`` for ``table`` (public name
    -> module, relative to the package): a name is imported when first used, then kept in
    the package's namespace, so later uses do not come back here."""

    def getattr_(name: str) -> Any:
        module = table.get(name)
        if module is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(module, package), name)
        setattr(sys.modules[package], name, value)
        return value

    def dir_() -> list[str]:
        return sorted({*vars(sys.modules[package]), *table})

    return getattr_, dir_
