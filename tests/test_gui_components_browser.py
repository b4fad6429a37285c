"""The components view in a real browser: live rows per robot, robots told apart."""

from __future__ import annotations

import functools
from pathlib import Path

from selenium.common.exceptions import StaleElementReferenceException
from selenium.webdriver.common.by import By

from debug_gui.ui.components import ALL, COMPACT
from efficient_comm.testing import isolated_domain_id

from ._gui import (
    by_testid,
    choose,
    click,
    fake_robot,
    gui,
    screenshot,
    text_of,
    wait_for,
    wait_for_text,
)


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
        first = wait_for(lambda: _calls(browser, table_a, "alpha_component0") + 1,
                         what="the calls column", alive=alive) - 1
        # Only changed cells are updated: the cell of a name that stays is the same element
        # after the figures changed twice (issue 18: every slotted cell of every table was
        # re-created at each update, which kept the browser's main thread busy).
        assert browser.execute_script(_MARK, table_a, "alpha_component0")
        second = wait_for(lambda: max(0, _calls(browser, table_a, "alpha_component0") - first),
                          what="the calls to grow", alive=alive) + first
        wait_for(lambda: _calls(browser, table_a, "alpha_component0") > second,
                 what="the calls to grow again", alive=alive)
        assert browser.execute_script(_MARKED, table_a), "the unchanged cell was re-created"
        # Sortable: a click on "component" orders beta's rows by name (they come by p95).
        header = by_testid(browser, table_b).find_element(
            By.XPATH, ".//th[contains(., 'component')]")
        header.click()
        wait_for(lambda: _column(browser, table_b, "node") == [
            "beta_component0", "beta_component1", "beta_component2"], what="sorted rows",
            alive=alive)
        header.click()
        wait_for(lambda: _column(browser, table_b, "node") == [
            "beta_component2", "beta_component1", "beta_component0"], what="reversed rows",
            alive=alive)
        screenshot(browser, "components_two_robots")



def test_changing_figures_and_status_line_send_no_element_update(
    tmp_path: Path, browser
) -> None:
    """Issue 18, 4a: a NiceGUI element update re-renders the page's whole Vue tree and lays
    out the page; the components view's figures and its status line (which changes as
    callbacks go over their period and back) change through the table's own messages, so
    none is sent while they change."""
    domain = isolated_domain_id()
    key = f"{domain}:/robot1"
    with fake_robot(tmp_path, domain_id=domain, namespace="/robot1", period_s=1.0,
                    callbacks=40) as robot, gui(tmp_path, domains=[domain]) as server:
        alive = [robot, server]
        browser.get(server.url)
        status = f"components-status-{key}"
        wait_for(lambda: "callbacks" in text_of(browser, status), what="the status line",
                 alive=alive)
        browser.execute_script(_COUNT_MESSAGES)
        seen = {text_of(browser, status)}

        def status_changed() -> bool:
            seen.add(text_of(browser, status))
            counts = browser.execute_script("return window.__issue18")
            return len(seen) >= 2 and counts["other"] >= 2

        wait_for(status_changed, what="the status line to change", alive=alive,
                 timeout_s=90)
        assert browser.execute_script("return window.__issue18")["update"] == 0, seen


