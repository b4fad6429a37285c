"""Container files: which components run together, decided at deployment.

A container file is YAML::

    parameter_files: [common.yaml]      # optional, ROS 2 params-file layout, for all nodes
    parameters:                         # optional, the same layout inline
      /**:
        ros__parameters: {use_filter: true}
    components:
      - class: my_pkg.camera:Camera     # "module:Class", or an entry point name of the
        name: camera                    #   group "efficient_comm.components"
        namespace: /robot               # optional
        remappings: {image: /robot/camera/image}   # or ["image:=/robot/camera/image"]
        parameters:                     # optional, params-file layout; keys are full
          /robot/camera:                #   node names (or wildcards: /**, /robot/*)
            ros__parameters: {rate_hz: 30.0}
        parameter_files: [camera.yaml]  # optional, relative to this file

Parameters apply in the order: file-wide files, file-wide inline, entry files, entry inline
(later wins). Every problem is reported as a :class:`~efficient_comm.errors.ConfigError`
naming the file and the entry (``demo.yaml: components[2] (detector)``); one bad entry
does not stop the others from loading.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from importlib.metadata import entry_points
from pathlib import Path
from typing import Any

import yaml

from ._names import check_node_name, parse_remaps
from ._params import overrides_for
from .errors import ConfigError, EfficientCommError

ENTRY_POINT_GROUP = "efficient_comm.components"
_ENTRY_KEYS = {"class", "name", "namespace", "remappings", "parameters", "parameter_files"}


@dataclass(frozen=True)
class ComponentSpec:
    """Everything needed to create one component; ``source`` is quoted in errors."""

    class_path: str
    name: str
    namespace: str = "/"
    remappings: Mapping[str, str] = field(default_factory=dict)
    parameters: Mapping[str, Any] = field(default_factory=dict)
    source: str = "<spec>"


def resolve_factory(spec: ComponentSpec) -> Callable[[Any], Any]:
    """Import the class of ``spec``: ``module:Class`` or an entry point name (which may
    hold ``::``, as ``humanoid_sim::BallDetector`` does, like a ROS plugin name)."""
    path = spec.class_path
    try:
        if ":" in path.replace("::", ""):
            module_name, _, attr = path.partition(":")
            target: Any = importlib.import_module(module_name)
            for part in attr.split("."):
                target = getattr(target, part)
        else:
            matches = entry_points(group=ENTRY_POINT_GROUP, name=path)
            if not matches:
                raise LookupError(f"no entry point {path!r} in group {ENTRY_POINT_GROUP}")
            target = next(iter(matches)).load()
    except Exception as exc:
        raise ConfigError(f"{spec.source}: cannot import component class {path!r}: {exc}") from exc
    if not callable(target):
        raise ConfigError(f"{spec.source}: {path!r} is not a class or callable")
    return target  # type: ignore[no-any-return]


def _read_yaml(path: Path, source: str) -> Any:
    try:
        return yaml.safe_load(path.read_text())
    except OSError as exc:
        raise ConfigError(f"{source}: cannot read {path}: {exc.strerror}") from exc
    except yaml.YAMLError as exc:
        raise ConfigError(f"{source}: invalid YAML in {path}: {exc}") from exc


def _param_layers(
    section: Mapping[str, Any], base: Path, source: str
) -> list[tuple[Any, str]]:
    """The params-file documents of a section (file-wide or one entry), in order."""
    layers: list[tuple[Any, str]] = []
    files = section.get("parameter_files") or []
    if not isinstance(files, list):
        raise ConfigError(f"{source}: parameter_files must be a list of paths")
    for name in files:
        path = base / str(name)
        layers.append((_read_yaml(path, source), f"{source}: {path}"))
    if section.get("parameters") is not None:
        layers.append((section["parameters"], f"{source}: parameters"))
    return layers


def parse_document(
    document: Any, *, base: Path, source: str
) -> list[ComponentSpec | ConfigError]:
    """Specs (or the error of each bad entry) of a parsed container document."""
    if not isinstance(document, Mapping) or not isinstance(document.get("components"), list):
        raise ConfigError(f"{source}: expected a mapping with a 'components' list")
    common = _param_layers(document, base, source)
    out: list[ComponentSpec | ConfigError] = []
    for index, entry in enumerate(document["components"]):
        where = f"{source}: components[{index}]"
        try:
            if not isinstance(entry, Mapping):
                raise ConfigError(f"{where}: each component must be a mapping")
            if isinstance(entry.get("name"), str):
                where += f" ({entry['name']})"
            unknown = set(entry) - _ENTRY_KEYS
            if unknown:
                raise ConfigError(f"{where}: unknown keys {sorted(unknown)}")
            for key in ("class", "name"):
                if not isinstance(entry.get(key), str) or not entry[key]:
                    raise ConfigError(f"{where}: '{key}' is required and must be a string")
            name, namespace = check_node_name(entry["name"], str(entry.get("namespace", "/")))
            fqn = namespace.rstrip("/") + "/" + name
            parameters: dict[str, Any] = {}
            for layer, layer_source in [*common, *_param_layers(entry, base, where)]:
                parameters.update(overrides_for(layer, fqn, source=layer_source))
            remaps = entry.get("remappings") or {}
            if not isinstance(remaps, Mapping | list):
                raise ConfigError(f"{where}: remappings must be a mapping or a list")
            out.append(
                ComponentSpec(
                    class_path=entry["class"],
                    name=name,
                    namespace=namespace,
                    remappings=parse_remaps(remaps),
                    parameters=parameters,
                    source=where,
                )
            )
        except ConfigError as exc:
            out.append(exc)
        except EfficientCommError as exc:
            out.append(ConfigError(f"{where}: {exc}"))
    return out


def parse_file(path: Path) -> list[ComponentSpec | ConfigError]:
    """Parse a container file; raises ConfigError only if the file as a whole is unusable."""
    source = str(path)
    return parse_document(_read_yaml(path, source), base=path.parent, source=source)
