"""Message translators: ROS 1 types learned at run time, their wire format, and the field
mapping between them and ROS 2 classes (automatic by name, YAML rules otherwise)."""

from __future__ import annotations

import threading
from collections.abc import Iterable

from .ros1_serde import Ros1Codec
from .ros1_types import TypeRegistry, derive_from_ros2, ros2_class, ros2_type_name
from .translator import Translator, TypeRule

__all__ = [
    "Ros1Codec",
    "Translator",
    "TranslatorSet",
    "TypeRegistry",
    "TypeRule",
    "derive_from_ros2",
    "ros2_class",
    "ros2_type_name",
]


class TranslatorSet:
    """The bridge's ROS 1 types, codec and translators, shared by every connection.

    Rules are registered up front; translators are compiled on first use and cached, so a
    type first seen in a connection header costs one compilation.
    """

    def __init__(self, rules: Iterable[TypeRule] = ()) -> None:
        self.registry = TypeRegistry()
        self.codec = Ros1Codec(self.registry)
        self.rules = {(r.ros1, r.ros2): r for r in rules}
        self._by_ros1 = {r.ros1: r for r in self.rules.values()}
        self._cache: dict[tuple[str, type], Translator] = {}
        self._lock = threading.Lock()
        for rule in self.rules.values():
            if rule.ros1_definition is not None:
                self.registry.add_full_definition(rule.ros1, rule.ros1_definition)

    def ros1_type_for(self, ros2_cls: type, ros1_type: str | None = None) -> str:
        """The ROS 1 type a ROS 2 class is published as: the one a topic names (its
        ``peer_type``, which brings the rule for that type) or the ROS 2 type's twin.

        A rule never applies to topics that do not name its ROS 1 type: other topics of
        the same ROS 2 type keep the twin, which is what ROS 1 peers of those topics expect.
        """
        if ros1_type is not None and ros1_type in self.registry:
            return ros1_type
        return derive_from_ros2(self.registry, ros2_cls, ros1_name=ros1_type)

    def ros2_class_for(self, ros1_type: str) -> type:
        """The ROS 2 class a ROS 1 type arrives as: a rule's, or the same package and name."""
        rule = self._by_ros1.get(ros1_type)
        if rule is not None:
            return ros2_class(rule.ros2)
        return ros2_class(ros1_type)

    def translator(self, ros1_type: str, ros2_cls: type) -> Translator:
        key = (ros1_type, ros2_cls)
        found = self._cache.get(key)
        if found is None:
            with self._lock:
                found = Translator(self.registry, ros1_type, ros2_cls, rules=self.rules)
                self._cache[key] = found
        return found

    def forget(self, ros1_type: str) -> None:
        """Drop cached translators and codecs of a type whose definition changed."""
        with self._lock:
            self._cache.clear()  # nested types are compiled into their parents' plans
            self.codec.forget()
