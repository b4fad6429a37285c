"""The image view in a real browser against a robot: frames advance, overlays match.

The robot is the light one with the real ball detector and JPEG compressor behind a drawn
camera (tests/_gui_camera_robot.py); tests/test_gui_demo_browser.py runs the full demo.

The frame rate the browser reaches is measured by bench/image_view_bench.py (a figure, not
an assertion); here: frames keep coming, each overlay is its frame's (same stamp), layers
switch off, pause holds the picture and step moves through older frames, and a collapsed
view leaves no subscriber on the robot.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from selenium.webdriver.common.by import By

from debug_gui import RobotId
from efficient_comm.testing import isolated_domain_id

from ._gui import by_testid, camera_robot, gui, screenshot, text_of, wait_for
from .test_gui_hub_data import plain_robot
from .test_gui_image_data import graph, view_readers

#: What the image view's page script exposes: (frames drawn, frame stamp, overlay stamp,
#: SVG elements, text elements) of the first image view on the page.
_STATE = """
const root = document.querySelector('[id^="dbgimg-"]');
if (!root || !root.dataset.frames) return null;
const svg = root.querySelector('svg');
return [Number(root.dataset.frames), root.dataset.stamp, root.dataset.overlayStamp,
        svg.children.length, svg.querySelectorAll('text').length];
"""


#: Whether the image view's <img> is displayed (it is not before its first picture).
_SHOWN = """
const img = document.querySelector(`[data-testid="${arguments[0]}"] img`);
return !!img && img.offsetParent !== null;
"""


def image_state(driver: Any) -> tuple[int, str, str, int, int] | None:
    state = driver.execute_script(_STATE)
    return tuple(state) if state else None


def image_layout(path: Path) -> Path:
    """A layout file with one image view for every robot."""
    path.write_text(json.dumps({"version": 1, "panels": [{"kind": "image", "team": True}]}))
    return path


def test_image_view_shows_frames_with_their_own_overlays_layers_pause_and_step(
    tmp_path: Path, browser
) -> None:
    domain = isolated_domain_id()
    layout = image_layout(tmp_path / "layout.json")
    with camera_robot(tmp_path, domain_id=domain, namespace="/robot") as bot, \
            gui(tmp_path, domains=[domain], args=["--layout", str(layout)]) as server:
        alive = [bot, server]
        browser.get(server.url)
        first = wait_for(lambda: (s := image_state(browser)) and s[0] >= 3 and s,
                         what="frames in the page", alive=alive, timeout_s=60)
        # Frames advance, and every one drawn came with the overlay of its own stamp.
        later = wait_for(lambda: (s := image_state(browser)) and s[0] >= first[0] + 10 and s,
                         what="frames to advance", alive=alive)
        assert later[1] != first[1]
        for _ in range(20):
            _n, stamp, overlay, _elements, _texts = image_state(browser) or (0, "", "", 0, 0)
            if overlay:
                assert overlay == stamp, (stamp, overlay)
        wait_for(lambda: (s := image_state(browser)) and s[2] == s[1] and s[3] > 0,
                 what="a frame with its overlay drawn", alive=alive)
        # The picture, no longer the text that stood in for it before the first frame.
        assert browser.execute_script(_SHOWN, f"image-{domain}:/robot")
        wait_for(lambda: not by_testid(browser, f"image-placeholder-{domain}:/robot")
                 .is_displayed(), what="the placeholder gone", alive=alive)
        screenshot(browser, "image_view_live")

        # A layer switched off leaves the overlay.
        wait_for(lambda: (s := image_state(browser)) and s[4] > 0, what="the internals' text",
                 alive=alive)
        key = f"{domain}:/robot"
        box = by_testid(browser, f"image-layer-{key}-internals")
        box.click()
        wait_for(lambda: (s := image_state(browser)) and s[4] == 0 and s[3] > 0,
                 what="text gone, shapes kept", alive=alive)

        # Pause holds the picture; step shows the previous buffered frame with its overlay.
        by_testid(browser, f"image-pause-{key}").click()
        wait_for(lambda: "paused at frame" in by_testid(
            browser, f"image-status-{key}").text, what="paused", alive=alive)
        held = image_state(browser)
        assert held is not None
        by_testid(browser, f"image-prev-{key}").click()
        stepped = wait_for(lambda: (s := image_state(browser)) and s[1] != held[1] and s,
                           what="the previous frame", alive=alive)
        assert int(stepped[1]) < int(held[1])  # an older frame
        assert stepped[2] in (stepped[1], "")  # its own overlay (or none)
        still = image_state(browser)
        assert still is not None and still[0] == stepped[0]  # paused: nothing new drawn
        screenshot(browser, "image_view_paused")

        # Live again; then collapsed (hidden): the view leaves no reader on the robot.
        by_testid(browser, f"image-pause-{key}").click()
        robot_id = RobotId(domain, "/robot")
        with graph(domain) as node:
            # Exactly this page's view (the fixture's check that the page answers fetched
            # one too, with no browser: that one must not subscribe).
            wait_for(lambda: view_readers(node, robot_id) == 2, what="the view's readers",
                     alive=alive)
            by_testid(browser, "panel-0").find_element(By.CSS_SELECTOR, ".q-item").click()
            wait_for(lambda: view_readers(node, robot_id) == 0, what="no reader when hidden",
                     alive=alive)


#: Whether the image view's picture shows nothing as an image (a broken-image icon): its
#: <img> is displayed without a picture.
_BROKEN = """
const img = document.querySelector(`[data-testid="${arguments[0]}"] img`);
return !!img && img.offsetParent !== null && !(img.complete && img.naturalWidth > 0);
"""


def test_a_robot_without_a_camera_says_so_instead_of_a_broken_image(
    tmp_path: Path, browser
) -> None:
    """Issue 18, 4g: a plain ROS 2 robot's image view says it has no image topic."""
    domain = isolated_domain_id()
    key = f"{domain}:/plainbot"
    layout = image_layout(tmp_path / "layout.json")
    with plain_robot(tmp_path, domain_id=domain, namespace="/plainbot") as bot, \
            gui(tmp_path, domains=[domain],
                args=["--layout", str(layout), "--plain-robots"]) as server:
        alive = [bot, server]
        browser.get(server.url)
        wait_for(lambda: "no image topic: this robot publishes no "
                 "/plainbot/camera/image_raw/compressed"
                 in text_of(browser, f"image-placeholder-{key}"),
                 what="the view saying there is no image topic", alive=alive, timeout_s=60)
        wait_for(lambda: text_of(browser, f"image-status-{key}").startswith("no camera;"),
                 what="the status line saying there is no camera", alive=alive)
        assert not browser.execute_script(_BROKEN, f"image-{key}")
        screenshot(browser, "image_view_no_camera")
