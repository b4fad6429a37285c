"""The ``debug_gui`` command: join the robots' domains and serve the GUI to a browser.

``debug_gui [--port P] [--host H] [--token T] [--domains 0,5] [--team-link-domains 7]
[--layout FILE] [--foxglove-port P] [--plain-robots]`` prints the URL to open (with the
token that gives write access) once it serves. Bad options end in one
``debug_gui: error: ...`` line.

``debug_gui --log LOG [--video VIDEO] [--events FILE] [--augmented MP4] [--report DIR]``
plays a merged team log back instead (``playback.py``; the bar: ``ui/playback.py``): the
events sidecar beside the log (``<log>.events.mcap``) and the video's fit beside it
(``<video>.sync.json``) are found by default.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import socket
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from rclpy.utilities import remove_ros_args

from .errors import DebugGuiError, InvalidInput, LogUnreadable
from .layout import Layout, check_layout_path
from .security import AccessPolicy, check_port, parse_domains

# The data side (rclpy contexts, bags, videos) and the UI toolkit are imported where they
# serve: a bad option or --help answers before them (1.5 s of imports).
if TYPE_CHECKING:
    from .hub import Hub
    from .source import Source
    from .ui.playback import PlaybackSetup

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
    log = parser.add_argument_group("playing a log back")
    log.add_argument("--log", type=Path, default=None,
                     help="play this merged team log back instead of joining domains")
    log.add_argument("--video", type=Path, default=None,
                     help="the external video of the match (its fit: VIDEO.sync.json)")
    log.add_argument("--events", type=Path, default=None,
                     help="events sidecar (default: LOG.events.mcap beside the log)")
    log.add_argument("--augmented", type=Path, default=None,
                     help="the augmented video (log_analysis augment) to show")
    log.add_argument("--report", type=Path, default=None,
                     help="an A/B report folder (log_analysis compare) to show")
    return parser


def free_port(host: str) -> int:
    """A port on ``host`` that stays free for the web server (``--port 0``).

    A port merely found free was taken by another process before the server bound it (a
    full test run saw "address already in use" for the port the GUI had just announced).
    So the port is left in TIME_WAIT by one connection to itself: the kernel hands it to
    no other ``bind(0)`` or outgoing connection for a minute, while a server that binds it
    with ``SO_REUSEADDR`` (uvicorn does) gets it at once.
    """
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    with socket.socket(family) as listener:
        listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        listener.bind((host, 0))
        listener.listen(1)
        address = listener.getsockname()
        with socket.socket(family) as client:
            client.connect(address)
            accepted, _ = listener.accept()
            accepted.close()  # closed first on this side: its end waits in TIME_WAIT
        return int(address[1])


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
        self.log: Path | None = ns.log
        self.video: Path | None = ns.video
        self.events: Path | None = ns.events
        self.augmented: Path | None = ns.augmented
        self.report: Path | None = ns.report
        if self.log is None and any(x is not None for x in (
                self.video, self.events, self.augmented, self.report)):
            raise InvalidInput("--video, --events, --augmented and --report go with --log LOG")
        if self.report is not None and not (self.report / "report.md").is_file():
            raise InvalidInput(f"--report {self.report}: no report.md in it "
                               "(a folder log_analysis compare wrote)")
        if self.augmented is not None and not self.augmented.is_file():
            raise InvalidInput(f"--augmented {self.augmented}: no such file")


def serving(options: Options) -> str:
    """Whose robots the start-up line names: ``robots of domain(s) 0, 5 and team-link
    domain(s) 40`` (a team-link domain alone: ``robots of team-link domain(s) 40``)."""
    parts = []
    if options.domains:
        parts.append(f"domain(s) {', '.join(map(str, options.domains))}")
    if options.team_link_domains:
        parts.append(f"team-link domain(s) {', '.join(map(str, options.team_link_domains))}")
    if options.log is not None:
        return f"the log {options.log}"
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

    from .hub import Hub
    from .playback import rebind
    from .ui import registry
    from .ui.app import Shell, install

    registry.load_views()
    known = [k.kind for k in registry.kinds()]
    layout: Layout | None = None
    if options.layout_path is not None and options.layout_path.exists():
        layout = Layout.load(options.layout_path, known_kinds=known)
    closers: list[Any] = []
    source: Source
    bar: Callable[[str | None], None] | None = None
    if options.log is not None:
        from .ui.playback import PlaybackBar, PlaybackShell
        from .ui.playback import install as install_playback

        setup = open_log(options)
        closers += [setup.playback.close, setup.close]
        source = setup.playback
        install_playback(setup)
        print(f"debug_gui: {describe(setup)}", flush=True)

        def bar(token: str | None) -> None:
            PlaybackBar(setup, token).build()
    else:
        hub = Hub(domains=options.domains, team_link_domains=options.team_link_domains,
                  plain_robots=options.plain_robots)
        hub.start()
        closers.append(hub.close)
        source = hub
    try:
        if options.foxglove_port is not None:
            if not isinstance(source, Hub):
                raise InvalidInput("--foxglove-port serves live robots, not a log")
            closers.append(_start_foxglove(source, options))
        shell = (Shell if bar is None else PlaybackShell)(
            source=source, policy=options.policy, layout=Layout(),
            layout_path=options.layout_path, bar=bar)
        shell.layout = (layout if layout is not None else default_layout
                        if default_layout is not None else shell.default_layout())
        if options.log is not None:  # a layout saved live: the match's robots, by namespace
            shell.layout = rebind(shell.layout, source.robots())
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


def open_log(options: Options) -> PlaybackSetup:
    """The log, its events and its video as ``--log`` and its options name them; what is
    missing beside the log is said (in the notes), what is broken is LogUnreadable."""
    from log_analysis import (
        ExternalVideo,
        LogAnalysisError,
        VideoFit,
        read_events,
        sidecar_path,
    )

    from .playback import Playback
    from .ui.playback import PlaybackSetup, describe_fit, sync_path

    assert options.log is not None
    playback = Playback(options.log)
    setup = PlaybackSetup(playback=playback, policy=options.policy,
                          augmented=options.augmented, report=options.report)
    try:
        events_path = options.events or sidecar_path(options.log)
        if events_path.exists():
            setup.events = sorted(read_events(events_path), key=lambda e: e.start_ns)
            setup.events_note = f"events from {events_path}"
        elif options.events is not None:
            raise LogUnreadable(f"--events {events_path}: no such file")
        else:
            setup.events_note = (f"no events beside the log ({events_path.name}): "
                                 f"ros2 run log_analysis events {options.log} finds them")
        if options.video is not None:
            setup.video = ExternalVideo(options.video)
            fit_path = sync_path(options.video)
            if fit_path.exists():
                setup.fit = VideoFit.load(fit_path)
                setup.video_note = describe_fit(setup.fit)
            else:
                setup.video_note = (f"no {fit_path.name}: the video is not in sync (its first "
                                    "frame is shown at the log's start); fit it here from "
                                    "the ball, or pick an anchor")
    except LogAnalysisError as exc:
        playback.close()
        raise LogUnreadable(str(exc)) from None
    except LogUnreadable:
        playback.close()
        raise
    return setup


def describe(setup: PlaybackSetup) -> str:
    p = setup.playback
    parts = [f"playing back {p.path}: {len(p.robots())} robot(s), "
             f"{(p.end_ns - p.start_ns) / 1e9:.1f} s", f"{len(setup.events)} event(s)"]
    if setup.video is not None:
        parts.append(setup.video_note)
    return "; ".join(parts)


def _start_foxglove(hub: Hub, options: Options) -> Any:
    """The foxglove endpoint (debug_gui.foxglove); returns its close function."""
    from . import foxglove

    assert options.foxglove_port is not None
    server = foxglove.start(hub, host=options.policy.host, port=options.foxglove_port,
                            policy=options.policy)
    return server.close
