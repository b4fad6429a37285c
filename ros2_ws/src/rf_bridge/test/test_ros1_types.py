"""ROS 1 types at run time: md5sums and wire bytes agree with Debian's ROS 1 (genpy/rospy)."""

from __future__ import annotations

import json
import shutil
import subprocess

import pytest
from geometry_msgs.msg import PoseStamped, Twist
from sensor_msgs.msg import CameraInfo, Image, Imu, JointState, LaserScan, PointCloud2
from std_msgs.msg import Header, String

from rf_bridge.errors import ProtocolError, TranslationError
from rf_bridge.translate import Ros1Codec, TranslatorSet
from rf_bridge.translate.ros1_types import TypeRegistry, parse_msg

TYPES = [String, Header, Image, PoseStamped, CameraInfo, Imu, JointState, LaserScan,
         PointCloud2, Twist]

# Only the comparisons with rospy need Debian's ROS 1 (scripts/test.sh installs it); the
# parsing and decoding checks run everywhere.
needs_ros1 = pytest.mark.skipif(
    shutil.which("rosmaster") is None, reason="Debian's ROS 1 missing: scripts/setup_ros1.sh"
)


def ros1(script: str, *args: str) -> str:
    env = {"PATH": "/usr/bin:/bin", "LANG": "C.UTF-8"}
    out = subprocess.run(["/usr/bin/python3", "-c", script, *args], env=env, check=True,
                         capture_output=True, text=True, timeout=60)
    return out.stdout


@needs_ros1
def test_derived_twins_have_ros1_md5sums_and_definitions() -> None:
    ts = TranslatorSet()
    names = [ts.ros1_type_for(cls) for cls in TYPES]
    script = (
        "import importlib, json, sys\n"
        "out = {}\n"
        "for n in sys.argv[1:]:\n"
        "    p, m = n.split('/')\n"
        "    c = getattr(importlib.import_module(p + '.msg'), m)\n"
        "    out[n] = [c._md5sum, c._full_text]\n"
        "print(json.dumps(out))\n"
    )
    theirs = json.loads(ros1(script, *names))
    for name in names:
        assert ts.registry.md5sum(name) == theirs[name][0], name
        # their full text (with comments) parses to the same md5sum
        other = TypeRegistry()
        other.add_full_definition(name, theirs[name][1])
        assert other.md5sum(name) == theirs[name][0], name


ALL_TYPES = r"""
import importlib, json, sys
out = {}
for package in sys.argv[1:]:
    module = importlib.import_module(package + ".msg")
    for name in dir(module):
        cls = getattr(module, name)
        if isinstance(cls, type) and hasattr(cls, "_md5sum") and not name.startswith("_"):
            out[package + "/" + name] = cls._md5sum
print(json.dumps(out))
"""
#: ROS 1 types with no ROS 2 message of that name: ROS 1's built-in time types as messages
#: and nav_msgs' GetMap action (ROS 2 actions are not messages).
NO_ROS2_TWIN = {
    "std_msgs/Time", "std_msgs/Duration",
    *(f"nav_msgs/GetMap{part}" for part in (
        "Action", "ActionFeedback", "ActionGoal", "ActionResult", "Feedback", "Goal", "Result"
    )),
}


@needs_ros1
def test_every_common_type_derived_from_ros2_has_rospys_md5sum() -> None:
    """All of Debian's ROS 1 std_msgs, geometry_msgs, sensor_msgs and nav_msgs: the twin
    derived from the ROS 2 type has the md5sum rospy gives (so rospy and roscpp peers accept
    the bridge's publications without a definition learned from them first)."""
    import importlib

    theirs = json.loads(ros1(ALL_TYPES, "std_msgs", "geometry_msgs", "sensor_msgs", "nav_msgs"))
    assert len(theirs) > 90
    missing, differ = set(), {}
    for name, md5 in sorted(theirs.items()):
        package, msg = name.split("/")
        cls = getattr(importlib.import_module(f"{package}.msg"), msg, None)
        if cls is None:
            missing.add(name)
            continue
        ts = TranslatorSet()  # each on its own: nothing learned from another type
        ours = ts.registry.md5sum(ts.ros1_type_for(cls))
        if ours != md5:
            differ[name] = (ours, md5)
    assert differ == {}
    assert missing == NO_ROS2_TWIN


SERIALIZE = r"""
import io, json, sys
import genpy
from sensor_msgs.msg import Image, JointState
from geometry_msgs.msg import PoseStamped
img = Image(height=2, width=3, encoding="rgb8", step=9, data=bytes(range(18)))
img.header.seq = 0; img.header.stamp = genpy.Time(5, 6); img.header.frame_id = "cam"
js = JointState(name=["a", "b"], position=[1.5, -2.0], velocity=[], effort=[0.25, 1e9])
ps = PoseStamped(); ps.header.frame_id = "map"
ps.pose.position.x = 3.0; ps.pose.orientation.w = 1.0
out = {}
for key, m in (("image", img), ("joints", js), ("pose", ps)):
    b = io.BytesIO(); m.serialize(b); out[key] = b.getvalue().hex()
print(json.dumps(out))
"""


