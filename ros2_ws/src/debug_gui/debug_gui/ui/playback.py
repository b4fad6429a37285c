"""The playback bar (``debug_gui --log``): one timeline and cursor above every view.

The bar drives the server's one :class:`~debug_gui.playback.Playback` (the Source every
view of every tab reads): play/pause, step back and forward, the rate, a slider in log
time with the events as its marks, "go to" a time. Below it the external video's frame
at the cursor (its clock put on the log's by ``<video>.sync.json``, log_analysis's
``VideoFit``), served as a JPEG the page asks for again when the cursor moves, as the
image view's frames are fetched, not pushed through element updates; the event list
(filter by text, robot, generator; a click jumps the cursor there; previous and next);
the augmented video and the A/B report when the server was given them.

A video without a fit is shown with its first frame at the log's start and says so; the
bar offers the fit from the ball's motion (log_analysis's ``fit_video_clock``, run off
the event loop) or an anchor picked by hand (the frame shown now is the cursor's
instant), and keeps it beside the video as ``sync-video`` would.
"""

from __future__ import annotations

import logging
import math
import re
import threading
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import cv2
from fastapi import Response
from fastapi.responses import FileResponse
from nicegui import app, run, ui

from log_analysis import (
    Event,
    ExternalVideo,
    LogAnalysisError,
    TeamLog,
    VideoFit,
    VideoFrames,
    fit_anchors,
    fit_video_clock,
)

from ..errors import DebugGuiError, LogUnreadable
from ..layout import Layout
from ..playback import Playback, filter_events, next_event, previous_event, rebind
from ..security import AccessPolicy
from .app import Shell

_log = logging.getLogger(__name__)
ROUTE = "/_debug_gui/playback"
#: How often the bar shows the cursor (s).
REFRESH_S = 0.2
RATES = {0.25: "0.25x", 0.5: "0.5x", 1.0: "1x", 2.0: "2x", 4.0: "4x", 8.0: "8x", 16.0: "16x"}
#: The event list shows at most this many rows (filter for the others).
MAX_ROWS = 200


