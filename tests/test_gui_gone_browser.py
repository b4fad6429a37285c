"""A robot that goes: its image view stops saying "live" (headless chromium)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from efficient_comm.testing import isolated_domain_id

from ._gui import by_testid, fake_robot, gui, wait_for, wait_for_text


def test_a_gone_robots_image_view_says_so_and_cannot_set(tmp_path: Path, browser: Any) -> None:
    domain = isolated_domain_id()
    layout = tmp_path / "layout.json"
    # Bound to the robot (a team panel drops a robot that goes).
    layout.write_text(json.dumps({"version": 1, "panels": [{"kind": "image", "robot": {
        "domain": domain, "namespace": "/gone", "via": "dds"}}]}))
    key = f"{domain}:/gone"
    with gui(tmp_path, domains=[domain], args=["--layout", str(layout)]) as server:
        with fake_robot(tmp_path, domain_id=domain, namespace="/gone") as proc:
            browser.get(server.url)
            wait_for_text(browser, "no camera;", alive=[proc, server])  # a robot, no camera
        wait_for_text(browser, "robot gone: its last frame", alive=[server], timeout_s=60)
        assert "no camera" not in by_testid(browser, f"image-status-{key}").text
        button = by_testid(browser, f"image-quality-set-{key}")
        wait_for(lambda: not button.is_enabled() or "disabled" in (
            button.get_attribute("class") or ""), what="SET disabled", alive=[server])
