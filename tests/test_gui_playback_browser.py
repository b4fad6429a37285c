"""A merged team log played back in debug_gui (issue 21, 3): ``debug_gui --log LOG --video
VIDEO`` as a user types it, driven in headless chromium.

One small log for the file (log_analysis.testing's filmed ball: 4 s of the ball at 100 Hz,
two robots' beliefs at 10 Hz, and its video on a camera clock 2 s ahead, with the fit
beside it), its events sidecar, and one debug_gui process shared by the tests: starting
the GUI costs more than anything they do.
"""

from __future__ import annotations

import re
import urllib.error
import urllib.request
from collections.abc import Iterator
from typing import Any

import pytest

from debug_gui import RobotId
from debug_gui.layout import Layout, Panel
from debug_gui.ui.playback import ROUTE
from efficient_comm.testing import isolated_domain_id
from log_analysis import Event, VideoFit, sidecar_path, write_events
from log_analysis.testing import film_ball

from ._gui import GuiProcess, by_testid, click, gui, text_of, wait_for, wait_for_text
from .test_gui_parameters_browser import enter

BLUE1 = "0:/blue1"
#: A 1 x 1 PNG: the report's plot.
PNG = bytes.fromhex("89504e470d0a1a0a0000000d49484452000000010000000108060000001f15c489"
                    "0000000b49444154789c6360000200000500017a5eab3f0000000049454e44ae426082")
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
    report = folder / "report"
    report.mkdir()
    (report / "report.md").write_text("# A/B report\n\nthe blob detector wins\n\n"
                                      "![detections](detections.png)\n")
    (report / "detections.png").write_bytes(PNG)
    layout = folder / "layout.json"
    # Saved live: the match's robots were in domain 13 (a log keeps their namespaces).
    layout.write_text(Layout((Panel(kind="world", robot=RobotId(13, "/blue1")),
                              Panel(kind="recorder"))).to_json())
    with gui(folder, domains=[isolated_domain_id()],
             args=["--log", str(log), "--video", str(video), "--layout", str(layout),
                   "--augmented", str(video), "--report", str(report)]) as g:
        yield g


def _time(browser: Any) -> float | None:
    found = re.match(r"\s*(-?\d+\.\d+) s /", text_of(browser, "playback-time"))
    return float(found.group(1)) if found else None


def _at(browser: Any, seconds: float, server: GuiProcess, *, what: str) -> None:
    wait_for(lambda: _time(browser) == seconds, what=f"{what}: the time at {seconds:.2f} s "
             f"(shows {text_of(browser, 'playback-time')!r})", alive=[server])


def _pause(browser: Any, server: GuiProcess) -> None:
    """Pause unless the cursor already stopped (at the log's end it stops by itself, and a
    click there would play again from the start)."""
    def label() -> str:  # the button's words after its icon's name
        words = text_of(browser, "playback-play").lower().split()
        return words[-1] if words else ""

    wait_for(lambda: label() in ("play", "pause"), what="the play button", alive=[server])
    if label() == "pause":
        click(browser, "playback-play")
    wait_for(lambda: label() == "play", what="paused", alive=[server])


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
    # The cursor is the server's, shared by every tab: another test of this module may
    # have moved it or left it playing (xdist runs them in any order): from the start.
    wait_for(lambda: _time(browser) is not None, what="the playback bar", alive=[server])
    _pause(browser, server)
    enter(browser, "playback-goto", "0")
    _at(browser, 0.0, server, what="the log's start")
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
    _pause(browser, server)
    # The timeline: a click a quarter along the slider seeks to about a quarter of the log
    # (the track is inset in its element), and the world view follows.
    from selenium.webdriver.common.action_chains import ActionChains

    slider = by_testid(browser, "playback-slider")
    width = slider.size["width"]
    ActionChains(browser).move_to_element_with_offset(slider, -width // 4, 0).click().perform()
    wait_for(lambda: 0.4 <= (_time(browser) or -9.0) <= 1.6,
             what=f"the slider's seek to about 1 s (shows {text_of(browser, 'playback-time')!r})",
             alive=[server])
    at = _time(browser) or 0.0
    # blue1 believed x = t - 1 at 10 Hz: the last pose at or before the instant.
    wait_for(lambda: abs(float(_blue1_x(browser) or 9.0) - (int(at * 10 + 1e-6) / 10 - 1.0))
             < 1e-3, what=f"blue1's pose at {at} s", alive=[server])


def test_the_event_list_jumps_filters_and_navigates(server: GuiProcess,
                                                    browser: Any) -> None:
    browser.get(server.url)
    wait_for(lambda: "blue1: fell" in text_of(browser, "event-1"), what="the event list",
             alive=[server])
    _pause(browser, server)  # the server is the file's: an earlier test may have left it playing
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


def _get(url: str) -> tuple[int, str, bytes]:
    try:
        with urllib.request.urlopen(url, timeout=10) as response:
            return int(response.status), str(response.headers["content-type"]), response.read()
    except urllib.error.HTTPError as exc:
        return exc.code, "", b""


def test_the_video_frame_augmented_video_and_report_are_served(server: GuiProcess,
                                                               browser: Any) -> None:
    base = server.base_url.rstrip("/")
    status, kind, data = _get(f"{base}{ROUTE}/frame.jpg?t=2500000000")
    assert (status, kind) == (200, "image/jpeg") and data.startswith(b"\xff\xd8")
    status, kind, data = _get(f"{base}{ROUTE}/augmented.mp4")
    assert status == 200 and kind == "video/mp4" and len(data) > 1000
    assert _get(f"{base}{ROUTE}/report/detections.png")[2] == PNG
    assert _get(f"{base}{ROUTE}/report/..%2Flog.events.mcap")[0] == 404  # the folder only
    browser.get(server.url)
    wait_for(lambda: "A/B report" in text_of(browser, "playback-report"), what="the report",
             alive=[server])
    click(browser, "playback-report")
    wait_for(lambda: "the blob detector wins" in text_of(browser, "playback-report"),
             what="the report's text", alive=[server])
    plot = by_testid(browser, "playback-report").find_element("css selector", "img")
    assert f"{ROUTE}/report/detections.png" in str(plot.get_attribute("src"))
    assert "augmented video" in text_of(browser, "playback-augmented")


def test_a_bad_go_to_is_told_and_the_recorder_says_the_log_is_not_live(
        server: GuiProcess, browser: Any) -> None:
    """"go to" a time that is no number or lies outside the log says so (it did nothing, or
    went to an end, without a word); the recorder view says the log is not live (it said
    the robot "has no recorder (yet)", as live)."""
    browser.get(server.url)
    # Loaded: a time is shown (whichever: the log's cursor is the module's server's, where
    # the test before left it; reading it once before the page showed any waited for 0.00).
    wait_for(lambda: _time(browser) is not None, what="the page's time", alive=[server])
    enter(browser, "playback-goto", "abc")
    wait_for_text(browser, "cannot go to 'abc'", alive=[server])
    enter(browser, "playback-goto", "99")
    wait_for_text(browser, re.compile(r"99 s is outside the log \(0 to [\d.]+ s\): went to "
                                      "its end"), alive=[server])
    wait_for_text(browser, "blue1 @ domain 0: recorded: not live: the log holds no "
                  "recorder's status", alive=[server])
