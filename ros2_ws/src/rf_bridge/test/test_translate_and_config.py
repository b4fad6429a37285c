"""Translators (automatic pairing, YAML rules, mismatches) and bridge files (errors named)."""

from __future__ import annotations

from pathlib import Path

import pytest
from geometry_msgs.msg import Vector3

from rf_bridge import ConfigError, load_config, parse_config
from rf_bridge.errors import TranslationError, UnknownTypeError
from rf_bridge.translate import TranslatorSet, TypeRule, ros2_class

SIGHTING = "string label\nfloat64 distance\nfloat64 bearing\n"


def test_rule_renames_fields_both_ways() -> None:
    rule = TypeRule(ros1="lab/Sighting", ros2="geometry_msgs/msg/Vector3",
                    fields={"x": "distance", "y": "bearing"}, ros1_definition=SIGHTING)
    ts = TranslatorSet([rule])
    assert ts.ros1_type_for(Vector3, "lab/Sighting") == "lab/Sighting"
    assert ts.ros1_type_for(Vector3) == "geometry_msgs/Vector3"  # a topic naming no type
    assert ts.ros2_class_for("lab/Sighting") is Vector3
    tr = ts.translator("lab/Sighting", Vector3)
    msg = tr.to_ros2({"label": "ball", "distance": 2.0, "bearing": 0.5})
    assert (msg.x, msg.y, msg.z) == (2.0, 0.5, 0.0)
    assert tr.to_ros1(msg) == {"label": "", "distance": 2.0, "bearing": 0.5}
    assert "label (ROS 1 only)" in tr.unmatched and "z (ROS 2 only)" in tr.unmatched


def test_mismatched_types_are_refused_with_the_field_named() -> None:
    ts = TranslatorSet()
    ts.registry.add_full_definition("lab/Bad", "string x\nfloat64 y\nfloat64 z\n")
    with pytest.raises(TranslationError, match="x"):
        ts.translator("lab/Bad", Vector3)
    rule = TypeRule(ros1="lab/V", ros2="geometry_msgs/msg/Vector3", fields={"x": "nope"},
                    ros1_definition="float64 a\n")
    with pytest.raises(TranslationError, match="'nope' does not exist"):
        TranslatorSet([rule]).translator("lab/V", Vector3)


def test_unknown_ros2_types() -> None:
    with pytest.raises(UnknownTypeError, match="not installed"):
        ros2_class("no_such_pkg/msg/Thing")
    with pytest.raises(UnknownTypeError, match="must be pkg/msg/Name"):
        ros2_class("a/b/c/d")


def test_config_errors_name_file_and_entry(tmp_path: Path) -> None:
    path = tmp_path / "bridge.yaml"
    path.write_text(
        "ros1: {master_uri: 'http://127.0.0.1:1/'}\n"
        "topics:\n"
        "  - {ros2: /ok, type: std_msgs/msg/String}\n"
        "  - {ros2: /bad, type: std_msgs/msg/String, direction: sideways}\n"
        "  - {ros2: /q, type: std_msgs/msg/String, qos: {depth: 0}}\n"
        "  - {ros2: /t, type: std_msgs/msg/String, throttle: {max_rate_hz: -1}}\n"
        "  - {ros2: /team, type: std_msgs/msg/String, peer: team}\n"
    )
    config = load_config(path)
    assert [t.ros2_topic for t in config.topics] == ["/ok"]
    assert len(config.errors) == 4
    assert all(str(path) in e for e in config.errors)
    assert "topics[1].direction" in config.errors[0]
    assert "topics[2].qos" in config.errors[1]
    assert "topics[3].throttle" in config.errors[2]
    assert "needs a 'team' section" in config.errors[3]


def test_config_fatal_errors(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="cannot read"):
        load_config(tmp_path / "missing.yaml")
    bad = tmp_path / "bad.yaml"
    bad.write_text("topics: [")
    with pytest.raises(ConfigError, match="invalid YAML"):
        load_config(bad)
    with pytest.raises(ConfigError, match="unknown sections"):
        parse_config({"rosl": {}})
    with pytest.raises(ConfigError, match="bind"):
        parse_config({"ros1": {"master_uri": "http://x:1/", "bind": 5}})


def test_defaults_bind_loopback() -> None:
    config = parse_config({"ros1": {"master_uri": "http://127.0.0.1:1/"}})
    assert config.ros1 is not None and config.ros1.bind == "127.0.0.1"


@pytest.mark.parametrize(
    ("section", "key", "value"),
    [
        ("ros1", "max_message_bytes", 0),
        ("ros1", "queue_size", -1),
        ("ros1", "queue_size", 0),
        ("ros1", "master_check_s", 0),
        ("ros1", "advertise_host", 5),
        ("team", "lease_s", 0),
        ("team", "max_message_bytes", -5),
    ],
)
def test_limits_and_timeouts_must_be_positive(section: str, key: str, value: object) -> None:
    base = {"ros1": {"master_uri": "http://127.0.0.1:1/"}, "team": {"robot_id": "a"}}
    with pytest.raises(ConfigError, match=f"{section}.{key}"):
        parse_config({section: {**base[section], key: value}})
