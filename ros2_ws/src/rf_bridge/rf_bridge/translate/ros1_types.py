"""ROS 1 message types at run time: parse ``.msg`` text, compute md5sums, build full definitions.

ROS 1 names a type by ``package/Name`` and checks compatibility by an md5sum of a canonical
form of its definition. The bridge needs no generated code: it learns a type from the
``message_definition`` a peer sends in its connection header, from a YAML rule, or derives
it from the matching ROS 2 type (see :func:`derive_from_ros2`).
"""

from __future__ import annotations

import hashlib
import threading
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from efficient_comm import EfficientCommError, import_type, type_name

from ..errors import TranslationError, UnknownTypeError

#: Built-in field types of ROS 1 and their wire size (0: variable length).
PRIMITIVES: dict[str, int] = {
    "bool": 1,
    "int8": 1,
    "uint8": 1,
    "byte": 1,
    "char": 1,
    "int16": 2,
    "uint16": 2,
    "int32": 4,
    "uint32": 4,
    "int64": 8,
    "uint64": 8,
    "float32": 4,
    "float64": 8,
    "string": 0,
    "time": 8,
    "duration": 8,
}
#: ROS 1 element types whose arrays travel (and are handed over) as ``bytes``.
BYTE_TYPES = frozenset({"uint8", "int8", "byte", "char"})
#: ``struct`` codes of the fixed-size ROS 1 primitives (little-endian on the wire).
STRUCT_CODES: dict[str, str] = {
    "bool": "?",
    "int8": "b",
    "uint8": "B",
    "byte": "b",
    "char": "B",
    "int16": "h",
    "uint16": "H",
    "int32": "i",
    "uint32": "I",
    "int64": "q",
    "uint64": "Q",
    "float32": "f",
    "float64": "d",
}
_SEPARATOR = "=" * 80


@dataclass(frozen=True, slots=True)
class Field:
    """One field; ``array`` is None (scalar), -1 (unbounded) or the fixed length."""

    name: str
    type: str  # primitive name or resolved "pkg/Name"
    array: int | None = None

    @property
    def is_primitive(self) -> bool:
        return self.type in PRIMITIVES

    def spec_type(self) -> str:
        suffix = "" if self.array is None else "[]" if self.array < 0 else f"[{self.array}]"
        return self.type + suffix


@dataclass(frozen=True, slots=True)
class Constant:
    type: str
    name: str
    value_text: str


@dataclass(frozen=True, slots=True)
class MsgSpec:
    name: str  # "pkg/Name"
    fields: tuple[Field, ...]
    constants: tuple[Constant, ...] = ()

    def text(self) -> str:
        """This type's own definition in ``.msg`` form (no comments)."""
        lines = [f"{c.type} {c.name}={c.value_text}" for c in self.constants]
        lines += [f"{f.spec_type()} {f.name}" for f in self.fields]
        return "\n".join(lines)


def _resolve(type_name: str, package: str) -> str:
    if type_name in PRIMITIVES:
        return type_name
    if type_name == "Header":
        return "std_msgs/Header"
    return type_name if "/" in type_name else f"{package}/{type_name}"


def parse_msg(name: str, text: str) -> MsgSpec:
    """Parse one ``.msg`` text for type ``name`` (``pkg/Name``); raises TranslationError."""
    if name.count("/") != 1:
        raise TranslationError(f"ROS 1 type name must be 'package/Name', not {name!r}")
    package = name.split("/")[0]
    fields: list[Field] = []
    constants: list[Constant] = []
    for lineno, raw in enumerate(text.splitlines(), 1):
        line = raw.strip()
        if not line or line.startswith("#"):
            continue
        parts = line.split(None, 1)
        if len(parts) != 2:
            raise TranslationError(f"{name}: line {lineno}: expected 'type name': {raw!r}")
        type_text, rest = parts
        if "=" in rest.split("#", 1)[0] or (type_text == "string" and "=" in rest):
            cname, value = rest.split("=", 1)
            value = value.strip() if type_text == "string" else value.split("#", 1)[0].strip()
            constants.append(Constant(type_text, cname.strip(), value))
            continue
        field_name = rest.split("#", 1)[0].strip()
        if not field_name.isidentifier():
            raise TranslationError(f"{name}: line {lineno}: bad field name {field_name!r}")
        array: int | None = None
        if type_text.endswith("]"):
            base, _, size = type_text[:-1].partition("[")
            try:
                array = int(size) if size else -1
            except ValueError:
                raise TranslationError(f"{name}: line {lineno}: bad array {type_text!r}") from None
            type_text = base
        fields.append(Field(field_name, _resolve(type_text, package), array))
    return MsgSpec(name, tuple(fields), tuple(constants))


