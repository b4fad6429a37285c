"""The components view in a real browser: live rows per robot, robots told apart."""

from __future__ import annotations

from pathlib import Path

from selenium.common.exceptions import StaleElementReferenceException
from selenium.webdriver.common.by import By

from debug_gui.ui.components import ALL
from efficient_comm.testing import isolated_domain_id

from ._gui import by_testid, click, fake_robot, gui, screenshot, text_of, wait_for, wait_for_text


def test_components_view_shows_live_rows_of_each_robot_and_flags_slow_ones(
    tmp_path: Path, browser
) -> None:
    """Two robots in two domains: each one's table shows its own callbacks, updating."""
    d1, d2 = isolated_domain_id(), isolated_domain_id()
    with fake_robot(tmp_path, domain_id=d1, namespace="/alpha") as a, \
            fake_robot(tmp_path, domain_id=d2, namespace="/beta") as b, \
            gui(tmp_path, domains=[d1, d2]) as server:
        browser.get(server.url)
        alive = [a, b, server]
        wait_for_text(browser, f"alpha @ domain {d1}", alive=alive)
        wait_for_text(browser, f"beta @ domain {d2}", alive=alive)
        table_a, table_b = f"components-{d1}:/alpha", f"components-{d2}:/beta"
        text_a = wait_for(lambda: "alpha_component0" in text_of(browser, table_a)
                          and text_of(browser, table_a), what="alpha's rows", alive=alive)
        text_b = wait_for(lambda: "beta_component0" in text_of(browser, table_b)
                          and text_of(browser, table_b), what="beta's rows", alive=alive)
        # Each robot's view shows its own data only.
        assert "beta_" not in text_a and "alpha_" not in text_b
        # The slow timer (p95 60 ms over a 50 ms period) is flagged, the others are not.
        assert text_a.count("over period") == 1, text_a
        # Live: the cumulative call count of component0 grows (a column shown on demand).
        click(browser, f"components-columns-{d1}:/alpha")
        first = _calls(browser, table_a, "alpha_component0")
        wait_for(lambda: _calls(browser, table_a, "alpha_component0") > first >= 0,
                 what="the calls to grow", alive=alive)
        screenshot(browser, "components_two_robots")


def _calls(browser, testid: str, node: str) -> int:
    """The calls column of ``node``'s row in the table ``testid`` (-1: no such row)."""
    calls = ALL.index("calls")
    try:
        for tr in by_testid(browser, testid).find_elements(By.CSS_SELECTOR, "tbody tr"):
            cells = [td.get_attribute("textContent").strip()
                     for td in tr.find_elements(By.TAG_NAME, "td")]
            if node in cells:
                return int(cells[calls])
    except (StaleElementReferenceException, ValueError, IndexError):
        pass  # the table was re-rendered while being read
    return -1
