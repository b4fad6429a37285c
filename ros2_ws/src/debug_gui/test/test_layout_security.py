"""Layouts (JSON, validated) and the access policy, without a server."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from debug_gui import AccessDenied, AccessPolicy, InvalidInput, RobotId
from debug_gui.errors import LayoutConflict
from debug_gui.layout import MAX_PANELS, Layout, Panel, saved_text
from debug_gui.security import check_name, check_rate, parse_domains


def test_a_layout_round_trips_through_its_file(tmp_path: Path) -> None:
    layout = Layout((Panel("components", RobotId(5, "/robot2")), Panel("components"),
                     Panel("image", RobotId(0, "/far", via="team link"))))
    path = tmp_path / "layout.json"
    layout.save(path)
    assert Layout.load(path, known_kinds=["components", "image"]) == layout
    assert json.loads(path.read_text())["panels"][1] == {"kind": "components", "team": True}


def test_a_panel_keeps_its_views_settings_through_its_file(tmp_path: Path) -> None:
    """Issue 18, 4b: a layout keeps what each view was set to, not only kind and robot."""
    params = Panel("parameters", RobotId(5, "/robot2")).with_setting(
        "node", "ball_detector").with_setting("filter", "sat")
    image = Panel("image").with_setting("rate_hz", 5)
    layout = Layout((params, image))
    path = tmp_path / "layout.json"
    layout.save(path)
    again = Layout.load(path, known_kinds=["parameters", "image"])
    assert again == layout
    assert again.panels[0].setting("node") == "ball_detector"
    assert again.panels[1].setting("rate_hz") == 5
    assert json.loads(path.read_text())["panels"][1] == {
        "kind": "image", "team": True, "settings": {"rate_hz": 5}}
    assert params.with_setting("filter", None).settings == (("node", "ball_detector"),)
    with pytest.raises(InvalidInput, match="at most"):
        params.with_setting("node", "x" * 600)


def test_a_save_never_silently_replaces_a_layout_saved_elsewhere(tmp_path: Path) -> None:
    """Issue 18, 4b: a tab saves over the file only as it last saw it."""
    path = tmp_path / "layout.json"
    mine = Layout((Panel("components"),))
    seen = mine.save_over(path, seen=None)  # no file yet: nothing to lose
    assert saved_text(path) == seen
    theirs = Layout((Panel("image"),))
    theirs.save(path)  # another tab (or server) saved meanwhile
    changed = Layout((Panel("components"), Panel("logs")))
    with pytest.raises(LayoutConflict, match="saved elsewhere since this tab loaded it"):
        changed.save_over(path, seen=seen)
    assert Layout.load(path) == theirs  # left alone
    with pytest.raises(LayoutConflict):
        changed.save_over(tmp_path / "new.json", seen="a file that went")
    # Saving what the file holds already is no conflict; seen as it is now, it saves.
    theirs.save_over(path, seen=seen)
    seen = changed.save_over(path, seen=saved_text(path))
    assert Layout.load(path) == changed and saved_text(path) == seen


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
    ('{"version": 1, "panels": [{"kind": "components", "team": true, "settings": []}]}',
     "settings are an object"),
    ('{"version": 1, "panels": [{"kind": "components", "team": true, "settings": '
     '{"a b": 1}}]}', "identifier"),
    ('{"version": 1, "panels": [{"kind": "components", "team": true, "settings": '
     '{"x": [1]}}]}', "text, a number or true/false"),
    ('{"version": 1, "panels": [{"kind": "components", "team": true, "settings": '
     '{"x": 1e999}}]}', "finite"),
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


def test_a_panel_inserted_goes_where_asked_and_the_limit_holds() -> None:
    """A clone goes right after its original (issue 18, 4g), adding at the end."""
    a, b, c = Panel("components"), Panel("image"), Panel("logs")
    assert Layout((a, b)).inserting(1, c).panels == (a, c, b)
    assert Layout((a, b)).adding(c).panels == (a, b, c)
    with pytest.raises(InvalidInput, match="at most"):
        Layout((a,) * MAX_PANELS).inserting(0, c)
