"""Message types by name, and their complete ``ros2msg`` definitions for MCAP schemas.

ROS tools that read a bag without the message packages installed (rosbags, Foxglove,
``mcap`` with mcap-ros2-support) decode it from the schema stored in the file, so each schema
must hold the type's own .msg text followed by every type it uses, recursively, each after a
two-line delimiter (80 ``=`` and ``MSG: pkg/msg/Type``), as rosbag2 writes them. The .msg
files come from ``share/<pkg>/msg/`` of every prefix on the ament index
(``AMENT_PREFIX_PATH``), where rosidl installs them.
"""

from __future__ import annotations

import functools
import json
import os
import re
from pathlib import Path

import efficient_comm
from efficient_comm import EfficientCommError

from .errors import UnknownTypeError

__all__ = ["full_definition", "import_service", "import_type", "service_definitions",
           "type_hash", "type_name"]

DELIMITER = "=" * 80
_PRIMITIVES = frozenset({
    "bool", "byte", "char", "float32", "float64", "int8", "uint8", "int16", "uint16",
    "int32", "uint32", "int64", "uint64", "string", "wstring",
})
_NAME = re.compile(r"^[A-Za-z][A-Za-z0-9_]*/(msg/)?[A-Za-z][A-Za-z0-9_]*$")
_SRV_NAME = re.compile(r"^[A-Za-z][A-Za-z0-9_]*/srv/[A-Za-z][A-Za-z0-9_]*$")


def type_name(msg_type: type) -> str:
    """``pkg/msg/Type`` of a generated message class (what rosbag2 stores as the type);
    efficient_comm owns the spelling, this keeps the error rosbag2_layout's own."""
    try:
        name = efficient_comm.type_name(msg_type)
    except EfficientCommError as exc:
        raise UnknownTypeError(str(exc)) from exc
    if name.split("/")[1] != "msg":
        raise UnknownTypeError(f"{msg_type!r} is not a generated ROS message class")
    return name


def _split(name: str) -> tuple[str, str]:
    if not _NAME.match(name):
        raise UnknownTypeError(f"message type must be pkg/msg/Type, not {name!r}")
    parts = name.split("/")
    return parts[0], parts[-1]


def import_type(name: str) -> type:
    """The message class for ``pkg/msg/Type`` (or ``pkg/Type``), through efficient_comm's
    :func:`~efficient_comm.import_type` with rosbag2_layout's error."""
    try:
        return efficient_comm.import_type(name, kind="msg")
    except EfficientCommError as exc:
        raise UnknownTypeError(str(exc)) from exc


def _prefixes() -> list[Path]:
    return [Path(p) for p in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if p]


@functools.cache
def _msg_text(package: str, short: str) -> str:
    for prefix in _prefixes():
        path = prefix / "share" / package / "msg" / f"{short}.msg"
        if path.is_file():
            return path.read_text(encoding="utf-8")
    raise UnknownTypeError(
        f"no {package}/msg/{short}.msg under share/ of any AMENT_PREFIX_PATH entry "
        f"({os.environ.get('AMENT_PREFIX_PATH', '')!r}); is the package installed and sourced?"
    )


@functools.cache
def type_hash(name: str) -> str:
    """The type description hash of ``pkg/msg/Type`` (``RIHS01_...``), or "" if unknown.

    rosbag2 (Jazzy) stores it per topic as ``type_description_hash``. rosidl computes it at
    build time and installs it beside the .msg file (``share/<pkg>/msg/<Type>.json``, the
    type description and its ``type_hashes``), which is where rclpy's type support has it
    from too; a type built without it (before Iron) has none, and "" is what rosbag2 writes.
    """
    try:
        package, short = _split(name)
    except UnknownTypeError:
        return ""
    full = f"{package}/msg/{short}"
    for prefix in _prefixes():
        path = prefix / "share" / package / "msg" / f"{short}.json"
        if path.is_file():
            try:
                hashes = json.loads(path.read_text(encoding="utf-8")).get("type_hashes", [])
            except (OSError, ValueError, AttributeError):
                return ""
            for entry in hashes:
                if isinstance(entry, dict) and entry.get("type_name") == full:
                    return str(entry.get("hash_string", ""))
            return ""
    return ""


def _dependencies(package: str, text: str) -> list[tuple[str, str]]:
    """Types a .msg text uses, in order of first use: ``(package, Type)``."""
    deps: list[tuple[str, str]] = []
    for raw in text.splitlines():
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        field_type = line.split()[0]
        base = re.split(r"[\[<]", field_type, maxsplit=1)[0]
        if base in _PRIMITIVES:
            continue
        if "/" in base:
            parts = base.split("/")
            dep = (parts[0], parts[-1])
        elif base == "Header":  # the one short name ROS resolves outside the own package
            dep = ("std_msgs", "Header")
        else:
            dep = (package, base)
        if dep not in deps:
            deps.append(dep)
    return deps


@functools.cache
def full_definition(name: str) -> str:
    """The complete ``ros2msg`` definition of ``pkg/msg/Type``: its text, then its deps."""
    package, short = _split(name)
    return _with_dependencies(package, short, _msg_text(package, short))


def _with_dependencies(package: str, short: str, text: str) -> str:
    seen: list[tuple[str, str]] = []
    todo = _dependencies(package, text)
    while todo:
        dep = todo.pop(0)
        if dep in seen or dep == (package, short):
            continue
        seen.append(dep)
        todo.extend(_dependencies(dep[0], _msg_text(*dep)))
    parts = [text.rstrip("\n")]
    for dep_package, dep_short in seen:
        parts.append(f"{DELIMITER}\nMSG: {dep_package}/msg/{dep_short}\n"
                     + _msg_text(dep_package, dep_short).rstrip("\n"))
    return "\n".join(parts) + "\n"


def _split_service(name: str) -> tuple[str, str]:
    if not _SRV_NAME.match(name):
        raise UnknownTypeError(f"service type must be pkg/srv/Type, not {name!r}")
    package, _, short = name.split("/")
    return package, short


def import_service(name: str) -> type:
    """The service class for ``pkg/srv/Type`` (with ``.Request`` and ``.Response``)."""
    _split_service(name)
    try:
        return efficient_comm.import_type(name, kind="srv")
    except EfficientCommError as exc:
        raise UnknownTypeError(str(exc)) from exc


@functools.cache
def service_definitions(name: str) -> tuple[str, str]:
    """The complete ``ros2msg`` definitions of ``pkg/srv/Type``'s request and response.

    Viewers that call a service without its package installed (Foxglove through a
    WebSocket endpoint) encode the request and decode the response from these, exactly as
    they decode topics: each half of the .srv text, then every type it uses.
    """
    package, short = _split_service(name)
    text = ""
    for prefix in _prefixes():
        path = prefix / "share" / package / "srv" / f"{short}.srv"
        if path.is_file():
            text = path.read_text(encoding="utf-8")
            break
    else:
        raise UnknownTypeError(f"no {package}/srv/{short}.srv under share/ of any "
                               "AMENT_PREFIX_PATH entry; is the package installed and sourced?")
    lines = text.splitlines()
    cut = next((i for i, line in enumerate(lines) if line.strip() == "---"), None)
    if cut is None:
        raise UnknownTypeError(f"{package}/srv/{short}.srv has no '---' between request "
                               "and response")
    request = "\n".join(lines[:cut]) + "\n"
    response = "\n".join(lines[cut + 1:]) + "\n"
    return (_with_dependencies(package, f"{short}_Request", request),
            _with_dependencies(package, f"{short}_Response", response))
