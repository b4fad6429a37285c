"""ROS 2 name expansion, validation and remapping for backends that have no rcl node.

The rules are those of rcl (and rclpy's ``expand_topic_name``/``validate_*`` helpers are
used, which need no context): ``~`` is the node's private namespace, relative names are
joined to the namespace, and a remap rule matches the fully expanded name exactly.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping

from rclpy.exceptions import InvalidNamespaceException, InvalidNodeNameException
from rclpy.expand_topic_name import expand_topic_name
from rclpy.validate_full_topic_name import validate_full_topic_name
from rclpy.validate_namespace import validate_namespace
from rclpy.validate_node_name import validate_node_name

from .errors import NameResolutionError


def check_node_name(name: str, namespace: str) -> tuple[str, str]:
    """Validate and normalise a node name and namespace; returns ``(name, namespace)``."""
    namespace = namespace or "/"
    if not namespace.startswith("/"):
        namespace = "/" + namespace
    try:
        validate_node_name(name)
        validate_namespace(namespace)
    except (InvalidNodeNameException, InvalidNamespaceException) as exc:
        raise NameResolutionError(str(exc)) from exc
    return name, namespace


def fully_qualified(name: str, namespace: str) -> str:
    return namespace.rstrip("/") + "/" + name


def expand(topic: str, node_name: str, namespace: str) -> str:
    """Expand ``topic`` relative to the node and check the result is a valid full name."""
    try:
        full = expand_topic_name(topic, node_name, namespace)
        validate_full_topic_name(full)
    except Exception as exc:  # rclpy raises several unrelated types here
        raise NameResolutionError(f"invalid topic or service name {topic!r}: {exc}") from exc
    return full


def parse_remaps(rules: Mapping[str, str] | Iterable[str]) -> dict[str, str]:
    """Accept ``{"from": "to"}`` or ``["from:=to", ...]``; as in rcl, the first rule for a
    name wins."""
    if isinstance(rules, Mapping):
        return {str(k): str(v) for k, v in rules.items()}
    out: dict[str, str] = {}
    for rule in rules:
        src, sep, dst = str(rule).partition(":=")
        if not sep or not src or not dst:
            raise NameResolutionError(f"remap rule {rule!r} is not of the form 'from:=to'")
        out.setdefault(src, dst)
    return out


def apply_node_remaps(
    name: str, namespace: str, remaps: Mapping[str, str]
) -> tuple[str, str, dict[str, str]]:
    """Apply ``__node:=`` and ``__ns:=`` (optionally ``node:``-prefixed) like rcl does;
    returns the node name, namespace and the remaining (topic/service) rules."""
    rest: dict[str, str] = {}
    new_name, new_ns = name, namespace
    for src, dst in remaps.items():
        target, _, key = src.rpartition(":")
        if target and target != name:
            rest[src] = dst  # a rule for another node; Resolver ignores it too
        elif key == "__node":
            new_name = dst
        elif key == "__ns":
            new_ns = dst
        else:
            rest[src] = dst
    return new_name, new_ns, rest


class Resolver:
    """Resolves names for one node: expansion first, then the node's remap rules."""

    def __init__(self, node_name: str, namespace: str, remaps: Mapping[str, str]) -> None:
        self._node = node_name
        self._ns = namespace
        self._remaps: dict[str, str] = {}
        for src, dst in remaps.items():
            target, _, topic = src.rpartition(":")
            if target and target != node_name:
                continue  # "other_node:from:=to" is not for this node
            full = expand(topic, node_name, namespace)
            self._remaps.setdefault(full, expand(dst, node_name, namespace))

    def resolve(self, topic: str) -> str:
        full = expand(topic, self._node, self._ns)
        return self._remaps.get(full, full)

    def cli_args(self) -> list[str]:
        """The same rules as rcl command-line arguments, for a real node."""
        args: list[str] = []
        for src, dst in self._remaps.items():
            args += ["-r", f"{src}:={dst}"]
        return ["--ros-args", *args] if args else []
