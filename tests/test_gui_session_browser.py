"""One chromium for the session (tests/_gui.py): each browser test gets it reset.

Starting chromium and its driver costs seconds, so the browser tests share one; what one
test leaves (cookies, storage, extra tabs, another window size) must not reach the next.
"""

from __future__ import annotations

import http.server
import threading
from collections.abc import Iterator
from typing import Any

import pytest

from ._gui import WINDOW_SIZE, fresh_browser, reset_browser


class _Page(http.server.BaseHTTPRequestHandler):
    def do_GET(self) -> None:
        body = b"<html><body>page</body></html>"
        self.send_response(200)
        self.send_header("Content-Type", "text/html")
        self.send_header("Content-Length", str(len(body)))
        self.end_headers()
        self.wfile.write(body)

    def log_message(self, *args: Any) -> None:
        pass


@pytest.fixture
def page_url() -> Iterator[str]:
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), _Page)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        yield f"http://127.0.0.1:{server.server_address[1]}/"
    finally:
        server.shutdown()
        server.server_close()


def test_the_session_browser_is_reused_and_left_clean(
    chromium_session: list[Any], page_url: str
) -> None:
    driver = fresh_browser(chromium_session)
    driver.get(page_url)
    driver.add_cookie({"name": "left", "value": "over"})
    driver.execute_script("window.localStorage.setItem('left', 'over')")
    driver.set_window_size(800, 600)
    driver.switch_to.new_window("tab")
    assert len(driver.window_handles) == 2

    reset_browser(driver, chromium_session)

    again = fresh_browser(chromium_session)
    assert again.session_id == driver.session_id  # the same chromium, not a new one
    assert len(again.window_handles) == 1
    assert tuple(again.get_window_size().values()) == WINDOW_SIZE
    again.get(page_url)
    assert again.get_cookies() == []
    assert again.execute_script("return window.localStorage.getItem('left')") is None


def test_a_browser_that_no_longer_answers_is_replaced(chromium_session: list[Any]) -> None:
    driver = fresh_browser(chromium_session)
    driver.quit()  # as a test that crashed chromium would leave it
    again = fresh_browser(chromium_session)
    assert again.session_id != driver.session_id
    assert again.current_window_handle
