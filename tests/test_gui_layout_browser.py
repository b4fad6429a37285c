"""A tab's layout in a real browser (issue 18, 4b): a reload brings back the tab's working
layout with each view's settings, and a save never silently replaces a layout saved
elsewhere since the tab loaded it."""

from __future__ import annotations

import json
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from efficient_comm.testing import isolated_domain_id

from ._gui import (
    Process,
    by_testid,
    choose,
    click,
    click_cell,
    fake_robot,
    gui,
    present,
    reload,
    screenshot,
    text_of,
    wait_for,
    wait_for_text,
)
from .test_gui_parameters_browser import field, field_value


def _add(browser: Any, kind: str, robot: str) -> None:
    choose(browser, "add-kind", kind)
    choose(browser, "add-robot", robot)
    click(browser, "add-view")


def _type(browser: Any, testid: str, text: str) -> None:
    element = field(browser, testid)
    element.click()
    element.send_keys(text)


def _select_text(browser: Any, testid: str) -> str:
    """What a NiceGUI select shows as chosen (Quasar puts the test id on its input)."""
    return str(browser.execute_script(
        "const el = document.querySelector(`[data-testid=\"${arguments[0]}\"]`);"
        "return el ? (el.closest('.q-field') || el).innerText : '';", testid))



@contextmanager
def _alpha_page(tmp_path: Path, browser: Any, *,
                layout: Path | None = None) -> Iterator[tuple[int, list[Process]]]:
    """A light robot ``/alpha`` in a domain of its own, the GUI (with ``--layout``, if
    given) and the browser on its page once the robot shows: (domain, processes to watch)."""
    domain = isolated_domain_id()
    args = ["--layout", str(layout)] if layout is not None else []
    with fake_robot(tmp_path, domain_id=domain, namespace="/alpha") as bot, \
            gui(tmp_path, domains=[domain], args=args) as server:
        alive: list[Process] = [bot, server]
        browser.get(server.url)
        wait_for_text(browser, f"alpha @ domain {domain}", alive=alive)
        yield domain, alive

def test_a_reload_keeps_the_tabs_layout_and_each_views_settings(tmp_path: Path,
                                                                  browser: Any) -> None:
    layout = tmp_path / "layout.json"
    with _alpha_page(tmp_path, browser, layout=layout) as (domain, alive):
        key, label = f"{domain}:/alpha", f"alpha @ domain {domain}"
        # Unsaved work: a log view with a level and a filter, a parameters view with a
        # node and a filter.
        _add(browser, "Diagnostics and log", label)
        wait_for(lambda: present(browser, f"logs-level-{key}"), what="the log view",
                 alive=alive)
        choose(browser, f"logs-level-{key}", "warn")
        _type(browser, f"logs-filter-{key}", "servo")
        _add(browser, "Parameters", label)
        wait_for(lambda: present(browser, f"params-node-{key}"),
                 what="the parameters view", alive=alive)
        choose(browser, f"params-node-{key}", "/alpha/fake_robot", timeout_s=60)
        wait_for(lambda: "use_sim_time" in text_of(browser, f"params-{key}"),
                 what="the node's parameters", alive=alive)
        _type(browser, f"params-filter-{key}", "sim")
        # The server has seen every keystroke once the filtered list shows.
        wait_for(lambda: field_value(browser, f"logs-filter-{key}") == "servo"
                 and "use_sim_time" in text_of(browser, f"params-{key}"),
                 what="the typed filters", alive=alive)

        reload(browser, alive=alive)  # what NiceGUI does when its handshake or rewind fails

        wait_for(lambda: "Parameters" in text_of(browser, "panel-2"),
                 what="the tab's three panels after the reload", alive=alive)
        assert "Diagnostics and log" in text_of(browser, "panel-1")
        wait_for(lambda: field_value(browser, f"logs-filter-{key}") == "servo",
                 what="the log filter", alive=alive)
        assert "warn" in _select_text(browser, f"logs-level-{key}")
        wait_for(lambda: field_value(browser, f"params-filter-{key}") == "sim"
                 and "use_sim_time" in text_of(browser, f"params-{key}"),
                 what="the parameters view's node and filter", alive=alive)
        assert field_value(browser, f"params-node-{key}") == "/alpha/fake_robot"
        assert not layout.exists()  # all of it from the tab, nothing saved

        # Saved, the file holds the settings too (names relative to the robot).
        click(browser, "save-layout")
        wait_for_text(browser, "layout saved", alive=alive)
        panels = json.loads(layout.read_text())["panels"]
        assert panels[1]["settings"] == {"filter": "servo", "level": "warn"}
        assert panels[2]["settings"] == {"filter": "sim", "node": "fake_robot"}


