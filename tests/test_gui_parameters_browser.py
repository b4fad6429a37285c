"""The parameters view in a real browser: edits reach the component, vetoes reach the user.

Against humanoid_sim's real ball detector (in the light robot tests/_gui_camera_robot.py,
fed by a drawn camera instead of the simulation): its ``min_saturation`` is typed into its
field and set with Enter, and the test reads the value back from the component over its
own ``get_parameters`` service (a plain rclpy client, not the GUI); an invalid
``hue_range`` is vetoed by the detector and its reason shows beside the field; a change
made with ``ros2 param set`` shows up live. Against the light plain-rclpy robot: a
switch sets a boolean, and a page opened without the token shows the values with every
field disabled, and what it sends anyway changes nothing.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from rcl_interfaces.srv import GetParameters
from rclpy.parameter import parameter_value_to_python
from selenium.webdriver.common.by import By
from selenium.webdriver.common.keys import Keys

from efficient_comm.testing import isolated_domain_id, unique_topic

from ._cli import ros2
from ._gui import (
    Process,
    by_testid,
    camera_robot,
    choose,
    gui,
    screenshot,
    text_of,
    wait_for,
    wait_for_text,
)
from ._ros import Peer, peer
from .test_gui_foxglove import Robot


def layout(path: Path, *, domain: int, namespace: str) -> Path:
    """A layout file with one parameters view bound to the robot."""
    path.write_text(json.dumps({"version": 1, "panels": [{
        "kind": "parameters",
        "robot": {"domain": domain, "namespace": namespace, "via": "dds"}}]}))
    return path


def read(p: Peer, node: str, name: str) -> Any:
    """The node's value of ``name``, asked over its get_parameters service."""
    client = p.node.create_client(GetParameters, f"{node}/get_parameters")
    try:
        assert p.wait_for(client.service_is_ready, 30.0), f"no {node}/get_parameters"
        future = client.call_async(GetParameters.Request(names=[name]))
        assert p.wait_for(future.done, 30.0), f"{node}/get_parameters did not answer"
        return parameter_value_to_python(future.result().values[0])
    finally:
        p.node.destroy_client(client)


def field(browser: Any, testid: str) -> Any:
    """The ``<input>`` of the NiceGUI field ``testid`` (Quasar puts the attribute on it)."""
    element = by_testid(browser, testid)
    return element if element.tag_name == "input" else element.find_element(By.TAG_NAME,
                                                                           "input")


def field_value(browser: Any, testid: str) -> str:
    try:
        return str(field(browser, testid).get_attribute("value"))
    except Exception:  # re-rendered meanwhile
        return ""


def enter(browser: Any, testid: str, text: str) -> None:
    """Click the field, select all, type ``text`` and Enter: what a user does."""
    element = field(browser, testid)
    element.click()
    element.send_keys(Keys.CONTROL, "a")
    element.send_keys(text, Keys.ENTER)


def test_a_parameter_edited_in_the_browser_changes_the_component(
    tmp_path: Path, browser
) -> None:
    domain = isolated_domain_id()
    ns, node = "/robot", "/robot/ball_detector"
    key = f"{domain}:{ns}"
    with camera_robot(tmp_path, domain_id=domain, namespace=ns) as bot, \
            gui(tmp_path, domains=[domain],
                args=["--layout", str(layout(tmp_path / "l.json", domain=domain,
                                             namespace=ns))]) as server, \
            peer(domain) as p:
        alive = [bot, server]
        browser.get(server.url)
        wait_for_text(browser, "pick a node", alive=alive)
        choose(browser, f"params-node-{key}", node, timeout_s=90)
        saturation = f"param-{key}-min_saturation"
        wait_for(lambda: field_value(browser, saturation) == "120",
                 what="min_saturation's field", alive=alive)
        assert "integer" in text_of(browser, f"params-{key}")

        # Typed and set with Enter: the component holds the new value.
        enter(browser, saturation, "140")
        wait_for(lambda: text_of(browser, f"param-status-{key}-min_saturation") == "set to 140",
                 what="the set's outcome", alive=alive)
        assert read(p, node, "min_saturation") == 140

        # A value the detector vetoes: its reason beside the field, the value unchanged.
        enter(browser, f"param-{key}-hue_range", "[30, 10]")
        refusal = wait_for(
            lambda: "hue_range must be [low, high] within 0..180" in (
                t := text_of(browser, f"param-status-{key}-hue_range")) and t,
            what="the veto's reason", alive=alive)
        assert refusal.startswith(f"refused by {node}: "), refusal
        assert list(read(p, node, "hue_range")) == [5, 22]
        wait_for(lambda: field_value(browser, f"param-{key}-hue_range") == "[5, 22]",
                 what="the field back at the node's value", alive=alive)
        screenshot(browser, "parameters_view_veto")
        # A valid array goes through.
        enter(browser, f"param-{key}-hue_range", "[6, 20]")
        wait_for(lambda: text_of(browser, f"param-status-{key}-hue_range") == "set to [6, 20]",
                 what="the array's outcome", alive=alive)
        assert list(read(p, node, "hue_range")) == [6, 20]

        # Bad input is refused in the page, before it is sent.
        enter(browser, f"param-{key}-hue_range", "[5, twenty]")
        wait_for(lambda: text_of(browser, f"param-status-{key}-hue_range")
                 == "expected an integer array, got '[5, twenty]'",
                 what="the input's refusal", alive=alive)
        assert list(read(p, node, "hue_range")) == [6, 20]

        # A change made elsewhere shows up live.
        result = ros2("param", "set", node, "min_value", "90", domain_id=domain)
        assert result.returncode == 0, result.stderr
        wait_for(lambda: field_value(browser, f"param-{key}-min_value") == "90",
                 what="the change made with ros2 param set", alive=alive)
        assert text_of(browser, f"param-status-{key}-min_value") == "changed elsewhere to 90"
        assert read(p, node, "min_saturation") == 140
        screenshot(browser, "parameters_view")


