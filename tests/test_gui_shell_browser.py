"""The shell in a real browser: binding views to robots, clone, team layout, layouts saved
and restored across a restart, robots appearing and leaving live."""

from __future__ import annotations

import json
import re
from pathlib import Path

from efficient_comm.testing import isolated_domain_id

from ._gui import (
    by_testid,
    choose,
    click,
    fake_robot,
    gui,
    present,
    screenshot,
    text_of,
    wait_for,
    wait_for_text,
)
from .test_gui_hub_data import plain_robot


def _tables(browser, panel: int, keys: list[str]) -> set[str]:
    """Which robots' component tables panel ``panel`` shows (of ``keys``)."""
    shown = text_of(browser, f"panel-{panel}")
    return {k for k in keys if present(browser, f"components-{k}") and k.split(":")[1] in shown}


def test_bind_clone_team_layout_save_and_restore(tmp_path: Path, browser) -> None:
    d1, d2 = isolated_domain_id(), isolated_domain_id()
    alpha, beta = f"{d1}:/alpha", f"{d2}:/beta"
    alpha_label, beta_label = f"alpha @ domain {d1}", f"beta @ domain {d2}"
    layout = tmp_path / "layout.json"
    with fake_robot(tmp_path, domain_id=d1, namespace="/alpha") as a, \
            fake_robot(tmp_path, domain_id=d2, namespace="/beta") as b:
        with gui(tmp_path, domains=[d1, d2], args=["--layout", str(layout)]) as server:
            alive = [a, b, server]
            browser.get(server.url)
            wait_for_text(browser, beta_label, alive=alive)
            # The default layout: one components panel for the whole team.
            wait_for(lambda: present(browser, f"components-{alpha}")
                     and present(browser, f"components-{beta}"), what="both tables",
                     alive=alive)
            # Bind the panel to alpha alone (the central binding view).
            choose(browser, "bind-0", alpha_label)
            wait_for(lambda: f"Components — {alpha_label}" in text_of(browser, "panel-0")
                     and not present(browser, f"components-{beta}"),
                     what="panel 0 bound to alpha", alive=alive)
            # Clone it for beta.
            choose(browser, "clone-0", beta_label)
            wait_for(lambda: f"Components — {beta_label}" in text_of(browser, "panel-1")
                     and present(browser, f"components-{beta}"), what="the clone for beta",
                     alive=alive)
            wait_for(lambda: "beta_component0" in text_of(browser, f"components-{beta}"),
                     what="beta's rows in the clone", alive=alive)
            # A team layout of the components view: one instance per robot, side by side.
            click(browser, "team-layout")
            wait_for(lambda: "Components — team" in text_of(browser, "panel-2"),
                     what="the team panel", alive=alive)
            # Robots appear and leave live; the team panel follows.
            with fake_robot(tmp_path, domain_id=d2, namespace="/gamma") as c:
                gamma = f"{d2}:/gamma"
                wait_for(lambda: present(browser, f"components-{gamma}"),
                         what="gamma joining the team panel", alive=[*alive, c])
                assert present(browser, f"robot-{gamma}")
                screenshot(browser, "shell_bound_clone_team")
            wait_for(lambda: not present(browser, f"robot-{gamma}")
                     and not present(browser, f"components-{gamma}"),
                     what="gamma leaving", alive=alive)
            click(browser, "save-layout")
            wait_for_text(browser, "layout saved", alive=alive)
        saved = json.loads(layout.read_text())["panels"]
        assert saved == [
            {"kind": "components", "robot": {"domain": d1, "namespace": "/alpha", "via": "dds"}},
            {"kind": "components", "robot": {"domain": d2, "namespace": "/beta", "via": "dds"}},
            {"kind": "components", "team": True},
        ]
        # A new server restores the layout it is given.
        with gui(tmp_path, domains=[d1, d2], args=["--layout", str(layout)]) as server:
            browser.get(server.url)
            wait_for(lambda: f"Components — {alpha_label}" in text_of(browser, "panel-0")
                     and f"Components — {beta_label}" in text_of(browser, "panel-1")
                     and "Components — team" in text_of(browser, "panel-2"),
                     what="the restored layout", alive=[a, b, server])


def _label_cut_off(browser, testid: str) -> bool:
    """Whether the label of the field ``testid`` is wider than the room it is given."""
    return bool(browser.execute_script(
        "const e = document.querySelector(`[data-testid='${arguments[0]}']`);"
        "const l = e && e.closest('.q-field').querySelector('.q-field__label');"
        "return !l || l.scrollWidth > l.clientWidth;", testid))


