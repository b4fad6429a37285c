"""Keeping in-process delivery and DDS apart, so no message arrives twice.

Composed components hand messages to each other by reference; DDS carries them only to and
from other processes. For that, the process's DDS participant must not match its own
endpoints, or a composed subscriber would get every in-process message a second time
through DDS. Fast DDS (the Jazzy default) offers exactly this as the participant property
``fastdds.ignore_local_endpoints``; :func:`prepare_process` turns it on through the
default XML profile, keeping any profile the user already points
``FASTRTPS_DEFAULT_PROFILES_FILE`` to.

Fast DDS reads that profile once, when the process creates its first participant. So call
:func:`prepare_process` before anything in the process calls ``rclpy.init`` (the container
entry point and the test fixtures do). The container checks the result with a probe and
raises :class:`~efficient_comm.errors.DdsSetupError` rather than deliver duplicates.

A process prepared this way should host its ROS nodes as components: two plain rclpy nodes
sharing one context (one participant) no longer hear each other over DDS. Nodes in other
contexts or other processes are unaffected.

``prompt_acks=True`` (what lockstep processes ask for: the step coordinator and containers
with simulated time) tunes the two Fast DDS timings a lockstep step waits on: each step
waits until its messages are acknowledged (:mod:`efficient_comm.simtime`).

- The process's readers acknowledge a writer's heartbeat at once instead of after Fast
  DDS's default 5 ms ``heartbeatResponseDelay``, which doubled a step (14.0 ms against
  6.9 ms for one participant, bench/lockstep_bench.py). The price is an acknowledgement per
  heartbeat instead of one per batch.
- The process's writers send a heartbeat every :data:`LOCKSTEP_HEARTBEAT_NS` instead of
  every 3 s while a sample is unacknowledged. A reader acknowledges only when a heartbeat
  comes, and Fast DDS piggybacks one on data only once a writer has sent a send buffer's
  worth, so a small message waited for the periodic one: a plain ``ros2 topic hz`` or a
  GUI subscribed to a lockstep robot's odometry held every step of the game for 3 s. A
  writer whose samples are all acknowledged sends no periodic heartbeat: the short period
  costs only while a step waits.

Default data-reader and data-writer profiles of the user's own are kept as they are. Like
the property, they apply to participants created after the first call: create a lockstep
process's coordinator or container first.
"""

from __future__ import annotations

import hashlib
import os
import sys
import tempfile
import time
import uuid
import xml.etree.ElementTree as ET
from pathlib import Path

from rclpy.context import Context
from std_msgs.msg import Empty

PROFILES_ENV = "FASTRTPS_DEFAULT_PROFILES_FILE"
#: A lockstep process's writers' heartbeat period while a sample is unacknowledged (ns).
LOCKSTEP_HEARTBEAT_NS = 1_000_000
IGNORE_LOCAL = "fastdds.ignore_local_endpoints"
_NS = "http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles"
_MARK = "efficient_comm-profile"


def _child(parent: ET.Element, tag: str) -> ET.Element:
    found = parent.find(tag)
    if found is None:
        found = parent.find(f"{{{_NS}}}{tag}")
    return found if found is not None else ET.SubElement(parent, tag)


def _with_ignore_local(source: Path | None, *, prompt_acks: bool = False) -> str:
    """The XML of ``source`` (or an empty profile set) with the property set to true
    (and, with ``prompt_acks``, a default reader profile that acknowledges at once)."""
    ET.register_namespace("", _NS)
    root = ET.parse(source).getroot() if source else ET.Element(f"{{{_NS}}}profiles")
    profiles = root if root.tag.endswith("profiles") else _child(root, "profiles")
    participant = next(
        (
            p
            for p in profiles
            if p.tag.endswith("participant") and p.get("is_default_profile") == "true"
        ),
        None,
    )
    if participant is None:
        participant = ET.SubElement(
            profiles, "participant", profile_name=_MARK, is_default_profile="true"
        )
    properties = _child(_child(_child(participant, "rtps"), "propertiesPolicy"), "properties")
    for prop in properties:
        name = prop.find("name") if prop.find("name") is not None else prop.find(f"{{{_NS}}}name")
        if name is not None and name.text == IGNORE_LOCAL:
            properties.remove(prop)
    prop = ET.SubElement(properties, "property")
    ET.SubElement(prop, "name").text = IGNORE_LOCAL
    ET.SubElement(prop, "value").text = "true"
    if prompt_acks:
        _default_times(profiles, "data_reader", "heartbeatResponseDelay", 0)
        _default_times(profiles, "data_writer", "heartbeatPeriod", LOCKSTEP_HEARTBEAT_NS)
    return ET.tostring(root, encoding="unicode")