def test_rows_out_of_sight_are_drawn_when_they_come_into_sight(tmp_path: Path, browser) -> None:
    """Issue 18, 4a: a row below the window keeps its figures undrawn (most rows of three
    robots' tables are, and drawing them kept a loaded machine's browser busy) and shows
    the current ones as soon as it is scrolled into sight."""
    domain = isolated_domain_id()
    key = f"{domain}:/robot1"
    table = f"components-{key}"
    with fake_robot(tmp_path, domain_id=domain, namespace="/robot1", period_s=0.5,
                    callbacks=60) as robot, gui(tmp_path, domains=[domain]) as server:
        alive = [robot, server]
        browser.get(server.url)
        wait_for(lambda: (browser.execute_script(_ENDS, table) or [0, 0, 0])[2] == 60,
                 what="60 rows", alive=alive)
        click(browser, f"components-columns-{key}")
        by_testid(browser, table).find_element(
            By.XPATH, ".//th[contains(., 'component')]").click()  # a steady order: by name
        calls = ALL.index("calls")

        def ends() -> tuple[int, int, bool]:
            first, last, _, below = browser.execute_script(_ENDS, table)
            try:
                return int(first[calls]), int(last[calls]), below
            except (ValueError, IndexError):
                return -1, -1, below

        top0, bottom0, below = wait_for(lambda: (e := ends())[0] > 0 and e,
                                        what="the calls column", alive=alive)
        assert below, "the last row is in sight: the window shows the whole table"
        wait_for(lambda: ends()[0] > top0, what="the first row's calls to grow", alive=alive)
        top1 = ends()[0]
        wait_for(lambda: ends()[0] > top1, what="the first row's calls to grow again",
                 alive=alive)
        assert ends()[1] == bottom0, "a row out of sight was drawn again"
        browser.execute_script(_SHOW_LAST, table)
        wait_for(lambda: ends()[1] > bottom0, what="the last row's current calls",
                 alive=alive)


#: The first and the last row's cell texts of table ``arguments[0]``, the number of rows
#: and whether the last one is below the window.
_ENDS = """
const rows = [...document.querySelectorAll('[data-testid="' + arguments[0] + '"] tbody tr')];
if (!rows.length) return [[], [], 0, false];
const cells = (tr) => [...tr.querySelectorAll('td')].map(td => td.textContent.trim());
const last = rows[rows.length - 1];
return [cells(rows[0]), cells(last), rows.length,
        last.getBoundingClientRect().top > window.innerHeight + 300];
"""
_SHOW_LAST = """
const rows = document.querySelectorAll('[data-testid="' + arguments[0] + '"] tbody tr');
rows[rows.length - 1].scrollIntoView();
"""


#: Counts the server's messages to the page: element updates and the others.
_COUNT_MESSAGES = """
window.__issue18 = {update: 0, other: 0};
window.socket.onAny((event) => { window.__issue18[event === 'update' ? 'update' : 'other']++; });
"""

#: Marks the cell showing ``name`` in table ``testid`` (a JS property: not in the markup, so
#: only the same element still has it); True when there was one.
_MARK = """
const cell = [...document.querySelectorAll('[data-testid="' + arguments[0] + '"] tbody td')]
  .find(td => td.textContent.trim() === arguments[1]);
if (cell) cell.__issue18 = true;
return Boolean(cell);
"""
_MARKED = """
return [...document.querySelectorAll('[data-testid="' + arguments[0] + '"] tbody td')]
  .some(td => td.__issue18 === true);
"""


def _column(browser, testid: str, name: str) -> list[str]:
    """The cells of the compact table's column ``name``, top to bottom."""
    index = COMPACT.index(name)
    try:
        return [tr.find_elements(By.TAG_NAME, "td")[index].get_attribute("textContent").strip()
                for tr in by_testid(browser, testid).find_elements(By.CSS_SELECTOR,
                                                                   "tbody tr")]
    except (StaleElementReferenceException, IndexError):
        return []


def _calls(browser, testid: str, node: str) -> int:
    """The calls column of ``node``'s row in the table ``testid`` (-1: no such row), read
    in one script (cell by cell over WebDriver, a table re-rendered meanwhile is stale)."""
    cells = browser.execute_script(_ROW, testid, node)
    try:
        return int(cells[ALL.index("calls")]) if cells else -1
    except (ValueError, IndexError):
        return -1


#: The cells' texts of the row of table ``arguments[0]`` that shows ``arguments[1]``.
_ROW = """
for (const tr of document.querySelectorAll('[data-testid="' + arguments[0] + '"] tbody tr')) {
  const cells = [...tr.querySelectorAll('td')].map(td => td.textContent.trim());
  if (cells.includes(arguments[1])) return cells;
}
return null;
"""