@dataclass
class PlaybackSetup:
    """What ``debug_gui --log`` opened: the playback, its events, the video and its fit,
    the augmented video and the A/B report folder."""

    playback: Playback
    policy: AccessPolicy
    events: list[Event] = field(default_factory=list)
    events_note: str = ""
    video: ExternalVideo | None = None
    fit: VideoFit | None = None
    video_note: str = ""
    augmented: Path | None = None
    report: Path | None = None
    _frames: VideoFrames | None = None
    _lock: threading.Lock = field(default_factory=threading.Lock)

    def camera_ns(self, log_ns: int) -> int:
        """The camera time shown at the log's ``log_ns``."""
        assert self.video is not None
        if self.fit is not None:
            return self.fit.to_camera(log_ns)
        return self.video.start_ns + (log_ns - self.playback.start_ns)

    def jpeg(self, log_ns: int) -> bytes | None:
        """The video's frame at ``log_ns`` as JPEG (None: no video, no frame)."""
        if self.video is None:
            return None
        with self._lock:
            if self._frames is None:
                self._frames = VideoFrames(self.video)
            # The frame nearest the instant (the one at or before it is up to a frame
            # period old: at 5 fps the ball was drawn 0.2 s back).
            found = self._frames.at(self.camera_ns(log_ns) + self.video.frame_period_ns // 2)
        if found is None:
            return None
        ok, data = cv2.imencode(".jpg", cv2.cvtColor(found[1], cv2.COLOR_RGB2BGR),
                                [cv2.IMWRITE_JPEG_QUALITY, 80])
        return data.tobytes() if ok else None

    def keep_fit(self, fit: VideoFit) -> None:
        """Use ``fit`` from now on and keep it beside the video (``<video>.sync.json``)."""
        assert self.video is not None
        fit.save(sync_path(self.video.path))
        self.fit = fit
        self.video_note = describe_fit(fit)

    def anchor(self, log_ns: int, *, offset_s: float = 0.0) -> VideoFit:
        """Fit the video's clock on one anchor picked by hand: the frame shown at
        ``log_ns`` now, moved by ``offset_s`` on the camera's clock, was taken at
        ``log_ns``. Kept as :meth:`keep_fit` keeps it."""
        video = self.video
        if video is None:
            raise LogUnreadable("no video to anchor: start debug_gui with --video VIDEO")
        camera = self.camera_ns(log_ns) + round(offset_s * 1e9)
        fit = fit_anchors([(camera, log_ns)], start_ns=video.start_ns,
                          frame_period_ns=video.frame_period_ns)
        self.keep_fit(fit)
        return fit

    def close(self) -> None:
        with self._lock:
            if self._frames is not None:
                self._frames.close()


class PlaybackShell(Shell):
    """The shell of ``debug_gui --log``: a layout restored from its file (saved live, on
    the match's domains) is moved onto the log's robots by namespace, as at start."""

    def restore(self) -> Layout:
        self.layout = rebind(super().restore(), self.source.robots())
        return self.layout


def sync_path(video: Path) -> Path:
    """Where ``sync-video`` keeps a video's fit."""
    return video.with_name(video.name + ".sync.json")


def describe_fit(fit: VideoFit) -> str:
    return (f"video clock: offset {fit.offset_ns / 1e9:+.3f} s, drift {fit.drift_ppm:+.1f} "
            f"ppm, residual {fit.residual_frames:.2f} frames ({fit.method})")


def install(setup: PlaybackSetup) -> None:
    """The routes the bar's page fetches: the video frame, the augmented video, the report's
    files (token-checked as the page is, beyond loopback)."""

    def allowed(token: str | None) -> bool:
        return setup.policy.loopback or setup.policy.valid(token)

    @app.get(ROUTE + "/frame.jpg")
    def frame(t: int, token: str | None = None) -> Response:
        if not allowed(token):
            return Response(status_code=403)
        try:
            data = setup.jpeg(t)
        except LogAnalysisError as exc:
            return Response(str(exc), status_code=500, media_type="text/plain")
        if data is None:
            return Response(status_code=404)
        return Response(data, media_type="image/jpeg", headers={"Cache-Control": "no-store"})

    if setup.augmented is not None:
        augmented = setup.augmented

        @app.get(ROUTE + "/augmented.mp4")
        def augmented_video(token: str | None = None) -> Response:
            if not allowed(token):
                return Response(status_code=403)
            return FileResponse(augmented, media_type="video/mp4")

    if setup.report is not None:
        report = setup.report.resolve()

        @app.get(ROUTE + "/report/{name}")
        def report_file(name: str, token: str | None = None) -> Response:
            path = (report / name).resolve()
            if not allowed(token) or path.parent != report or not path.is_file():
                return Response(status_code=404)
            return FileResponse(path)


def report_markdown(folder: Path, *, token: str | None) -> str:
    """The report's markdown with its plots' links pointing at the bar's route."""
    text = (folder / "report.md").read_text()
    query = f"?token={token}" if token else ""

    def link(found: re.Match[str]) -> str:
        target = found.group(2)
        if "/" in target or ":" in target:
            return found.group(0)
        return f"{found.group(1)}({ROUTE}/report/{target}{query})"

    return re.sub(r"(!\[[^\]]*\])\(([^)\s]+)\)", link, text)


class PlaybackBar:
    """One tab's bar. Built by the shell above the views (Shell.bar)."""

    def __init__(self, setup: PlaybackSetup, token: str | None) -> None:
        self.setup = setup
        self.playback = setup.playback
        self.token = token
        self.shown: list[Event] = list(setup.events)
        self._text = ""
        self._robot = ""
        self._generator = ""
        self._frame_t: int | None = None
        #: The cursor the bar showed last (what a pause stops on).
        self._shown_ns: int | None = None

    def _rel(self, t_ns: int) -> float:
        return (t_ns - self.playback.start_ns) / 1e9

    def _seek_rel(self, seconds: Any) -> None:
        duration = self._rel(self.playback.end_ns)
        try:
            rel = float(seconds)
            if not math.isfinite(rel):
                raise ValueError("not a number")
            self.playback.seek(self.playback.start_ns / 1e9 + rel)
        except (TypeError, ValueError, DebugGuiError) as exc:
            ui.notify(f"cannot go to {seconds!r}: {exc} (seconds from the log's start, "
                      f"0 to {duration:.2f})", type="negative")
            return
        if not 0.0 <= rel <= duration:
            ui.notify(f"{rel:g} s is outside the log (0 to {duration:.2f} s): went to its "
                      f"{'start' if rel < 0 else 'end'}", type="warning")

    def build(self) -> None:
        p = self.playback
        duration = self._rel(p.end_ns)
        # The controls stay in sight while the views below are scrolled (under the
        # page's header); the video and the event list scroll with the page.
        with ui.card().classes("w-full gap-1").props("data-testid=playback").style(
                "position: sticky; top: 3.6rem; z-index: 5; padding: 0.5rem 1rem 1.5rem"):
            with ui.row().classes("items-center gap-2 w-full"):
                ui.label(f"log {Path(p.path).name}").classes("text-bold")
                ui.button(icon="skip_previous", on_click=lambda: p.step(back=True)).props(
                    "flat dense data-testid=playback-back").tooltip("previous message")
                self.play = ui.button("play", icon="play_arrow", on_click=self._toggle).props(
                    "dense data-testid=playback-play")
                ui.button(icon="skip_next", on_click=lambda: p.step()).props(
                    "flat dense data-testid=playback-forward").tooltip("next message")
                ui.select(RATES, value=p.rate, on_change=lambda e: p.set_rate(e.value)).props(
                    "dense data-testid=playback-rate").classes("w-20")
                self.time = ui.label().props("data-testid=playback-time").classes("font-mono")
                goto = ui.input("go to (s)").props("dense data-testid=playback-goto").classes(
                    "w-28")
                goto.on("keydown.enter", lambda: self._seek_rel(goto.value))
                self.problem = ui.label().classes("text-negative").props(
                    "data-testid=playback-problem")
            self.slider = ui.slider(min=0.0, max=max(duration, 0.01), step=0.01, value=0.0).props(
                "label data-testid=playback-slider")
            self.slider.props["marker-labels"] = {
                f"{self._rel(e.start_ns):.2f}": e.name for e in self.setup.events[:MAX_ROWS]}
            self.slider.on("change", lambda e: self._seek_rel(e.args))
        with ui.card().classes("w-full gap-1").props("data-testid=playback-media"):
            with ui.row().classes("w-full items-start gap-4 no-wrap"):
                if self.setup.video is not None:
                    self._video_panel()
                self._event_panel()
            self._extras()
        ui.timer(REFRESH_S, self._refresh)

    def _toggle(self) -> None:
        if self.playback.playing:
            # Stop where the page is, not where the cursor ran on to since the last refresh
            # (at 4x, the bar's 0.2 s is almost a second of log): what was shown is what
            # the user paused on.
            self.playback.pause()
            if self._shown_ns is not None:
                self.playback.seek_ns(self._shown_ns)
        else:
            self.playback.play()

    def _video_panel(self) -> None:
        with ui.column().classes("gap-1"):
            self.frame = ui.image().classes("w-96").props("data-testid=playback-video")
            self.video_note = ui.label(self.setup.video_note).classes("text-caption").props(
                "data-testid=playback-video-note")
            if self.setup.fit is None:
                with ui.row().classes("items-center gap-2"):
                    ui.button("fit from the ball", on_click=self._fit).props(
                        "flat dense data-testid=playback-fit")
                    offset = ui.number("camera - log (s)", value=0.0, format="%.3f").props(
                        "dense").classes("w-32")
                    ui.button("anchor here", on_click=lambda: self._anchor(offset.value)).props(
                        "flat dense data-testid=playback-anchor").tooltip(
                        "the frame at the cursor plus this offset is the cursor's instant")

    async def _fit(self) -> None:
        video = self.setup.video
        assert video is not None
        ui.notify("fitting the video's clock from the ball's motion ...")
        try:
            # A reader of its own: the playing thread reads the playback's meanwhile.
            fit = await run.io_bound(lambda: fit_video_clock(TeamLog(self.playback.path),
                                                             video))
            if fit is None:  # the server stops meanwhile
                return
            self.setup.keep_fit(fit)
        except LogAnalysisError as exc:
            ui.notify(f"no fit: {exc}", type="negative")
            return
        self.video_note.text = self.setup.video_note
        self._frame_t = None

    def _anchor(self, offset_s: Any) -> None:
        try:
            self.setup.anchor(self.playback.cursor_ns, offset_s=float(offset_s or 0.0))
        except (LogAnalysisError, DebugGuiError, OSError) as exc:
            ui.notify(f"no fit: {exc}", type="negative")
            return
        self.video_note.text = self.setup.video_note
        self._frame_t = None

    def _event_panel(self) -> None:
        events = self.setup.events
        with ui.column().classes("gap-1 grow"):
            with ui.row().classes("items-center gap-2"):
                ui.label(f"events ({len(events)})").classes("text-bold")
                ui.button(icon="navigate_before", on_click=lambda: self._jump(previous_event)
                          ).props("flat dense data-testid=event-previous").tooltip(
                    "previous event")
                ui.button(icon="navigate_next", on_click=lambda: self._jump(next_event)).props(
                    "flat dense data-testid=event-next").tooltip("next event")
                ui.input("filter", on_change=lambda e: self._filter(text=e.value)).props(
                    "dense clearable data-testid=event-filter").classes("w-32")
                robots = {"": "any robot", **{r: r for r in sorted({e.robot for e in events})
                                              if r}}
                ui.select(robots, value="", on_change=lambda e: self._filter(robot=e.value)
                          ).props("dense data-testid=event-robot").classes("w-32")
                generators = {"": "any generator", **{
                    g: g for g in sorted({e.generator for e in events}) if g}}
                ui.select(generators, value="",
                          on_change=lambda e: self._filter(generator=e.value)).props(
                    "dense data-testid=event-generator").classes("w-40")
            if self.setup.events_note:
                ui.label(self.setup.events_note).classes("text-caption").props(
                    "data-testid=events-note")
            self.rows = ui.column().classes("gap-0 w-full max-h-60 overflow-auto").props(
                "data-testid=event-list")
        self._render_rows()

    def _filter(self, *, text: str | None = None, robot: str | None = None,
                generator: str | None = None) -> None:
        self._text = self._text if text is None else (text or "")
        self._robot = self._robot if robot is None else (robot or "")
        self._generator = self._generator if generator is None else (generator or "")
        self.shown = filter_events(self.setup.events, text=self._text, robot=self._robot,
                                   generator=self._generator)
        self._render_rows()

    def _render_rows(self) -> None:
        self.rows.clear()
        with self.rows:
            if not self.shown:
                ui.label("no events" if not self.setup.events else "no event matches").classes(
                    "italic")
            for i, event in enumerate(self.shown[:MAX_ROWS]):
                where = f" {event.robot}" if event.robot else ""
                ui.button(f"{self._rel(event.start_ns):8.2f} s{where}: {event.name}",
                          on_click=lambda e=event: self.playback.seek_ns(e.start_ns)).props(
                    f"flat dense no-caps align=left data-testid=event-{i}").classes(
                    "w-full").tooltip(event.description or event.name)

    def _jump(self, pick: Any) -> None:
        event = pick(self.shown, self.playback.cursor_ns)
        if event is None:
            ui.notify("no further event")
            return
        self.playback.seek_ns(event.start_ns)

    def _extras(self) -> None:
        query = f"?token={self.token}" if self.token else ""
        if self.setup.augmented is not None:
            with ui.expansion("augmented video").classes("w-full").props(
                    "dense data-testid=playback-augmented"):
                ui.video(f"{ROUTE}/augmented.mp4{query}", autoplay=False).classes("w-full")
                ui.link("open the MP4", f"{ROUTE}/augmented.mp4{query}", new_tab=True)
        if self.setup.report is not None:
            with ui.expansion("A/B report").classes("w-full").props(
                    "dense data-testid=playback-report"):
                try:
                    ui.markdown(report_markdown(self.setup.report, token=self.token))
                except OSError as exc:
                    ui.label(f"cannot read {self.setup.report / 'report.md'}: {exc}")

    def _refresh(self) -> None:
        p = self.playback
        t = p.cursor_ns
        self._shown_ns = t
        rel = self._rel(t)
        self.time.text = (f"{rel:.2f} s / {self._rel(p.end_ns):.2f} s "
                          f"(log time {t / 1e9:.3f})")
        if abs(float(self.slider.value or 0.0) - rel) >= 0.005:
            self.slider.value = round(rel, 2)
        playing = p.playing
        self.play.text = "pause" if playing else "play"
        self.play.props(f"icon={'pause' if playing else 'play_arrow'}")
        problem = p.error or "; ".join(p.problems)
        self.problem.text = problem
        if self.setup.video is not None and t != self._frame_t:
            self._frame_t = t
            query = f"&token={self.token}" if self.token else ""
            self.frame.set_source(f"{ROUTE}/frame.jpg?t={t}{query}")