@needs_ros1
def test_serialisation_is_byte_identical_to_rospy() -> None:
    theirs = {k: bytes.fromhex(v) for k, v in json.loads(ros1(SERIALIZE)).items()}
    ts = TranslatorSet()
    img = Image(height=2, width=3, encoding="rgb8", step=9, data=bytes(range(18)))
    img.header.stamp.sec, img.header.stamp.nanosec, img.header.frame_id = 5, 6, "cam"
    js = JointState(name=["a", "b"], position=[1.5, -2.0], effort=[0.25, 1e9])
    ps = PoseStamped()
    ps.header.frame_id, ps.pose.position.x, ps.pose.orientation.w = "map", 3.0, 1.0
    for key, msg in (("image", img), ("joints", js), ("pose", ps)):
        name = ts.ros1_type_for(type(msg))
        tr = ts.translator(name, type(msg))
        ours = ts.codec.encode(name, tr.to_ros1(msg))
        assert ours == theirs[key], key
        assert tr.to_ros2(ts.codec.decode(name, theirs[key])) == msg


@pytest.mark.parametrize(("data", "error"), [
    (b"\x05\x00\x00\x00abc", "truncated"),
    (b"\x02\x00\x00\x00ab!", "left over"),
    (b"\x02\x00\x00\x00\xff\xfe", "not UTF-8"),
])
def test_malformed_payloads_raise_protocol_errors(data: bytes, error: str) -> None:
    ts = TranslatorSet()
    name = ts.ros1_type_for(String)
    with pytest.raises(ProtocolError, match=error):
        ts.codec.decode(name, data)


def test_huge_array_count_is_refused_before_allocating() -> None:
    ts = TranslatorSet()
    name = ts.ros1_type_for(JointState)
    bogus = bytes(4 + 8 + 4) + b"\xff\xff\xff\x7f"  # header, then 2**31 names
    with pytest.raises(ProtocolError, match="truncated"):
        ts.codec.decode(name, bogus)


def test_bad_definitions_are_named() -> None:
    with pytest.raises(TranslationError, match="bad field name"):
        parse_msg("p/T", "int32 1abc")
    with pytest.raises(TranslationError, match="package/Name"):
        parse_msg("NoPackage", "int32 a")
    reg = TypeRegistry()
    with pytest.raises(TranslationError, match="'q/Missing' has no definition"):
        reg.add_full_definition("p/T", "q/Missing inner")


SEP = "\n" + "=" * 80 + "\n"


@pytest.mark.parametrize(("definition", "error"), [
    ("int32 a\nfoo/Missing b", "has no definition"),
    ("std_msgs/Header header" + SEP + "MSG: std_msgs/Header\nstd_msgs/Header again",
     "contains itself"),
    ("p/L0 x" + "".join(f"{SEP}MSG: p/L{i}\np/L{i + 1} x" for i in range(40))
     + f"{SEP}MSG: p/L40\nint8 a", "levels deep"),
], ids=["missing", "cycle", "deep"])
def test_a_bad_peer_definition_changes_nothing(definition: str, error: str) -> None:
    """A peer's definition is taken whole or not at all: one that redefines std_msgs/Header
    badly must not break the Header every other connection uses."""
    ts = TranslatorSet()
    name = ts.ros1_type_for(String)
    header = ts.ros1_type_for(Header)
    before = {n: ts.registry.md5sum(n) for n in (name, header)}
    with pytest.raises(TranslationError, match=error):
        ts.registry.add_full_definition("p/Bad", definition)
    assert "p/Bad" not in ts.registry
    assert {n: ts.registry.md5sum(n) for n in (name, header)} == before


def test_array_of_empty_messages_cannot_claim_more_elements_than_bytes() -> None:
    """Empty elements cost no bytes, so their count is held to the bytes that follow it:
    2**32 - 1 of them would otherwise be built from a four-byte frame."""
    reg = TypeRegistry()
    reg.add_full_definition("p/Many", "p/Nothing[] items\nuint16 tail" + SEP + "MSG: p/Nothing\n")
    codec = Ros1Codec(reg)
    assert codec.decode("p/Many", b"\x02\x00\x00\x00\x07\x00") == {"items": [{}, {}], "tail": 7}
    with pytest.raises(ProtocolError, match="truncated"):
        codec.decode("p/Many", b"\xff\xff\xff\xff\x07\x00")