def test_a_save_over_a_layout_saved_elsewhere_is_refused_then_confirmed(
        tmp_path: Path, browser: Any) -> None:
    layout = tmp_path / "layout.json"
    with _alpha_page(tmp_path, browser, layout=layout) as (domain, alive):
        label = f"alpha @ domain {domain}"
        click(browser, "save-layout")
        wait_for_text(browser, "layout saved", alive=alive)
        # Another tab or server saves a different layout meanwhile.
        theirs = {"version": 1, "panels": [{"kind": "image", "team": True}]}
        layout.write_text(json.dumps(theirs))
        _add(browser, "Diagnostics and log", label)
        wait_for(lambda: present(browser, "panel-1"), what="the added panel", alive=alive)
        click(browser, "save-layout")
        wait_for_text(browser, "saved elsewhere since this tab loaded it", alive=alive)
        assert json.loads(layout.read_text()) == theirs  # left alone
        # Told, the user saves again: now it replaces the other layout.
        by_testid(browser, "save-layout").click()
        wait_for(lambda: len(json.loads(layout.read_text())["panels"]) == 2,
                 what="the confirmed save", alive=alive)


def test_a_reload_echoes_and_plots_what_the_topics_view_showed(tmp_path: Path,
                                                               browser: Any) -> None:

    stats = "/alpha/efficient_comm/stats"
    with _alpha_page(tmp_path, browser) as (domain, alive):
        key, label = f"{domain}:/alpha", f"alpha @ domain {domain}"
        _add(browser, "Topics", label)
        click_cell(browser, f"topics-{key}", stats, alive=alive)
        wait_for(lambda: "window_ns" in text_of(browser, f"topics-echo-{key}"),
                 what="the echoed statistics", alive=alive)
        choose(browser, f"topics-plot-field-{key}", "window_ns")
        wait_for(lambda: "window_ns" in _select_text(browser, f"topics-plot-field-{key}"),
                 what="the plotted field", alive=alive)

        reload(browser, alive=alive)

        wait_for(lambda: stats in text_of(browser, f"topics-echo-title-{key}"),
                 what="the echoed topic after the reload", alive=alive)
        wait_for(lambda: "window_ns" in text_of(browser, f"topics-echo-{key}")
                 and "window_ns" in _select_text(browser, f"topics-plot-field-{key}"),
                 what="the echo and the plotted field after the reload", alive=alive)


#: The panels' test ids in the page's order.
_PANELS = """
return Array.from(document.querySelectorAll('[data-testid^="panel-"]')).map(
    p => p.dataset.testid);
"""


def _panels_in_order(browser: Any, titles: list[str]) -> bool:
    """Whether the page shows panels with these titles, in this order."""
    ids = [f"panel-{i}" for i in range(len(titles))]
    return bool(browser.execute_script(_PANELS) == ids and all(
        text_of(browser, f"panel-{i}").startswith(title) for i, title in enumerate(titles)))


def test_add_keeps_the_chosen_view_and_robot(tmp_path: Path, browser: Any) -> None:
    """Issue 18, 4g: after "add" the view and robot chosen stay chosen (adding several views
    for one robot is one click each), and the panel's own robot selector stays the robot."""
    with _alpha_page(tmp_path, browser) as (domain, alive):
        key, label = f"{domain}:/alpha", f"alpha @ domain {domain}"
        _add(browser, "Diagnostics and log", label)
        wait_for(lambda: present(browser, "panel-1") and present(browser, f"logs-level-{key}"),
                 what="the log view", alive=alive)
        assert label in _select_text(browser, "add-robot")
        assert "Diagnostics and log" in _select_text(browser, "add-kind")
        click(browser, "add-view")  # nothing chosen again: the same view, the same robot
        wait_for(lambda: present(browser, "panel-2"), what="the second log view", alive=alive)
        assert text_of(browser, "panel-2").startswith(f"Diagnostics and log — {label}")
        assert label in _select_text(browser, "add-robot")


def test_a_clone_lands_beside_its_original(tmp_path: Path, browser: Any) -> None:
    """Issue 18, 4g: a clone is the panel right after its original, not the last one."""
    with _alpha_page(tmp_path, browser) as (domain, alive):
        label = f"alpha @ domain {domain}"
        _add(browser, "Diagnostics and log", label)
        wait_for(lambda: present(browser, "panel-1"), what="the log view", alive=alive)
        # The team's components panel (the first) cloned for alpha: second, not last.
        choose(browser, "clone-0", label)
        expected = ["Components — team", f"Components — {label}",
                    f"Diagnostics and log — {label}"]
        wait_for(lambda: _panels_in_order(browser, expected),
                 what=f"the panels in the order {expected}", alive=alive)
        wait_for(lambda: "alpha_component0" in text_of(browser, "panel-1"),
                 what="the clone's rows", alive=alive)
        assert text_of(browser, "binding-1").startswith("2. Components")
        screenshot(browser, "clone_beside_its_original")