class TypeRegistry:
    """ROS 1 types known to this process, with their md5sums and full definitions.

    Thread-safe: connections learn types from their own threads.
    """

    def __init__(self) -> None:
        self._specs: dict[str, MsgSpec] = {}
        self._md5: dict[str, str] = {}
        self._lock = threading.Lock()

    def __contains__(self, name: str) -> bool:
        return name in self._specs

    def add(self, spec: MsgSpec) -> None:
        with self._lock:
            old = self._specs.get(spec.name)
            if old != spec:
                self._specs[spec.name] = spec
                self._md5.clear()

    def get(self, name: str) -> MsgSpec:
        try:
            return self._specs[name]
        except KeyError:
            raise UnknownTypeError(f"unknown ROS 1 type {name!r}") from None

    def add_full_definition(self, name: str, full_text: str) -> MsgSpec:
        """Learn ``name`` and every type embedded in its full definition (as peers send it).

        All or nothing: the definition is checked as a whole (every embedded type present,
        no type containing itself, nesting at most :data:`MAX_NESTING` deep) before any of
        it replaces what the registry knows, so a peer's broken definition cannot spoil the
        types other connections use.
        """
        sections = full_text.split("\n" + _SEPARATOR + "\n")
        specs = [parse_msg(name, sections[0])]
        for section in sections[1:]:
            head, _, body = section.partition("\n")
            if not head.startswith("MSG: "):
                raise TranslationError(f"{name}: embedded definition without 'MSG:' line")
            specs.append(parse_msg(head[5:].strip(), body))
        with self._lock:
            staged = {**self._specs, **{spec.name: spec for spec in specs}}
        _check_closed(staged, name)
        for spec in specs:
            self.add(spec)
        return specs[0]

    def md5sum(self, name: str) -> str:
        """The ROS 1 md5sum of ``name`` (genmsg's canonical text: constants, then fields
        with nested types replaced by their own md5sum)."""
        cached = self._md5.get(name)
        if cached is not None:
            return cached
        spec = self.get(name)
        lines = [f"{c.type} {c.name}={c.value_text}" for c in spec.constants]
        for f in spec.fields:
            if f.is_primitive:
                lines.append(f"{f.spec_type()} {f.name}")
            else:
                lines.append(f"{self.md5sum(f.type)} {f.name}")
        digest = hashlib.md5("\n".join(lines).encode()).hexdigest()
        self._md5[name] = digest
        return digest

    def full_definition(self, name: str) -> str:
        """The definition with every nested type appended, as ``message_definition``."""
        spec = self.get(name)
        out = [spec.text()]
        for dep in self.dependencies(name):
            out.append(f"{_SEPARATOR}\nMSG: {dep}\n{self.get(dep).text()}")
        return "\n".join(out) + "\n"

    def dependencies(self, name: str) -> list[str]:
        """Every message type ``name`` embeds, depth first."""
        seen: list[str] = []

        def visit(n: str) -> None:
            for f in self.get(n).fields:
                if not f.is_primitive and f.type not in seen:
                    seen.append(f.type)
                    visit(f.type)

        visit(name)
        return seen


#: Deepest nesting of message types accepted from a peer; decoding recurses once per level.
MAX_NESTING = 32