def test_a_plain_robot_a_robot_without_camera_restore_and_robots_leaving(
    tmp_path: Path, browser
) -> None:
    """With --plain-robots a plain ROS 2 robot is shown, and its components view says why
    it is empty; an image view of a robot without a JPEG compressor says why the quality
    cannot be set; removing that view and restoring a layout give their messages and no
    server error."""
    domain = isolated_domain_id()
    key, plain = f"{domain}:/r", f"{domain}:/plainbot"
    layout = tmp_path / "layout.json"
    with fake_robot(tmp_path, domain_id=domain, namespace="/r") as r, \
            plain_robot(tmp_path, domain_id=domain, namespace="/plainbot") as p, \
            gui(tmp_path, domains=[domain],
                args=["--layout", str(layout), "--plain-robots"]) as server:
        alive = [r, p, server]
        browser.get(server.url)
        # Both robots first: one found later re-renders the binding view (and its menus).
        wait_for(lambda: present(browser, f"robot-{plain}") and present(browser, f"robot-{key}"),
                 what="both robots in the header", alive=alive)
        wait_for(lambda: "publishes no efficient_comm statistics"
                 in text_of(browser, f"components-status-{plain}"),
                 what="the plain robot's components view saying why it is empty", alive=alive)
        # An image view of a robot without a compressor: the reason, no traceback.
        choose(browser, "add-kind", "Image")
        choose(browser, "add-robot", f"r @ domain {domain}")
        click(browser, "add-view")
        wait_for(lambda: "no service /r/jpeg_compressor/get_parameters"
                 in text_of(browser, f"image-quality-note-{key}"),
                 what="why the quality cannot be set", alive=alive)
        assert not by_testid(browser, f"image-quality-set-{key}").is_enabled()
        assert not _label_cut_off(browser, f"image-quality-{key}")
        screenshot(browser, "image_without_compressor")
        click(browser, "remove-1")  # its frame socket closes
        wait_for(lambda: not present(browser, f"image-{key}"), what="the image view gone",
                 alive=alive)
        click(browser, "save-layout")
        wait_for_text(browser, "layout saved", alive=alive)
        click(browser, "restore-layout")  # re-renders the button that was clicked
        wait_for_text(browser, "layout restored", alive=alive)
    output = server.output()
    for error in ("Traceback", "Exception in ASGI", "slot", "default-expand-all"):
        assert error not in output, output


def test_the_header_says_no_robots_once_the_last_one_left(tmp_path: Path, browser) -> None:
    domain = isolated_domain_id()
    with gui(tmp_path, domains=[domain]) as server:
        browser.get(server.url)
        wait_for(lambda: text_of(browser, "robots") == "no robots yet",
                 what="no robots yet", alive=[server])
        with fake_robot(tmp_path, domain_id=domain, namespace="/r") as r:
            wait_for(lambda: present(browser, f"robot-{domain}:/r"), what="the robot",
                     alive=[r, server])
        wait_for(lambda: text_of(browser, "robots") == "no robots",
                 what="the header saying no robots", alive=[server])


def _stats_readers(robot) -> int:
    found = re.findall(r"stats readers (\d+)", robot.output())
    return int(found[-1]) if found else -1


def test_a_hidden_view_costs_the_robot_nothing(tmp_path: Path, browser) -> None:
    """Collapsing, removing or leaving a view closes its feed on the robot; opening it again
    subscribes again."""
    domain = isolated_domain_id()
    with fake_robot(tmp_path, domain_id=domain, namespace="/r") as robot, \
            gui(tmp_path, domains=[domain]) as server:
        alive = [robot, server]

        def readers(n: int, what: str) -> None:
            reports = robot.output().count("stats readers")
            # two fresh reports, the last one with n readers
            wait_for(lambda: robot.output().count("stats readers") >= reports + 2
                     and _stats_readers(robot) == n, what=what, alive=alive)

        readers(0, "no reader before anyone looks")
        browser.get(server.url)
        wait_for(lambda: present(browser, f"components-{domain}:/r"), what="the view",
                 alive=alive)
        readers(1, "the view reading the robot's statistics")
        click_header(browser, "panel-0")  # collapse
        readers(0, "the collapsed view letting go")
        click_header(browser, "panel-0")  # open again
        readers(1, "the reopened view reading again")
        click(browser, "remove-0")
        readers(0, "the removed view letting go")
        click(browser, "team-layout")
        readers(1, "a new team panel reading")
        browser.get("about:blank")  # the tab goes
        readers(0, "the closed tab letting go")


def click_header(browser, testid: str) -> None:
    """Toggle an expansion panel by its header."""
    from selenium.webdriver.common.by import By

    from ._gui import by_testid

    header = ".q-expansion-item__container > .q-item"
    by_testid(browser, testid).find_element(By.CSS_SELECTOR, header).click()
