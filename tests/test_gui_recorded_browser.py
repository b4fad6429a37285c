"""The views that call a robot's services, in a real browser, over a source that is a
recorded log (not live): each says "recorded: not live" and offers no control, even to a
writer with the token, instead of an error or a wait for a service that cannot answer.

The server is tests/_gui_recorded_server.py: the production views over
``debug_gui.testing.FakeSource(live=False)`` (a playback's contract: no service answers),
since the log playback source is built apart (issue 21); one process, no robot.
"""

from __future__ import annotations

import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from selenium.webdriver.common.by import By

from efficient_comm.testing import isolated_domain_id, ros_env

from ._gui import _URL, GuiProcess, Process, by_testid, started, text_of, wait_for

SERVER = Path(__file__).with_name("_gui_recorded_server.py")
KEY = "0:/rec1"


@contextmanager
def recorded_gui(tmp_path: Path) -> Iterator[GuiProcess]:
    log = tmp_path / "recorded_gui.log"
    with started([sys.executable, SERVER], env=ros_env(isolated_domain_id()),
                 log=log) as proc:
        first = Process(proc=proc, log=log)
        match = wait_for(lambda: _URL.search(first.output()), timeout_s=60,
                         what="the server's URL", alive=[first])
        yield GuiProcess(proc=proc, log=log, url=match.group(1))


def _disabled(element: Any) -> bool:
    if element.tag_name not in ("input", "button", "textarea"):
        inputs = element.find_elements(By.TAG_NAME, "input")
        element = inputs[0] if inputs else element
    return not element.is_enabled() or "disabled" in (element.get_attribute("class") or "")


def _text(browser: Any, testid: str) -> str:
    try:
        return text_of(browser, testid)
    except Exception:  # not rendered yet, or re-rendered meanwhile
        return ""


def test_views_that_call_services_say_recorded_not_live(tmp_path: Path, browser) -> None:
    with recorded_gui(tmp_path) as server:
        alive = [server]
        browser.get(server.url)  # with the token: a writer, were the source live
        recorder = f"{KEY}-recorder"
        wait_for(lambda: "recorded: not live" in _text(browser, f"recorder-result-{recorder}"),
                 timeout_s=60, what="the recorder's not-live note", alive=alive)
        # The status as the log replays it, and no control.
        wait_for(lambda: _text(browser, f"recorder-state-{recorder}") == "recording",
                 what="the recorded status", alive=alive)
        for action in ("start", "stop", "split", "snapshot"):
            assert _disabled(by_testid(browser, f"recorder-{action}-{recorder}")), action
        # The parameters as the log's events tell them, read-only, said so.
        wait_for(lambda: "recorded: not live" in _text(browser, f"params-status-{KEY}"),
                 what="the parameters' not-live note", alive=alive)
        wait_for(lambda: _text(browser, f"params-status-{KEY}").startswith("/rec1/detector ("),
                 what="the layout's node chosen", alive=alive)
        wait_for(lambda: "threshold" in _text(browser, f"params-{KEY}"),
                 what="the recorded parameter", alive=alive)
        assert _disabled(by_testid(browser, f"param-{KEY}-threshold"))
        # The camera's JPEG quality: a log's cannot be set.
        wait_for(lambda: "recorded: not live" in _text(browser, f"image-quality-note-{KEY}"),
                 what="the image view's not-live note", alive=alive)
        assert _disabled(by_testid(browser, f"image-quality-set-{KEY}"))
        assert "Traceback" not in server.output()