def _check_closed(specs: dict[str, MsgSpec], name: str) -> None:
    """Every type ``name`` embeds is in ``specs``, none contains itself, nesting is bounded."""
    done: set[str] = set()

    def visit(n: str, path: tuple[str, ...]) -> None:
        if n in path:
            raise TranslationError(f"{name}: {n} contains itself ({' -> '.join((*path, n))})")
        if len(path) > MAX_NESTING:
            raise TranslationError(f"{name}: nested more than {MAX_NESTING} levels deep")
        if n in done:
            return
        spec = specs.get(n)
        if spec is None:
            raise UnknownTypeError(f"{name}: embedded type {n!r} has no definition")
        for f in spec.fields:
            if not f.is_primitive:
                visit(f.type, (*path, n))
        done.add(n)

    visit(name, ())


# --- deriving a ROS 1 definition from a ROS 2 type -------------------------------------

ROS2_PRIMITIVES = {
    "boolean": "bool",
    "octet": "byte",  # a .msg ``byte``: ROS 1's ``byte`` (an int8 on its wire)
    "char": "uint8",
    "byte": "byte",
    "int8": "int8",
    "uint8": "uint8",
    "int16": "int16",
    "uint16": "uint16",
    "int32": "int32",
    "uint32": "uint32",
    "int64": "int64",
    "uint64": "uint64",
    "float": "float32",
    "double": "float64",
    "float32": "float32",
    "float64": "float64",
    "string": "string",
    "wstring": "string",
}
_ROS2_SPECIAL = {"builtin_interfaces/Time": "time", "builtin_interfaces/Duration": "duration"}


@dataclass(frozen=True, slots=True)
class _Ros1Form:
    """How a common_interfaces type's ROS 1 definition differs from its ROS 2 one, so the
    twin derived from ROS 2 has ROS 1's md5sum: fields ROS 2 renamed (lowercased), and
    constants and fields ROS 2 added."""

    renames: Mapping[str, str] = field(default_factory=dict)  # ROS 2 name: ROS 1 name
    new_constants: frozenset[str] = frozenset()
    new_fields: frozenset[str] = frozenset()


_ROS1_FORMS = {
    "sensor_msgs/CameraInfo": _Ros1Form(renames={"d": "D", "k": "K", "r": "R", "p": "P"}),
    "sensor_msgs/NavSatStatus": _Ros1Form(
        new_constants=frozenset({"STATUS_UNKNOWN", "SERVICE_UNKNOWN"})
    ),
    "sensor_msgs/BatteryState": _Ros1Form(
        new_constants=frozenset(
            {"POWER_SUPPLY_TECHNOLOGY_TERNARY", "POWER_SUPPLY_TECHNOLOGY_VRLA"}
        )
    ),
    "sensor_msgs/Range": _Ros1Form(new_fields=frozenset({"variance"})),
}
#: ROS 1's Header has a sequence number that ROS 2 dropped.
_ROS1_HEADER = MsgSpec(
    "std_msgs/Header",
    (Field("seq", "uint32"), Field("stamp", "time"), Field("frame_id", "string")),
)


def ros2_class(name: str) -> type:
    """Import a ROS 2 message class from ``pkg/msg/Name`` or ``pkg/Name`` (efficient_comm
    owns the spelling; the error becomes the bridge's own)."""
    try:
        return import_type(name, kind="msg")
    except EfficientCommError as exc:
        raise UnknownTypeError(f"ROS 2 type: {exc}") from exc


def ros2_type_name(cls: type) -> str:
    """``pkg/msg/Name`` of a ROS 2 message class."""
    try:
        return type_name(cls)
    except EfficientCommError as exc:
        raise UnknownTypeError(str(exc)) from exc


def ros2_constants(cls: type) -> dict[str, Any]:
    meta = type(cls)
    found: dict[str, Any] = getattr(meta, f"_{meta.__name__}__constants", {})
    return found


def split_ros2_type(ros2_type: str) -> tuple[str, int | None]:
    """Element type and array kind (None scalar, -1 sequence, n fixed) of a ROS 2 field type
    (``sequence<T>``, ``sequence<T, N>`` and ``T[<=N]`` are all unbounded on ROS 1)."""
    if ros2_type.startswith("sequence<"):
        return ros2_type[len("sequence<") : -1].split(",")[0], -1
    if ros2_type.endswith("]"):
        base, _, size = ros2_type[:-1].partition("[")
        return base, int(size) if size.isdigit() else -1
    return ros2_type, None