def _default_times(profiles: ET.Element, kind: str, timing: str, nanoseconds: int) -> None:
    """A default ``kind`` profile setting ``<times><timing>``, unless the user has one."""
    if any(p.tag.endswith(kind) and p.get("is_default_profile") == "true" for p in profiles):
        return
    profile = ET.SubElement(profiles, kind, profile_name=f"{_MARK}-{kind.split('_')[1]}",
                            is_default_profile="true")
    value = _child(_child(profile, "times"), timing)
    ET.SubElement(value, "sec").text = str(nanoseconds // 1_000_000_000)
    ET.SubElement(value, "nanosec").text = str(nanoseconds % 1_000_000_000)


def prepare_process(*, prompt_acks: bool = False) -> None:
    """Make DDS participants created from now on ignore their own endpoints (idempotent:
    the first call decides, ``prompt_acks`` included; see the module docstring)."""
    current = os.environ.get(PROFILES_ENV)
    if current and _MARK in Path(current).name:
        return
    xml = _with_ignore_local(Path(current) if current else None, prompt_acks=prompt_acks)
    # One file per distinct content, shared by every process that needs it (no leak).
    digest = hashlib.sha256(xml.encode()).hexdigest()[:16]
    path = Path(tempfile.gettempdir()) / f"{_MARK}-{os.getuid()}-{digest}.xml"
    if not path.exists():
        fd, tmp = tempfile.mkstemp(prefix=f"{_MARK}-", suffix=".tmp", dir=path.parent)
        with os.fdopen(fd, "w") as out:
            out.write(xml)
        os.replace(tmp, path)  # atomic: a concurrent process never reads half a file
    os.environ[PROFILES_ENV] = str(path)


def local_endpoints_ignored(context: Context) -> bool:
    """Probe: does a publisher in ``context`` match a subscription in the same context?"""
    import rclpy

    node = rclpy.create_node(
        f"_efficient_comm_probe_{uuid.uuid4().hex[:8]}",
        context=context,
        enable_rosout=False,
        start_parameter_services=False,
        use_global_arguments=False,
    )
    try:
        topic = f"/_efficient_comm_probe_{uuid.uuid4().hex}"
        pub = node.create_publisher(Empty, topic, 1)
        node.create_subscription(Empty, topic, lambda _msg: None, 1)
        # Same-participant matching is synchronous in DDS: no wait is needed.
        return pub.get_subscription_count() == 0
    finally:
        node.destroy_node()


#: Where Fast DDS keeps its shared-memory transport's segments (Linux).
SHM_FOLDER = Path("/dev/shm")
#: A domain's ports (RTPS's defaults, which rmw_fastrtps keeps): 7400 + 250 x domain and the
#: 249 after it; each port that a participant listens on has a segment ``fastrtps_port<N>``.
#: The shared-memory transport's discovery ports lie below 7400 (fastrtps_port7000 and up),
#: shared by the participants of every domain.
_PORT_BASE, _DOMAIN_GAIN = 7400, 250
#: boost.interprocess's first word of a managed segment: 0 uninitialized, 1 initializing,
#: 2 initialized (3 corrupted).
_UNFINISHED_STATES = (0, 1)


def remove_stale_shm_ports(
    domain_id: int, *, folder: Path = SHM_FOLDER, min_age_s: float = 10.0
) -> list[Path]:
    """Delete the shared-memory port segments of ``domain_id`` (and the discovery ports all
    domains share) that a killed process left half made, so that the next participant does
    not hang; returns them.

    Fast DDS makes a port's segment in /dev/shm when a participant first opens the port,
    and boost.interprocess, opening an existing segment, waits without a timeout until it is
    sized and initialized. A process SIGKILLed between making the file and initializing it
    (a test ending its peers, a crash at start-up) leaves one that never will be: every later
    participant that gets that port (the same domain and participant index) spins in its
    creation for ever, inside rclpy's ``Node(...)``. Only a segment still empty or not marked
    initialized after ``min_age_s`` goes: one younger may be in the making.
    """
    first = _PORT_BASE + _DOMAIN_GAIN * domain_id
    now = time.time()
    removed: list[Path] = []
    try:
        entries = list(os.scandir(folder))
    except OSError:
        return removed
    for entry in entries:
        number = entry.name.removeprefix("fastrtps_port")
        if number == entry.name or not number.isdigit():
            continue  # not a port's segment (``_el`` locks, ``_mutex``es, data segments)
        port = int(number)
        if not (first <= port < first + _DOMAIN_GAIN or port < _PORT_BASE):
            continue
        try:
            stat = entry.stat()
            if now - stat.st_mtime < min_age_s:
                continue
            if stat.st_size >= 4:
                with open(entry.path, "rb") as segment:
                    state = int.from_bytes(segment.read(4), sys.byteorder)
                if state not in _UNFINISHED_STATES:
                    continue
            os.unlink(entry.path)
        except OSError:  # gone meanwhile, or another user's
            continue
        removed.append(Path(entry.path))
    return removed
