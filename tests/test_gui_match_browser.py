"""Issue 19, point 8: ``scripts/gui_demo.sh`` watches the team match. The demo as a user
types it (``python -m debug_gui.demo --robots 1v1 --lockstep``), seen in a browser: the
match's robots by name, each one's components, and the world view with both robots on one
field in their teams' colours, their roles, and the referee's game state and score."""

from __future__ import annotations

import re
import signal
import sys
from collections.abc import Callable
from functools import partial
from pathlib import Path
from typing import Any

import pytest

from efficient_comm.testing import isolated_domain_id, ros_env

from ._gui import Process, screenshot, started, text_of, wait_for

_WATCH = re.compile(r"soccer match: debug_gui --domains (\d+),(\d+) watches")
_GAME = re.compile(r"game: (initial|ready|set|playing), 1st half, blue 0 : 0 red")


def _robots_drawn(browser: Any) -> dict[str, dict[str, str]]:
    """Every robot the world view draws, with its attributes, read at once (the drawing is
    replaced at the display rate)."""
    return browser.execute_script(  # type: ignore[no-any-return]
        "const out = {};"
        "for (const g of document.querySelectorAll(\"[data-testid^='world-robot-']\"))"
        "  out[g.dataset.testid.slice(12)] = {team: g.dataset.team, role: g.dataset.role,"
        "    colour: g.dataset.colour, source: g.dataset.source};"
        "return out;")


def _seen_once_each(checks: dict[str, Callable[[], Any]], *, timeout_s: float,
                    alive: list[Process]) -> dict[str, Any]:
    """Poll every check until each has held once (what it returned, by name): a live match
    shows one thing now and another later, the page is not asked for all at one moment."""
    seen: dict[str, Any] = {}

    def every_one() -> bool:
        for name, check in checks.items():
            if name not in seen and (value := check()):
                seen[name] = value
        return len(seen) == len(checks)

    try:
        wait_for(every_one, timeout_s=timeout_s, what="the match on the page", alive=alive)
    except pytest.fail.Exception as exc:
        missing = ", ".join(name for name in checks if name not in seen)
        pytest.fail(f"never shown: {missing}\n{exc}")
    return seen


# The demo with a real 1v1 match: a world and two robot processes, the GUI and chromium
# share two cores; the robots' pipelines start in turn. In lockstep, so what the page must
# show costs the same simulated time however loaded the machine is (in real time the match
# ran, rendered and was watched for 200 s of a loaded full run, 266 s of CPU).
@pytest.mark.timeout(300)
def test_gui_demo_watches_a_match_robots_by_name_game_state_and_both_on_one_field(
    tmp_path: Path, browser
) -> None:
    log = tmp_path / "demo.log"
    cmd = [sys.executable, "-m", "debug_gui.demo", "--robots", "1v1", "--lockstep", "--port",
           "0", "--camera-hz", "10", "--out-dir", "match", "--report", "match/report.md"]
    with started(cmd, env=ros_env(isolated_domain_id()), log=log) as proc:
        demo = Process(proc=proc, log=log)
        url = wait_for(lambda: re.search(r"at (http://\S+)", demo.output()), timeout_s=90,
                       what="the URL", alive=[demo]).group(1)
        blue, red = (int(d) for d in _WATCH.search(demo.output()).groups())  # type: ignore[union-attr]
        assert f"serving robots of domain(s) {blue}, {red} at" in demo.output()
        browser.set_window_size(1600, 1200)
        browser.get(url)
        keys = {f"{blue}:/blue1": "blue", f"{red}:/red1": "red"}
        checks: dict[str, Callable[[], Any]] = {}
        for key in keys:
            domain, name = key.split(":/")
            # The robot by name in the header, its components filling with its callbacks.
            checks[f"{name} in the header"] = partial(
                lambda key, label: label in text_of(browser, f"robot-{key}"),
                key, f"{name} @ domain {domain}")
            checks[f"{name}'s components"] = partial(
                lambda key: "ball_detector" in text_of(browser, f"components-{key}"), key)
        # The referee's state and score, as the robots received it.
        checks["the game state and score"] = lambda: _GAME.search(
            text_of(browser, "world-game-team"))
        # Both robots on the one field with their roles, placed by their localization. Until
        # a robot's first localized pose arrives the view places it by odometry (a robot whose
        # pipeline starts late under load), so the localization is awaited, not assumed.
        checks["both robots drawn with their roles by their localization"] = lambda: (
            (d := _robots_drawn(browser)) and set(keys) <= set(d)
            and all(d[k]["role"] and d[k]["source"] == "localization" for k in keys) and d)
        # Not awaited: a ball some robot believes in. Whether a robot sees the ball is the
        # robots' play (on a loaded machine they started late, fell at kick-off and saw none
        # for minutes); tests/test_gui_world_model.py draws beliefs from given messages.
        seen = _seen_once_each(checks, timeout_s=200, alive=[demo])
        drawn = seen["both robots drawn with their roles by their localization"]
        assert {k: drawn[k]["team"] for k in keys} == keys, drawn
        assert drawn[f"{blue}:/blue1"]["colour"] != drawn[f"{red}:/red1"]["colour"], drawn
        screenshot(browser, "debug_gui_match")
        # Stopping the demo stops the match, which reports as when it is stopped by Ctrl-C.
        proc.send_signal(signal.SIGTERM)
        assert proc.wait(timeout=120) == 0, demo.output()[-3000:]
    assert "# Team match report" in demo.output()
    assert (tmp_path / "match" / "report.md").exists()