def _ros2_field(name: str, ros2_type: str) -> tuple[Field, str | None]:
    """ROS 1 field for a ROS 2 field type string; returns the nested ROS 2 type to derive."""
    t, array = split_ros2_type(ros2_type)
    if t.startswith(("string<", "wstring<")):
        t = "string"
    if t in ROS2_PRIMITIVES:
        return Field(name, ROS2_PRIMITIVES[t], array), None
    if t in _ROS2_SPECIAL:
        return Field(name, _ROS2_SPECIAL[t], array), None
    return Field(name, t, array), t


def derive_from_ros2(registry: TypeRegistry, cls: type, *, ros1_name: str | None = None) -> str:
    """Register the ROS 1 twin of ROS 2 message class ``cls`` and return its ROS 1 name.

    The twin lists the fields and constants of the ROS 2 ``.msg`` file, with ROS 1's
    ``char``/``byte`` where the file declares them (rclpy reports both as integers) and
    the known differences of common_interfaces undone (:data:`_ROS1_FORMS`), so every
    std_msgs, geometry_msgs, sensor_msgs and nav_msgs type has ROS 1's md5sum. For other
    types whose ROS 1 form differs, a YAML rule or a peer's own definition gives it. Types
    already known are kept (a learned definition wins).
    """
    pkg, _, msg_name = ros2_type_name(cls).split("/")
    name = ros1_name or f"{pkg}/{msg_name}"
    if name in registry:
        return name
    if name == "std_msgs/Header":
        registry.add(_ROS1_HEADER)
        return name
    form = _ROS1_FORMS.get(name, _Ros1Form())
    declared, constants = _ros2_msg_file(cls, pkg, msg_name)
    fields: list[Field] = []
    for field_name, ros2_type in cls.get_fields_and_field_types().items():  # type: ignore[attr-defined]
        if field_name in form.new_fields:
            continue
        spec, nested = _ros2_field(form.renames.get(field_name, field_name), ros2_type)
        if declared.get(field_name) in ("char", "byte"):  # what ROS 1 calls them too
            spec = Field(spec.name, declared[field_name], spec.array)
        if nested is not None:
            nested_pkg, _, nested_name = nested.partition("/")
            derive_from_ros2(registry, ros2_class(f"{nested_pkg}/msg/{nested_name}"))
        fields.append(spec)
    kept = tuple(c for c in constants if c.name not in form.new_constants)
    registry.add(MsgSpec(name, tuple(fields), kept))
    return name


def _ros2_msg_file(
    cls: type, pkg: str, msg_name: str
) -> tuple[dict[str, str], tuple[Constant, ...]]:
    """Field types as the ROS 2 ``.msg`` file declares them (element type, by field name)
    and its constants (type and text matter for the md5sum); from the class's values when
    the file is not installed."""
    try:
        from ament_index_python.packages import get_package_share_directory

        path = Path(get_package_share_directory(pkg)) / "msg" / f"{msg_name}.msg"
        text = path.read_text()
    except (ImportError, LookupError, OSError):
        text = None
    if text is not None:
        found = []
        declared: dict[str, str] = {}
        for line in text.splitlines():
            parts = line.strip().split(None, 1)
            if len(parts) != 2 or parts[0].startswith("#"):
                continue
            if "=" in parts[1].split("#", 1)[0] or (parts[0] == "string" and "=" in parts[1]):
                cname, value = parts[1].split("=", 1)
                if parts[0] != "string":
                    value = value.split("#", 1)[0]
                found.append(Constant(parts[0], cname.strip(), value.strip()))
            else:
                field_name = parts[1].split("#", 1)[0].split()[0]
                declared[field_name] = parts[0].split("[", 1)[0]
        return declared, tuple(found)
    return {}, tuple(
        Constant(
            _constant_type(value), cname, str(int(value) if isinstance(value, bool) else value)
        )
        for cname, value in ros2_constants(cls).items()
    )


def _constant_type(value: object) -> str:
    if isinstance(value, bool):
        return "bool"
    if isinstance(value, int):
        return "int32"
    if isinstance(value, float):
        return "float64"
    return "string"
