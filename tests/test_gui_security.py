"""debug_gui's security (issue 12, point 7) and bad command lines, as a user meets them."""

from __future__ import annotations

import socket
import subprocess
import sys
from pathlib import Path

import pytest

from efficient_comm.testing import isolated_domain_id, ros_env

from ._gui import choose, click, fake_robot, gui, present, wait_for, wait_for_text


def _run(*args: str, timeout_s: float = 60.0) -> subprocess.CompletedProcess[str]:
    return subprocess.run(["ros2", "run", "debug_gui", "debug_gui", *args],
                          env=ros_env(isolated_domain_id()), capture_output=True, text=True,
                          timeout=timeout_s)


def test_serving_beyond_loopback_without_a_token_refuses_to_start() -> None:
    result = _run("--host", "0.0.0.0", "--port", "0")
    assert result.returncode == 2
    assert result.stderr.strip().splitlines() == [
        "debug_gui: error: --host 0.0.0.0 serves beyond this machine: give --token TOKEN too "
        "(writes and pages then need it)"
    ], result.stderr


@pytest.mark.parametrize(("args", "error"), [
    (["--domains", "0,x"], "domains are comma-separated integers"),
    (["--domains", "999"], "domain id is an integer 0..232"),
    (["--port", "70000"], "port is an integer 0..65535"),
    (["--token", "short"], "a token is 8 to 128 characters"),
    (["--foxglove-port", "-1"], "port is an integer"),
    (["--domains", "0", "--team-link-domains", "0"],
     "domain 0 is in both --domains and --team-link-domains: name each domain once"),
])
def test_bad_options_end_in_one_line(args: list[str], error: str) -> None:
    result = _run(*args)
    assert result.returncode == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and error in lines[0] and "Traceback" not in result.stderr, lines


def test_a_bad_layout_file_and_a_busy_port_end_in_one_line(tmp_path: Path) -> None:
    layout = tmp_path / "layout.json"
    layout.write_text('{"version": 1, "panels": [{"kind": "nosuch", "team": true}]}')
    result = _run("--port", "0", "--layout", str(layout))
    assert result.returncode == 2 and "Traceback" not in result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(
        f"debug_gui: error: {layout}: panel 1: no view kind 'nosuch' here (known: "
    ), lines
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        result = _run("--port", str(busy.getsockname()[1]))
    assert result.returncode == 2 and "Traceback" not in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1
    assert "cannot serve on 127.0.0.1:" in result.stderr, result.stderr


def test_a_layout_file_that_cannot_be_written_is_refused_at_start(tmp_path: Path) -> None:
    """Not only at the first "save layout", and naming the layout, not a temporary file."""
    missing = tmp_path / "nosuch" / "layout.json"
    result = _run("--port", "0", "--layout", str(missing))
    assert result.returncode == 2 and "Traceback" not in result.stderr
    assert result.stderr.strip().splitlines() == [
        f"debug_gui: error: --layout {missing}: directory {missing.parent} does not exist"
    ], result.stderr
    result = _run("--port", "0", "--layout", str(tmp_path))
    assert result.stderr.strip().splitlines() == [
        f"debug_gui: error: --layout {tmp_path} is a directory, not a file"
    ], result.stderr


def test_the_start_up_line_names_the_team_link_domains(tmp_path: Path) -> None:
    domain, far = isolated_domain_id(), isolated_domain_id()
    with gui(tmp_path, domains=[domain], args=["--team-link-domains", str(far)]) as server:
        assert (f"debug_gui: serving robots of domain(s) {domain} and team-link domain(s) "
                f"{far} at {server.url}") in server.output()


def test_without_the_token_a_page_is_read_only_and_writes_are_refused(
    tmp_path: Path, browser
) -> None:
    domain = isolated_domain_id()
    layout = tmp_path / "layout.json"
    with fake_robot(tmp_path, domain_id=domain, namespace="/r") as robot, \
            gui(tmp_path, domains=[domain], args=["--layout", str(layout)]) as server:
        browser.get(server.base_url)  # no ?token=
        alive = [robot, server]
        wait_for_text(browser, "read-only", alive=alive)
        click(browser, "save-layout")
        wait_for_text(browser, "needs the server's token", alive=alive)
        assert not layout.exists()
        # Reading works all the same.
        wait_for(lambda: present(browser, f"components-{domain}:/r"), what="the view",
                 alive=alive)
        # With the token, the same write goes through.
        browser.get(server.url)
        wait_for_text(browser, "write access", alive=alive)
        choose(browser, "bind-0", f"r @ domain {domain}")
        click(browser, "save-layout")
        wait_for_text(browser, "layout saved", alive=alive)
        assert '"namespace": "/r"' in layout.read_text()


def test_beyond_loopback_pages_need_the_token(tmp_path: Path, browser) -> None:
    domain = isolated_domain_id()
    token = "test-token-123"
    with gui(tmp_path, domains=[domain],
             args=["--host", "0.0.0.0", "--token", token]) as server:
        assert server.token == token
        local = server.base_url.replace("0.0.0.0", "127.0.0.1")
        browser.get(local)
        wait_for_text(browser, "needs its token", alive=[server])
        assert not present(browser, "binding")
        browser.get(f"{local}?token=wrong-token-1")
        wait_for_text(browser, "needs its token", alive=[server])
        browser.get(f"{local}?token={token}")
        wait_for_text(browser, "write access", alive=[server])


@pytest.mark.parametrize(("args", "error"), [
    (["--solo", "--robots", "9"], "--robots is 1..6, not 9"),
    (["--solo", "--domains", "3"], "--domains is two different domain ids A,B"),
    (["--solo", "--domains", "4,4"], "--domains is two different domain ids A,B"),
    (["--solo", "--duration", "-1", "--port", "0"], "--duration is >= 0"),
    (["--solo", "--seed", "3"], "unrecognized arguments with --solo: --seed 3"),
    # The match (the demo without --solo): the demo's refusals, and the match's own.
    (["--robots", "1"], "--robots 1 is one robot alone, no match: --solo --robots 1"),
    (["--lockstep", "--domains", "3,4"], "--domains: for --solo robots only"),
    (["--robots", "4v1", "--port", "0"], "soccer_match: error: argument --robots: '4v1'"),
])
def test_the_demo_refuses_bad_options_in_one_line(args: list[str], error: str) -> None:
    result = subprocess.run([sys.executable, "-m", "debug_gui.demo", *args],
                            env=ros_env(isolated_domain_id()), capture_output=True, text=True,
                            timeout=60)
    assert result.returncode == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and error in lines[0] and "Traceback" not in result.stderr, lines
