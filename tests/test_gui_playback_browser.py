"""A merged team log played back in debug_gui (issue 21, 3): ``debug_gui --log LOG --video
VIDEO`` as a user types it, driven in headless chromium.

One small log for the file (log_analysis.testing's filmed ball: 4 s of the ball at 100 Hz,
two robots' beliefs at 10 Hz, and its video on a camera clock 2 s ahead, with the fit
beside it), its events sidecar, and one debug_gui process shared by the tests: starting
the GUI costs more than anything they do.
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from typing import Any

import pytest

from debug_gui import RobotId
from debug_gui.layout import Layout, Panel
from efficient_comm.testing import isolated_domain_id
from log_analysis import Event, VideoFit, sidecar_path, write_events
from log_analysis.testing import film_ball

from ._gui import GuiProcess, by_testid, click, gui, text_of, wait_for
from .test_gui_parameters_browser import enter

BLUE1 = "0:/blue1"
#: The events, by log time (s): what the list shows, in this order.
EVENTS = [(0.5, "kick-off", ""), (1.5, "fell", "blue1"), (3.0, "fell", "red1")]


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[GuiProcess]:
    folder = tmp_path_factory.mktemp("playback")
    log, video = film_ball(
        folder, lambda t: (t - 2.0, 0.5), seconds=4.0, offset_s=2.0, drift_ppm=0.0, fps=5,
        robots={"blue1": lambda t: (t - 1.0, -1.0, 0.0), "red1": lambda t: (2.0, 1.0, 3.1)})
    write_events(sidecar_path(log), [
        Event(name, round(t * 1e9), round(t * 1e9), robot, f"{robot or 'team'} {name}",
              generator="falls" if name == "fell" else "game")
        for t, name, robot in EVENTS])
    VideoFit(offset_ns=2_000_000_000, drift_ppm=0.0, start_ns=2_000_000_000, residual_ns=0,
             method="known", frame_period_ns=200_000_000).save(f"{video}.sync.json")
    layout = folder / "layout.json"
    # Saved live: the match's robots were in domain 13 (a log keeps their namespaces).
    layout.write_text(Layout((Panel(kind="world", robot=RobotId(13, "/blue1")),)).to_json())
    with gui(folder, domains=[isolated_domain_id()],
             args=["--log", str(log), "--video", str(video), "--layout", str(layout)]) as g:
        yield g


def _time(browser: Any) -> float | None:
    found = re.match(r"\s*(-?\d+\.\d+) s /", text_of(browser, "playback-time"))
    return float(found.group(1)) if found else None


def _at(browser: Any, seconds: float, server: GuiProcess, *, what: str) -> None:
    wait_for(lambda: _time(browser) == seconds, what=f"{what}: the time at {seconds:.2f} s "
             f"(shows {text_of(browser, 'playback-time')!r})", alive=[server])


def _blue1_x(browser: Any) -> str:
    try:
        return str(by_testid(browser, f"world-robot-{BLUE1}").get_attribute("data-x"))
    except Exception:  # not drawn yet, or re-rendered meanwhile
        return ""


def _frame_t(browser: Any) -> str:
    try:
        img = by_testid(browser, "playback-video").find_element("css selector", "img")
        return str(img.get_attribute("src"))
    except Exception:
        return ""


def test_play_and_seek_show_the_new_instant_in_every_view(server: GuiProcess,
                                                          browser: Any) -> None:
    browser.get(server.url)
    _at(browser, 0.0, server, what="the log opened at its start")
    wait_for(lambda: _blue1_x(browser) == "-1.000", what="blue1 at its first pose",
             alive=[server])
    enter(browser, "playback-goto", "2.5")
    _at(browser, 2.5, server, what="a seek")
    # The world view (bound to the log's robots, from a layout saved live) and the video
    # show the new instant: blue1 believed itself at x = t - 1; frame t=2.4 s (5 fps).
    wait_for(lambda: _blue1_x(browser) == "1.500", what="blue1's pose at 2.5 s",
             alive=[server])
    wait_for(lambda: "t=1002500000000" in _frame_t(browser) or "t=2500000000" in
             _frame_t(browser), what="the video frame of 2.5 s", alive=[server])
    click(browser, "playback-play")
    wait_for(lambda: (_time(browser) or 0.0) > 2.6, what="the cursor running",
             alive=[server])
    wait_for(lambda: float(_blue1_x(browser) or 0.0) > 1.5, what="blue1 moving on",
             alive=[server])
    click(browser, "playback-play")  # pause
    wait_for(lambda: "play" in text_of(browser, "playback-play").lower()
             and "pause" not in text_of(browser, "playback-play").lower(),
             what="paused", alive=[server])


def test_the_event_list_jumps_filters_and_navigates(server: GuiProcess,
                                                    browser: Any) -> None:
    browser.get(server.url)
    wait_for(lambda: "blue1: fell" in text_of(browser, "event-1"), what="the event list",
             alive=[server])
    click(browser, "event-1")
    _at(browser, 1.5, server, what="a click on blue1's fall")
    click(browser, "event-next")
    _at(browser, 3.0, server, what="the next event")
    click(browser, "event-previous")
    click(browser, "event-previous")
    _at(browser, 0.5, server, what="the event before the previous one")
    enter(browser, "event-filter", "fell")
    wait_for(lambda: "red1: fell" in text_of(browser, "event-1")
             and "kick-off" not in text_of(browser, "event-list"),
             what="the list filtered to falls", alive=[server])
    click(browser, "event-1")
    _at(browser, 3.0, server, what="a click on red1's fall")
