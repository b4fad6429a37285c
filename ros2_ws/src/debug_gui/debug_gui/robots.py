"""Which robot: a (DDS domain, namespace) pair, and how the GUI reaches it.

A robot is whatever publishes ``<namespace>/efficient_comm/stats`` (every container and
standalone node of ours does). Robots in separate domains may share a namespace, and robots
in one domain are told apart by namespace, so both make up the identity. ``via`` says how
the domain is reached: directly over DDS, or through rf_bridge's team link (a constrained
link, whose bridge republishes the robot's topics into a local domain).
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Any, Literal

from .errors import InvalidInput

Via = Literal["dds", "team link"]
VIAS: tuple[Via, ...] = ("dds", "team link")
#: Domain ids ROS 2 accepts (Fast DDS maps 0..232 to ports).
MAX_DOMAIN_ID = 232
STATS_SUFFIX = "efficient_comm/stats"

_NAMESPACE = re.compile(r"^/([A-Za-z_][A-Za-z0-9_]*(/[A-Za-z_][A-Za-z0-9_]*)*)?$")


def check_namespace(namespace: str) -> str:
    """``namespace`` if it is an absolute ROS namespace (``/`` or ``/a/b``), else InvalidInput."""
    if not isinstance(namespace, str) or not _NAMESPACE.match(namespace):
        raise InvalidInput(f"not an absolute ROS namespace: {namespace!r}")
    return namespace


def check_domain(domain: object) -> int:
    if isinstance(domain, bool) or not isinstance(domain, int) or not (
        0 <= domain <= MAX_DOMAIN_ID
    ):
        raise InvalidInput(f"a DDS domain id is an integer 0..{MAX_DOMAIN_ID}, not {domain!r}")
    return domain


@dataclass(frozen=True, slots=True, order=True)
class RobotId:
    """One robot: its DDS domain, its namespace and how it is reached."""

    domain: int
    namespace: str
    via: Via = "dds"

    def __post_init__(self) -> None:
        check_domain(self.domain)
        check_namespace(self.namespace)
        if self.via not in VIAS:
            raise InvalidInput(f"via must be one of {VIAS}, not {self.via!r}")

    @property
    def name(self) -> str:
        """The namespace's last token ("robot2"), or "/" for a robot at the root."""
        return self.namespace.rsplit("/", 1)[-1] or "/"

    @property
    def label(self) -> str:
        """What the GUI shows: ``robot2 @ domain 5`` (``, team link`` when bridged)."""
        suffix = ", team link" if self.via == "team link" else ""
        return f"{self.name} @ domain {self.domain}{suffix}"

    @property
    def key(self) -> str:
        """A stable string key (layouts, element ids): ``5:/robot2``."""
        return f"{self.domain}:{self.namespace}"

    def resolve(self, name: str) -> str:
        """An absolute topic, service or node name: relative ones go under the namespace."""
        if not isinstance(name, str) or not name or name.startswith("~"):
            raise InvalidInput(f"not a topic or service name: {name!r}")
        if name.startswith("/"):
            return name
        return f"{self.namespace.rstrip('/')}/{name}"

    def relative(self, name: str) -> str:
        """``/robot2/recorder`` as ``recorder``: the inverse of :meth:`resolve` for names
        under the namespace (others stay absolute). Layouts keep names so, which suits every
        robot of a team panel and a clone."""
        prefix = self.namespace.rstrip("/") + "/"
        return name[len(prefix):] if self.namespace != "/" and name.startswith(prefix) else name

    @property
    def stats_topic(self) -> str:
        return self.resolve(STATS_SUFFIX)

    def contains(self, name: str) -> bool:
        """True if the absolute ``name`` lies under this robot's namespace."""
        if self.namespace == "/":
            return name.startswith("/")
        return name == self.namespace or name.startswith(self.namespace + "/")

    def to_dict(self) -> dict[str, Any]:
        return {"domain": self.domain, "namespace": self.namespace, "via": self.via}

    @classmethod
    def from_dict(cls, data: object) -> RobotId:
        """From :meth:`to_dict`'s form (a layout file): validated, InvalidInput otherwise."""
        if not isinstance(data, dict) or set(data) - {"domain", "namespace", "via"}:
            raise InvalidInput(f"a robot is {{domain, namespace, via}}, not {data!r}")
        try:
            return cls(domain=data["domain"], namespace=data["namespace"],
                       via=data.get("via", "dds"))
        except KeyError as exc:
            raise InvalidInput(f"robot {data!r} lacks {exc}") from None

    @classmethod
    def from_stats_topic(cls, domain: int, topic: str, *, via: Via = "dds") -> RobotId | None:
        """The robot whose stats topic ``topic`` is, or None for any other topic."""
        tail = "/" + STATS_SUFFIX
        if not topic.endswith(tail):
            return None
        namespace = topic[: -len(tail)] or "/"
        try:
            return cls(domain=domain, namespace=namespace, via=via)
        except InvalidInput:
            return None
