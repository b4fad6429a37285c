"""The ``debug_gui`` command: join the robots' domains and serve the GUI to a browser.

``debug_gui [--port P] [--host H] [--token T] [--domains 0,5] [--team-link-domains 7]
[--layout FILE] [--foxglove-port P] [--plain-robots]`` prints the URL to open (with the
token that gives write access) once it serves. Bad options end in one
``debug_gui: error: ...`` line.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import socket
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from rclpy.utilities import remove_ros_args

from .errors import DebugGuiError, InvalidInput
from .hub import Hub
from .layout import Layout, check_layout_path
from .security import AccessPolicy, check_port, parse_domains

DEFAULT_PORT = 8080
#: How long a tab whose connection dropped keeps its page (NiceGUI's default, 3 s, makes a
#: browser on a loaded machine reload and rebuild every view). Its feeds close at once on
#: the drop and reopen on reconnection either way, so waiting costs the robots nothing.
RECONNECT_TIMEOUT_S = 30.0


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="debug_gui",
        description="Serve the debugging GUI for the robots of one or more DDS domains.",
    )
    parser.add_argument("--port", type=int, default=DEFAULT_PORT,
                        help=f"HTTP port (default {DEFAULT_PORT}; 0 = any free port)")
    parser.add_argument("--host", default="127.0.0.1",
                        help="address to bind (default 127.0.0.1; others need --token)")
    parser.add_argument("--token", default=None,
                        help="token for writes (and for pages beyond loopback); made up "
                             "and printed in the URL when not given on loopback")
    parser.add_argument("--domains", default=os.environ.get("ROS_DOMAIN_ID") or "0",
                        help="DDS domain ids to look for robots in, e.g. 0,5 "
                             "(default: $ROS_DOMAIN_ID or 0)")
    parser.add_argument("--team-link-domains", default="",
                        help="domains whose robots are reached over rf_bridge's team link")
    parser.add_argument("--layout", type=Path, default=None,
                        help="layout JSON file: restored at start if it exists, "
                             "written by 'save layout'")
    parser.add_argument("--foxglove-port", type=int, default=None,
                        help="also serve the robots on a Foxglove WebSocket endpoint")
    parser.add_argument("--plain-robots", action="store_true",
                        help="also show plain ROS 2 robots (no efficient_comm statistics): "
                             "every top-level namespace with running nodes, the root "
                             "namespace included")
    return parser


def free_port(host: str) -> int:
    with socket.socket(socket.AF_INET6 if ":" in host else socket.AF_INET) as s:
        s.bind((host, 0))
        return int(s.getsockname()[1])


def _check_bindable(host: str, port: int) -> None:
    try:
        family = socket.AF_INET6 if ":" in host else socket.AF_INET
        with socket.socket(family) as s:
            s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            s.bind((host, port))
    except OSError as exc:
        raise InvalidInput(f"cannot serve on {host}:{port}: {exc.strerror or exc}") from None


def url(policy: AccessPolicy, port: int) -> str:
    host = f"[{policy.host}]" if ":" in policy.host else policy.host
    return f"http://{host}:{port}/?token={policy.token}"


class Options:
    """The command line, validated."""

    def __init__(self, argv: Sequence[str]) -> None:
        ns = _parser().parse_args(list(argv))
        self.policy = AccessPolicy.for_server(host=ns.host, token=ns.token)
        port = check_port(ns.port)
        self.domains = parse_domains(ns.domains)
        self.team_link_domains = (
            parse_domains(ns.team_link_domains) if ns.team_link_domains else []
        )
        both = sorted(set(self.domains) & set(self.team_link_domains))
        if both:
            raise InvalidInput(
                f"domain {', '.join(map(str, both))} is in both --domains and "
                "--team-link-domains: name each domain once"
            )
        self.plain_robots = bool(ns.plain_robots)
        self.layout_path: Path | None = (
            None if ns.layout is None else check_layout_path(ns.layout)
        )
        self.foxglove_port = None if ns.foxglove_port is None else check_port(ns.foxglove_port)
        if port:
            _check_bindable(self.policy.host, port)
        self.port = port or free_port(self.policy.host)


def serving(options: Options) -> str:
    """Whose robots the start-up line names: ``robots of domain(s) 0, 5 and team-link
    domain(s) 40`` (a team-link domain alone: ``robots of team-link domain(s) 40``)."""
    parts = []
    if options.domains:
        parts.append(f"domain(s) {', '.join(map(str, options.domains))}")
    if options.team_link_domains:
        parts.append(f"team-link domain(s) {', '.join(map(str, options.team_link_domains))}")
    plain = " (plain ROS 2 robots too)" if options.plain_robots else ""
    return f"robots of {' and '.join(parts)}{plain}"


def main(argv: Sequence[str] | None = None) -> int:
    argv = remove_ros_args(list(sys.argv if argv is None else ["debug_gui", *argv]))[1:]
    try:
        options = Options(argv)
        return serve(options)
    except DebugGuiError as exc:
        print(f"debug_gui: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 0


def serve(options: Options, *, default_layout: Layout | None = None) -> int:
    """Join the domains, then serve until Ctrl-C/SIGTERM (NiceGUI in this main thread).

    ``default_layout``: what a tab starts from when no ``--layout`` file holds one (by
    default a team components panel); the demo of a team match starts from its world."""
    # NiceGUI takes a variable inherited from a pytest parent (a test that starts this
    # command) to mean it runs under its own test fixture, and then ignores --port.
    os.environ.pop("PYTEST_CURRENT_TEST", None)
    from nicegui import app, ui

    from .ui import registry
    from .ui.app import Shell, install

    registry.load_views()
    known = [k.kind for k in registry.kinds()]
    layout: Layout | None = None
    if options.layout_path is not None and options.layout_path.exists():
        layout = Layout.load(options.layout_path, known_kinds=known)
    hub = Hub(domains=options.domains, team_link_domains=options.team_link_domains,
              plain_robots=options.plain_robots)
    hub.start()
    closers: list[Any] = [hub.close]
    try:
        if options.foxglove_port is not None:
            closers.append(_start_foxglove(hub, options))
        shell = Shell(source=hub, policy=options.policy, layout=Layout(),
                      layout_path=options.layout_path)
        shell.layout = (layout if layout is not None else default_layout
                        if default_layout is not None else shell.default_layout())
        install(shell)
        address = url(options.policy, options.port)

        def announce() -> None:
            print(f"debug_gui: serving {serving(options)} at {address}", flush=True)

        app.on_startup(announce)
        ui.run(
            host=options.policy.host, port=options.port, title="debug_gui", reload=False,
            show=False, show_welcome_message=False, uvicorn_logging_level="warning",
            favicon="🤖", reconnect_timeout=RECONNECT_TIMEOUT_S,
        )
    finally:
        for close in reversed(closers):
            with contextlib.suppress(Exception):
                close()
    return 0


def _start_foxglove(hub: Hub, options: Options) -> Any:
    """The foxglove endpoint (debug_gui.foxglove); returns its close function."""
    from . import foxglove

    assert options.foxglove_port is not None
    server = foxglove.start(hub, host=options.policy.host, port=options.foxglove_port,
                            policy=options.policy)
    return server.close