def test_a_switch_sets_a_boolean_and_a_page_without_the_token_cannot_write(
    tmp_path: Path, browser
) -> None:
    domain = isolated_domain_id()
    ns, node = "/pr", "/pr/detector"
    key = f"{domain}:{ns}"
    bot = Robot(domain, ns, unique_topic("chatter"))
    try:
        with gui(tmp_path, domains=[domain],
                 args=["--layout", str(layout(tmp_path / "l.json", domain=domain,
                                              namespace=ns))]) as server:
            alive: list[Process] = [server]
            browser.get(server.url)
            choose(browser, f"params-node-{key}", node, timeout_s=60)
            switch = f"param-{key}-enabled"
            wait_for(lambda: text_of(browser, f"params-{key}") and by_testid(browser, switch),
                     what="the boolean's switch", alive=alive)
            assert "how many · 0..10 step 1" in text_of(browser, f"params-{key}")
            assert "string · read-only" in text_of(browser, f"params-{key}")
            assert not field(browser, f"param-{key}-label").is_enabled()  # read-only param
            by_testid(browser, switch).click()
            bot.expect("enabled False")
            wait_for(lambda: text_of(browser, f"param-status-{key}-enabled") == "set to false",
                     what="the switch's outcome", alive=alive)
            # Outside the descriptor's range (shown above): refused before it is sent.
            enter(browser, f"param-{key}-count", "11")
            wait_for(lambda: text_of(browser, f"param-status-{key}-count")
                     == "count must be within 0..10, not 11", what="the range's refusal",
                     alive=alive)
            assert bot.last("count") is None  # nothing reached the node

            # Without the token: values shown, every field disabled, forced events ignored.
            # Another tab: this one would come back with its own working layout.
            browser.switch_to.new_window("tab")
            browser.get(server.base_url)
            wait_for_text(browser, "read-only", alive=alive)
            choose(browser, f"params-node-{key}", node, timeout_s=60)
            count = f"param-{key}-count"
            wait_for(lambda: field_value(browser, count) == "3", what="count's value",
                     alive=alive)
            assert "changes need the server's token" in text_of(browser, f"params-status-{key}")
            assert not field(browser, count).is_enabled()
            assert "disabled" in (by_testid(browser, switch).get_attribute("class") or "")
            _force(browser, count, 9)
            # Events of one page are handled in order: once the filter typed after the
            # forced ones has narrowed the list, those were handled too.
            filter_box = field(browser, f"params-filter-{key}")
            filter_box.send_keys("coun")
            wait_for(lambda: "threshold" not in text_of(browser, f"params-{key}")
                     and "count" in text_of(browser, f"params-{key}"),
                     what="the filtered list", alive=alive)
            assert field_value(browser, count) == "3"
            with peer(domain) as p:
                assert read(p, node, "count") == 3
            assert bot.last("count") is None
            screenshot(browser, "parameters_view_read_only")
    finally:
        bot.close()


def _force(browser: Any, testid: str, value: int) -> None:
    """Send what the page would send for a typed value and Enter, around the disabled
    field (the server must not act on it)."""
    browser.execute_script("""
        const root = document.querySelector(`[data-testid="${arguments[0]}"]`);
        const known = (el) => el && /^c[0-9]+$/.test(el.id) && mounted_app.elements[el.id.slice(1)];
        let el = root;
        while (el && !known(el)) el = el.parentElement;
        const id = Number(el.id.slice(1));
        const events = mounted_app.elements[id].events;
        const send = (ev, arg) => window.socket.emit('event', {
            id, client_id: window.clientId, listener_id: ev.listener_id,
            args: [JSON.stringify(arg)]});
        events.filter((ev) => ev.type.startsWith('update')).forEach((ev) => send(ev, arguments[1]));
        events.filter((ev) => ev.type === 'keydown').forEach((ev) => send(ev, {key: 'Enter'}));
        """, testid, value)
