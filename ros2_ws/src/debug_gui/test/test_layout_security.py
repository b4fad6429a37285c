"""Layouts (JSON, validated) and the access policy, without a server."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from debug_gui import AccessDenied, AccessPolicy, InvalidInput, RobotId
from debug_gui.layout import MAX_PANELS, Layout, Panel
from debug_gui.security import check_name, check_rate, parse_domains


def test_a_layout_round_trips_through_its_file(tmp_path: Path) -> None:
    layout = Layout((Panel("components", RobotId(5, "/robot2")), Panel("components"),
                     Panel("image", RobotId(0, "/far", via="team link"))))
    path = tmp_path / "layout.json"
    layout.save(path)
    assert Layout.load(path, known_kinds=["components", "image"]) == layout
    assert json.loads(path.read_text())["panels"][1] == {"kind": "components", "team": True}


@pytest.mark.parametrize(("text", "error"), [
    ("not json", "not JSON"),
    ('{"version": 2, "panels": []}', "version 2"),
    ('{"version": 1, "panels": {}}', "list"),
    ('{"version": 1, "panels": [{"kind": "x y", "team": true}]}', "panel 1: kind"),
    ('{"version": 1, "panels": [{"kind": "components"}]}', "either a robot or team"),
    ('{"version": 1, "panels": [{"kind": "components", "team": true, "x": 1}]}', "unknown"),
    ('{"version": 1, "panels": [{"kind": "components", "robot": {"domain": 999, '
     '"namespace": "/r"}}]}', "domain id"),
    ('{"version": 1, "panels": [{"kind": "components", "robot": {"domain": 1, '
     '"namespace": "../etc"}}]}', "namespace"),
    ('{"version": 1, "panels": [{"kind": "nosuch", "team": true}]}', "no view kind"),
    ('{"version": 1, "panels": [' + ",".join(['{"kind": "components", "team": true}']
                                             * (MAX_PANELS + 1)) + "]}", "at most"),
])
def test_malformed_layouts_are_refused_naming_the_problem(text: str, error: str) -> None:
    with pytest.raises(InvalidInput, match=error):
        Layout.from_json(text, known_kinds=["components"])


def test_beyond_loopback_a_token_is_required() -> None:
    with pytest.raises(InvalidInput, match="--token"):
        AccessPolicy.for_server(host="0.0.0.0")
    policy = AccessPolicy.for_server(host="0.0.0.0", token="s3cret-token")
    assert not policy.loopback and policy.explicit_token
    with pytest.raises(AccessDenied):
        policy.check_read(None)
    policy.check_read("s3cret-token")


def test_writes_need_the_token_even_on_loopback() -> None:
    policy = AccessPolicy.for_server()
    assert policy.loopback and not policy.explicit_token and len(policy.token) >= 16
    policy.check_read(None)  # looking is fine on loopback
    for wrong in (None, "", policy.token + "x", "x" * len(policy.token)):
        with pytest.raises(AccessDenied, match="token"):
            policy.check_write(wrong)
    policy.check_write(policy.token)
    assert AccessPolicy.for_server().token != policy.token  # made up per server


@pytest.mark.parametrize("token", ["short", "with space inside", "x" * 200, "ä" * 10])
def test_bad_tokens_are_refused(token: str) -> None:
    with pytest.raises(InvalidInput, match="token"):
        AccessPolicy.for_server(token=token)


def test_names_rates_and_domains_are_validated() -> None:
    assert check_name("camera/image_raw") == "camera/image_raw"
    for bad in ("", "a b", "a//b", "/1abc", "~/x", 3, "a/../b"):
        with pytest.raises(InvalidInput):
            check_name(bad)
    assert check_rate(None) is None and check_rate(5) == 5.0
    for bad_rate in (0, -1, float("nan"), float("inf"), True, "5", 1e9):
        with pytest.raises(InvalidInput):
            check_rate(bad_rate)
    assert parse_domains("0, 5,5") == [0, 5]
    for bad_domains in ("", "a", "1;2", "-1", "233"):
        with pytest.raises(InvalidInput):
            parse_domains(bad_domains)
