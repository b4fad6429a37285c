"""The recorder view in a real browser against a running simulated robot: a recording
started and stopped by clicks writes a bag (read back here); the page shows the bytes
growing; "start all robots" records the team; a page without the token cannot."""

from __future__ import annotations

import re
from pathlib import Path

from selenium.webdriver.common.by import By
from selenium.webdriver.common.keys import Keys

from efficient_comm.testing import isolated_domain_id
from robot_recorder import read_messages

from ._gui import (
    by_testid,
    choose,
    click,
    gui,
    robot,
    screenshot,
    text_of,
    wait_for,
    wait_for_text,
)

_BYTES = re.compile(r"([\d,]+) bytes")


def _bytes(browser, testid: str) -> int:
    match = _BYTES.search(text_of(browser, testid))
    return int(match.group(1).replace(",", "")) if match else -1


def _count(bag: Path) -> dict[str, int]:
    counts: dict[str, int] = {}
    for message in read_messages(bag):
        counts[message.topic] = counts.get(message.topic, 0) + 1
    return counts


def _press(browser, testid: str) -> None:
    """Click ``testid`` in the middle of the screen (scrolled to the top edge, the page's
    fixed header would be over it)."""
    element = by_testid(browser, testid)
    browser.execute_script("arguments[0].scrollIntoView({block: 'center'})", element)
    element.click()


def _ticked(browser, testid: str) -> bool:
    try:
        return bool(by_testid(browser, testid).get_attribute("aria-checked") == "true")
    except Exception:  # not rendered (yet)
        return False


def _add_recorder_view(browser, alive) -> None:
    """What the KLM scenario does: view select > Recorder, add (robot: the team)."""
    choose(browser, "add-kind", "Recorder")
    click(browser, "add-view")
    wait_for(lambda: "start all robots" in text_of(browser, "panel-1").lower(),
             what="the recorder view", alive=alive)


def test_a_recording_started_in_the_browser_writes_a_bag(tmp_path: Path, browser) -> None:
    domain = isolated_domain_id()
    bags = tmp_path / "bags"
    with robot(tmp_path, domain_id=domain, namespace="/rb",
               args=["--bag-dir", str(bags)]) as sim, \
            gui(tmp_path, domains=[domain]) as server:
        alive = [sim, server]
        key = f"{domain}:/rb-recorder"
        browser.get(server.url)
        wait_for_text(browser, f"rb @ domain {domain}", timeout_s=90, alive=alive)
        _add_recorder_view(browser, alive)
        wait_for(lambda: text_of(browser, f"recorder-state-{key}") == "idle", timeout_s=60,
                 what="the recorder's status", alive=alive)

        # Start into a bag named here, watch the bytes grow, stop.
        bag = bags / "from_the_browser"
        field = by_testid(browser, f"recorder-bagname-{key}")
        if field.tag_name != "input":  # Quasar puts the attributes on the native input
            field = field.find_element(By.TAG_NAME, "input")
        field.send_keys(str(bag))
        _press(browser, f"recorder-start-{key}")
        wait_for(lambda: "recording into" in text_of(browser, f"recorder-result-{key}"),
                 what="the start answer", alive=alive)
        wait_for(lambda: text_of(browser, f"recorder-state-{key}") == "recording",
                 what="recording", alive=alive)
        first = wait_for(lambda: max(0, _bytes(browser, f"recorder-figures-{key}")),
                         what="bytes on the page", alive=alive)
        wait_for(lambda: _bytes(browser, f"recorder-figures-{key}") > first,
                 what="the bytes to grow", alive=alive)
        wait_for(lambda: "/rb/" not in text_of(browser, f"recorder-topics-{key}")
                 and "joint_states" in text_of(browser, f"recorder-topics-{key}"),
                 what="the recorded topics", alive=alive)
        screenshot(browser, "recorder_view_recording")
        _press(browser, f"recorder-stop-{key}")
        wait_for(lambda: "stopped, bag" in text_of(browser, f"recorder-result-{key}"),
                 what="the stop answer", alive=alive)
        wait_for(lambda: text_of(browser, f"recorder-state-{key}") == "idle",
                 what="idle again", alive=alive)
        counts = _count(bag)
        assert (bag / "metadata.yaml").is_file()
        assert counts.get("/rb/joint_states", 0) > 0, counts
        assert sum(counts.values()) > 0

        # The topic selection editor: the robot's topics, ticked as recorded; a bad option
        # is refused with robot_recorder's reason; a newly ticked topic is recorded.
        _press(browser, f"recorder-editor-{key}")
        wait_for(lambda: _ticked(browser, f"recorder-pick-{key}-joint_states"),
                 what="joint_states ticked", alive=alive)
        stats = f"recorder-pick-{key}-efficient_comm/stats"
        assert not _ticked(browser, stats)
        entries = by_testid(browser, f"recorder-entries-{key}")
        if entries.tag_name != "textarea":
            entries = entries.find_element(By.TAG_NAME, "textarea")
        entries.send_keys("fall/state every_nth=2.5")
        _press(browser, f"recorder-apply-{key}")
        wait_for(lambda: "every_nth has an invalid value '2.5'"
                 in text_of(browser, f"recorder-result-{key}"), what="the refusal",
                 alive=alive)
        entries.send_keys(Keys.CONTROL, "a")  # clear() would bypass the page's input event
        entries.send_keys(Keys.DELETE)
        _press(browser, stats)
        _press(browser, f"recorder-apply-{key}")
        wait_for(lambda: "topic selection applied" in text_of(browser, f"recorder-result-{key}"),
                 what="the selection applied", alive=alive)
        wait_for(lambda: "efficient_comm/stats" in text_of(
            browser, f"recorder-topics-{key}").split(), what="the stats recorded", alive=alive)

        # The KLM scenario: one click records every robot of the team.
        before = set(bags.iterdir())
        _press(browser, "recorder-start-all")
        wait_for(lambda: "recording into" in text_of(browser, "recorder-all-result"),
                 what="start all robots", alive=alive)
        wait_for(lambda: text_of(browser, f"recorder-state-{key}") == "recording",
                 what="recording", alive=alive)
        _press(browser, "recorder-stop-all")
        wait_for(lambda: "stopped, bag" in text_of(browser, "recorder-all-result"),
                 what="stop all robots", alive=alive)
        (team_bag,) = set(bags.iterdir()) - before
        assert text_of(browser, "recorder-all-result") == (
            f"rb @ domain {domain} recorder: stopped, bag {team_bag}")
        assert sum(_count(team_bag).values()) > 0

        # Without the token: the controls are disabled, and nothing can start. Another
        # tab: this one would come back with its own working layout.
        browser.switch_to.new_window("tab")
        browser.get(server.base_url)
        wait_for_text(browser, "read-only", alive=alive)
        _add_recorder_view(browser, alive)
        wait_for(lambda: text_of(browser, f"recorder-state-{key}") == "idle",
                 what="the status, read-only", alive=alive)
        for testid in (f"recorder-start-{key}", f"recorder-stop-{key}", "recorder-start-all",
                       f"recorder-apply-{key}"):
            assert by_testid(browser, testid).get_attribute("disabled") is not None, testid
        screenshot(browser, "recorder_view_read_only")
        assert set(bags.iterdir()) - before == {team_bag}