#: What is cut off in the window: elements of the given test ids that reach beyond it, and
#: tables in them whose columns do not fit (hidden behind their own scroll bar).
_CUT_OFF = """
const out = [], width = window.innerWidth;
if (document.documentElement.scrollWidth > width)
  out.push('the page scrolls sideways: ' + document.documentElement.scrollWidth);
for (const testid of arguments[0]) {
  const el = document.querySelector(`[data-testid="${testid}"]`);
  if (!el) { out.push(testid + ' missing'); continue; }
  const box = el.getBoundingClientRect();
  if (box.left < 0 || box.right > width) out.push(`${testid} at ${box.left}..${box.right}`);
  for (const table of el.querySelectorAll('.q-table__middle'))
    if (table.scrollWidth > table.clientWidth)
      out.push(`${testid}: table ${table.scrollWidth} wide in ${table.clientWidth}`);
}
return out;
"""


def test_team_views_of_three_robots_fit_the_window_at_1600_and_1280_px(
    tmp_path: Path, browser
) -> None:
    """Issue 18, 4g: at 1600 px and at 1280x720 every robot of a three-robot team, its
    components' figures (mean, p95, max), its recorder's buttons and topic types are in
    the window, not cut off or behind a scroll bar."""
    from .test_gui_recorder_browser import _press
    from .test_gui_recorder_data import recorder_robot

    domain = isolated_domain_id()
    names = ("/robot1", "/robot2", "/robot3")
    with recorder_robot(tmp_path, domain_id=domain, namespace=names[0]) as r1, \
            recorder_robot(tmp_path, domain_id=domain, namespace=names[1]) as r2, \
            recorder_robot(tmp_path, domain_id=domain, namespace=names[2]) as r3, \
            gui(tmp_path, domains=[domain]) as server:
        alive = [r1, r2, r3, server]
        keys = [f"{domain}:{name}" for name in names]
        browser.get(server.url)
        wait_for(lambda: all("talker" in text_of(browser, f"components-{k}") for k in keys),
                 what="every robot's components", alive=alive, timeout_s=60)
        choose(browser, "add-kind", "Recorder")
        click(browser, "add-view")
        recorders = [f"{key}-recorder" for key in keys]
        wait_for(lambda: all(text_of(browser, f"recorder-state-{r}") == "idle"
                             for r in recorders), what="every recorder's status", alive=alive,
                 timeout_s=60)
        _press(browser, "recorder-start-all")  # the longest lines: bags, recorded topics
        wait_for(lambda: all("chatter" in text_of(browser, f"recorder-topics-{r}")
                             and "file" in text_of(browser, f"recorder-bag-{r}")
                             for r in recorders), what="every recorder recording", alive=alive)
        wanted = [f"components-{key}" for key in keys] + [
            testid for recorder in recorders for testid in (
                f"recorder-{recorder}", f"recorder-split-{recorder}",
                f"recorder-snapshot-{recorder}", f"recorder-topics-{recorder}")]
        for width, height in ((1600, 1000), (1280, 720)):
            browser.set_window_size(width, height)
            wait_for(functools.partial(_window_is, browser, width),
                     what=f"a window {width} px wide")
            screenshot(browser, f"team_views_{width}")
            assert browser.execute_script(_CUT_OFF, wanted) == [], width
            browser.execute_script("arguments[0].scrollIntoView()",
                                   by_testid(browser, f"recorder-{recorders[0]}"))
            screenshot(browser, f"team_views_{width}_recorder")
            for key in keys:  # the figures' headings themselves, in the window
                headings = by_testid(browser, f"components-{key}").find_elements(
                    By.CSS_SELECTOR, "th")
                shown = [" ".join(th.text.split()) for th in headings if th.is_displayed()
                         and th.rect["x"] + th.rect["width"] <= width]
                for figure in ("mean ms", "p95 ms", "max ms"):
                    assert any(figure in text for text in shown), (width, figure, shown)


def _window_is(browser, width: int) -> bool:
    return bool(browser.execute_script("return window.innerWidth") == width)
