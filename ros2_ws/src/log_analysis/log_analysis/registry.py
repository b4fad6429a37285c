"""Where event generators come from: the entry point group ``log_analysis.event_generators``
(the built-in ones, and any package's that registers there) and Python files a user gives.

An entry point names a class or function that makes a generator when called without
arguments. A file is run as a module and lists its generators in ``GENERATORS``::

    from log_analysis import Event, event_generator

    @event_generator(topics=["behaviour/state"])
    def kicks(m):
        if m.message.data == "kick":
            return [Event("kick", m.log_time_ns, m.log_time_ns, robot=m.robot)]

    GENERATORS = [kicks]
"""

from __future__ import annotations

import importlib.util
import os
from collections.abc import Callable, Sequence
from importlib.metadata import entry_points
from pathlib import Path

from .errors import GeneratorError
from .events import EventGenerator, generator_name

__all__ = ["ENTRY_POINT_GROUP", "available_generators", "generators_from_file",
           "load_generators"]

ENTRY_POINT_GROUP = "log_analysis.event_generators"


def available_generators() -> dict[str, Callable[[], EventGenerator]]:
    """The registered generators' factories by entry-point name."""
    found: dict[str, Callable[[], EventGenerator]] = {}
    for ep in entry_points(group=ENTRY_POINT_GROUP):
        try:
            found[ep.name] = ep.load()
        except Exception as exc:  # another package's broken entry point
            raise GeneratorError(f"event generator {ep.name!r} ({ep.value}) does not load: "
                                 f"{type(exc).__name__}: {exc}") from exc
    return found


def _checked(generator: object, where: str) -> EventGenerator:
    if not isinstance(generator, EventGenerator):
        missing = [a for a in ("topics", "__call__", "finish") if not hasattr(generator, a)]
        raise GeneratorError(f"{where}: {generator!r} is not an event generator (it lacks "
                             f"{', '.join(missing)}; see log_analysis.event_generator)")
    if isinstance(generator.topics, str) or not generator.topics:
        raise GeneratorError(f"{where}: {generator_name(generator)}'s topics must be a "
                             f"non-empty list of names, not {generator.topics!r}")
    return generator


def generators_from_file(path: str | os.PathLike[str]) -> list[EventGenerator]:
    """The ``GENERATORS`` of a Python file; :class:`GeneratorError` saying why not."""
    file = Path(path)
    if not file.is_file():
        raise GeneratorError(f"no generator file at {file}")
    spec = importlib.util.spec_from_file_location(f"log_analysis_user_{file.stem}", file)
    if spec is None or spec.loader is None:
        raise GeneratorError(f"{file} is not a Python file")
    module = importlib.util.module_from_spec(spec)
    try:
        spec.loader.exec_module(module)
    except Exception as exc:
        raise GeneratorError(f"{file} does not run: {type(exc).__name__}: {exc}") from exc
    listed = getattr(module, "GENERATORS", None)
    if not isinstance(listed, (list, tuple)) or not listed:
        raise GeneratorError(f"{file} must list its generators in GENERATORS = [...]")
    return [_checked(g, str(file)) for g in listed]


def load_generators(*, names: Sequence[str] | None = None,
                    files: Sequence[str | os.PathLike[str]] = ()) -> list[EventGenerator]:
    """The registered generators and those of ``files`` (``names`` of them; all when
    ``None``). A file's generator named like a registered one replaces it (the user's
    wins); a file given twice is read once; two files' generators of one name, or an
    unknown name, raise :class:`GeneratorError` naming them."""
    registered = available_generators()
    mine: dict[str, tuple[EventGenerator, Path]] = {}
    for file in dict.fromkeys(Path(f).resolve() for f in files):
        for generator in generators_from_file(file):
            name = generator_name(generator)
            if name in mine:
                raise GeneratorError(f"two generators are named {name!r}: in {mine[name][1]} "
                                     f"and in {file}; rename one")
            mine[name] = (generator, file)
    chosen = ([n for n in registered if n not in mine] + list(mine) if names is None
              else list(dict.fromkeys(names)))
    if unknown := [n for n in chosen if n not in registered and n not in mine]:
        raise GeneratorError(f"unknown event generator(s) {', '.join(unknown)}; known: "
                             f"{', '.join(sorted({*registered, *mine}))}")
    return [mine[n][0] if n in mine else _checked(registered[n](), f"entry point {n}")
            for n in chosen]
