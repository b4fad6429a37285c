"""The image view (seed Fig. 5.5): a robot's camera with its debug-drawing layers.

Frames do not travel through NiceGUI's element updates (a JSON diff per frame would be
base64 and far too slow): each view instance opens a WebSocket of its own,
``/_debug_gui/image/<key>``, on which the server sends one binary message per frame: a
4-byte length, a JSON header (stamps, the SVG overlay of the shown layers) and the JPEG as
the robot compressed it, untouched. The browser asks for the next frame only after it has
drawn the last one, so a slow browser gets fewer frames, never a backlog. Image and overlay
arrive in the same message, so the overlay drawn is always that frame's.

Only while the view is shown in a connected browser does it subscribe (a page fetched by
something that never connects, such as a health check, subscribes to nothing); paused, it
does not either.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
import secrets
import struct
from typing import Any, Literal

from fastapi import WebSocket, WebSocketDisconnect
from nicegui import app, background_tasks, run, ui
from nicegui.context import context

from debug_probes import JPEG_QUALITY

from ..errors import NOT_LIVE, DebugGuiError
from ..models.image import GRACE_S, ImageModel
from .registry import ViewContext, register

_log = logging.getLogger(__name__)

ROUTE = "/_debug_gui/image"
RATES_HZ = (5, 10, 15, 30)
POLL_S = 0.5
#: How long a view waits for its page's browser to connect before it gives up subscribing.
CONNECT_TIMEOUT_S = 60.0
#: Stream key -> the model a view instance streams from (while it is shown).
_STREAMS: dict[str, ImageModel] = {}

#: The browser side: one WebSocket per shown view, frame counters for tests and benchmarks
#: in ``window.debugGuiImage.views[key]`` and the root element's data attributes.
_SCRIPT = r"""
window.debugGuiImage = window.debugGuiImage || {
  views: {},
  attach(key, path) {
    this.detach(key);
    const v = {frames: 0, stamp: null, overlayStamp: null, ws: null, url: null, closed: false};
    this.views[key] = v;
    const open = () => {
      if (v.closed) return;
      const ws = new WebSocket((location.protocol === 'https:' ? 'wss://' : 'ws://') +
                               location.host + path);
      ws.binaryType = 'arraybuffer';
      v.ws = ws;
      const next = () => { if (ws.readyState === 1) ws.send('next'); };
      ws.onopen = next;
      ws.onmessage = (ev) => {
        const n = new DataView(ev.data).getUint32(0);
        const meta = JSON.parse(new TextDecoder().decode(new Uint8Array(ev.data, 4, n)));
        const url = URL.createObjectURL(new Blob([new Uint8Array(ev.data, 4 + n)],
                                                 {type: 'image/jpeg'}));
        const root = document.getElementById('dbgimg-' + key);
        if (!root) { URL.revokeObjectURL(url); v.closed = true; ws.close(); return; }
        const img = root.querySelector('img'), svg = root.querySelector('svg');
        img.onload = () => {
          if (v.url) URL.revokeObjectURL(v.url);
          v.url = url;
          img.style.display = 'block';
          svg.setAttribute('viewBox', '0 0 ' + img.naturalWidth + ' ' + img.naturalHeight);
          svg.innerHTML = meta.svg;
          v.frames += 1; v.stamp = meta.stamp_ns; v.overlayStamp = meta.overlay_stamp_ns;
          root.dataset.frames = v.frames;
          root.dataset.stamp = meta.stamp_ns;
          root.dataset.overlayStamp = meta.overlay_stamp_ns || '';
          next();
        };
        img.onerror = () => { URL.revokeObjectURL(url); next(); };
        img.src = url;
      };
      ws.onclose = () => { setTimeout(open, 1000); };
    };
    open();
  },
  detach(key) {
    const v = this.views[key];
    if (v) { v.closed = true; if (v.ws) v.ws.close(); delete this.views[key]; }
  },
};
"""


def live_state(*, online: bool, position: tuple[int, int] | None, fps: float,
               asked: float, camera: bool = True) -> str:
    """What the status line says the picture is: a robot that has gone is not "live", nor
    is one without a camera (it would read "live, 0.0 fps")."""
    if not online:
        return "robot gone: its last frame"
    if not camera:
        return "no camera"
    if position is not None:
        return f"paused at frame {position[0] + 1} of {position[1]}"
    return f"live, {fps:.1f} fps received (asked {asked:g})"


def placeholder_text(*, camera: bool, image_topic: str) -> str:
    """What the view shows where the picture will be, before the first frame."""
    if not camera:
        return f"no image topic: this robot publishes no {image_topic}"
    return "waiting for the first frame…"


def frame_message(model: ImageModel) -> tuple[tuple[Any, ...], bytes] | None:
    """What to send for the frame shown now: (what identifies it, the binary message)."""
    shown = model.current()
    if shown is None:
        return None
    frame, drawing = shown
    layers = tuple(model.shown_layers())
    ident = (frame.seq, drawing is not None, layers, model.position())
    meta = json.dumps({
        "seq": frame.seq,
        # Strings: nanosecond stamps exceed JavaScript's exact integers.
        "stamp_ns": str(frame.stamp_ns),
        "overlay_stamp_ns": str(drawing.stamp_ns) if drawing is not None else None,
        "svg": model.overlay(drawing),
    }).encode()
    return ident, struct.pack(">I", len(meta)) + meta + frame.jpeg


async def _stream(websocket: WebSocket, key: str) -> None:
    """Send the view's frames, one per 'next' from the browser (its flow control)."""
    model = _STREAMS.get(key)
    if model is None:
        await websocket.close(code=4404)
        return
    await websocket.accept()
    loop = asyncio.get_running_loop()
    changed = asyncio.Event()

    def wake() -> None:  # on a feed's thread
        loop.call_soon_threadsafe(changed.set)

    remove = model.add_listener(wake)
    last: tuple[Any, ...] | None = None
    try:
        while _STREAMS.get(key) is model:
            await websocket.receive_text()  # the browser drew the last frame
            while _STREAMS.get(key) is model:
                changed.clear()
                out = frame_message(model)
                if out is not None and out[0] != last:
                    last = out[0]
                    await websocket.send_bytes(out[1])
                    break
                # A frame waiting for its drawing is shown after GRACE_S without one.
                with contextlib.suppress(TimeoutError):
                    await asyncio.wait_for(changed.wait(), timeout=GRACE_S)
    except WebSocketDisconnect:
        return  # the browser went (its tab closed, the view hidden): nothing to close
    finally:
        remove()
    # The view stopped streaming while the browser is still there: close the socket. The
    # browser may go at the same moment, and then there is nothing to close either.
    with contextlib.suppress(WebSocketDisconnect, RuntimeError):
        await websocket.close()


app.add_api_websocket_route(ROUTE + "/{key}", _stream)


@register(kind="image", title="Image", order=30)
def build(ctx: ViewContext) -> None:
    assert ctx.robot is not None  # a per-robot kind: the shell binds every instance
    robot = ctx.robot
    model = ImageModel(ctx.source, robot)
    kept_rate = ctx.settings.get("rate_hz")
    if isinstance(kept_rate, int) and not isinstance(kept_rate, bool) and kept_rate in RATES_HZ:
        model.set_rate(float(kept_rate))  # the panel's layout: the rate the user chose
    key = secrets.token_hex(8)
    client = context.client
    shown = {"yes": False}

    with ui.row().classes("items-center gap-2"):
        pause = ui.button("pause").props(f"dense data-testid=image-pause-{robot.key}")
        prev = ui.button("◀").props(f"dense data-testid=image-prev-{robot.key}")
        nxt = ui.button("▶").props(f"dense data-testid=image-next-{robot.key}")
        rate = ui.select({r: f"{r} fps" for r in RATES_HZ}, value=int(model.rate_hz),
                         label="rate").props(f"dense data-testid=image-rate-{robot.key}")
        # Wide enough for its label: a dense field as narrow as its number cuts it off.
        low, high = JPEG_QUALITY
        quality = ui.number("JPEG quality", value=80, min=low, max=high, step=5,
                            precision=0).props(
            f"dense data-testid=image-quality-{robot.key}").classes("min-w-[7.5rem]")
        apply = ui.button("set").props(f"dense data-testid=image-quality-set-{robot.key}")
        # Why the quality cannot be set (no compressor, no token); text, since a tooltip
        # would be a new element, which a background task cannot create.
        quality_note = ui.label("").classes("text-caption").props(
            f"data-testid=image-quality-note-{robot.key}")
        if not ctx.source.live:  # a log's quality is what it recorded
            quality.disable()
            apply.disable()
            quality_note.text = f"{NOT_LIVE}: the JPEG quality cannot be set"
        elif not ctx.can_write:
            quality.disable()
            apply.disable()
            apply.tooltip("changing the robot needs the server's token")
    layer_row = ui.row().classes("items-center gap-1").props(
        f"data-testid=image-layers-{robot.key}")
    # Text until the first frame is drawn: an <img> without a picture is a broken-image icon.
    placeholder = ui.label(placeholder_text(
        camera=True, image_topic=robot.resolve(model.image_topic))).style(
        "width: 640px; max-width: 100%; background: #222; color: #eee; padding: 1.5rem"
    ).props(f"data-testid=image-placeholder-{robot.key}")
    ui.html(
        f'<div id="dbgimg-{key}" data-testid="image-{robot.key}" '
        f'style="position:relative; width:640px; max-width:100%; background:#222">'
        f'<img style="display:none; width:100%" alt="camera"/>'
        f'<svg style="position:absolute; left:0; top:0; width:100%; height:100%; '
        f'pointer-events:none"></svg></div>',
        sanitize=False,
    )
    status = ui.label("waiting for the camera…").classes("text-caption").props(
        f"data-testid=image-status-{robot.key}")
    boxes: dict[str, Any] = {}
    counts: dict[str, Any] = {"received": 0, "at": 0.0, "online": True}

    def refresh() -> None:
        for layer in model.layers():
            if layer not in boxes:
                with layer_row:
                    boxes[layer] = ui.checkbox(
                        layer, value=True,
                        on_change=lambda e, name=layer: model.show_layer(name, bool(e.value)),
                    ).props(f"dense data-testid=image-layer-{robot.key}-{layer}")
        loop_now = asyncio.get_running_loop().time()
        fps = ((model.received - counts["received"]) / (loop_now - counts["at"])
               if counts["at"] else 0.0)
        counts["received"], counts["at"] = model.received, loop_now
        position = model.position()
        shown_now = model.current()
        online = robot in ctx.source.robots()
        where = live_state(online=online, position=position, fps=fps, asked=model.rate_hz,
                           camera=bool(model.received) or model.has_camera())
        if online != counts["online"]:
            counts["online"] = online
            if not online and ctx.source.live:
                quality.disable()
                apply.disable()
                quality_note.text = "JPEG quality cannot be set: the robot has gone"
            elif ctx.can_write and ctx.source.live:
                background_tasks.create(read_quality(), name=f"image quality {key}")
        if model.received and placeholder.visible:
            placeholder.set_visibility(False)
        elif not model.received:
            text = placeholder_text(camera=model.has_camera(),
                                    image_topic=robot.resolve(model.image_topic))
            if text != placeholder.text:
                placeholder.text = text
        stamp = f"stamp {shown_now[0].stamp_ns / 1e9:.3f} s" if shown_now else "no frame yet"
        status.text = f"{where}; {stamp}; {model.received} frames, " \
                      f"{model.drawings_received} drawings"

    timer = ui.timer(POLL_S, refresh, active=False)

    def toggle_pause() -> None:
        if model.paused:
            model.resume(shown=shown["yes"])
            pause.text = "pause"
        else:
            model.pause()
            pause.text = "resume"

    def step(delta: int) -> None:
        if not model.paused:
            model.pause()
            pause.text = "resume"
        model.step(delta)

    def gone() -> bool:
        """The tab or the view went while a call was out (closed, removed, the server
        stopping): its elements must not be touched then."""
        return client.is_deleted or quality.is_deleted

    async def set_quality() -> None:
        kind: Literal["positive", "negative"]
        try:
            ctx.policy.check_write(ctx.token)
            value = int(quality.value or 0)
            await run.io_bound(model.set_quality, value)
            message, kind = f"{robot.label}: JPEG quality {value}", "positive"
        except (DebugGuiError, ValueError) as exc:
            message, kind = str(exc), "negative"
        # To the tab, not the button's slot: the panel may have been removed meanwhile.
        if not client.is_deleted:
            with client:
                ui.notify(message, type=kind)

    async def read_quality() -> None:
        # A background task: no slot to create elements in, so only existing ones change.
        try:
            value = await run.io_bound(model.quality)
        except DebugGuiError as exc:  # no compressor on this robot: say so, keep the view
            if not gone():
                quality.disable()
                apply.disable()
                quality_note.text = f"JPEG quality cannot be set: {exc}"
            return
        if not gone():
            quality.value = value
            quality.enable()
            apply.enable()
            quality_note.text = ""

    pause.on_click(toggle_pause)
    prev.on_click(lambda: step(-1))
    nxt.on_click(lambda: step(1))
    def on_rate(event: Any) -> None:
        model.set_rate(float(event.value))
        ctx.keep("rate_hz", int(event.value))

    rate.on_value_change(on_rate)
    apply.on_click(set_quality)

    def start() -> None:
        if not shown["yes"] or client.is_deleted:
            return
        _STREAMS[key] = model
        if not model.paused:
            model.activate()
        timer.activate()
        client.run_javascript(f"{_SCRIPT}; window.debugGuiImage.attach('{key}', "
                              f"'{ROUTE}/{key}');")
        if ctx.can_write and ctx.source.live:
            background_tasks.create(read_quality(), name=f"image quality {key}")

    async def start_when_connected() -> None:
        # A page fetched by something that is no browser (a health check, curl) never
        # connects: it must not subscribe to the robot's camera meanwhile.
        with contextlib.suppress(TimeoutError):
            await client.connected(timeout=CONNECT_TIMEOUT_S)
        if client.has_socket_connection:
            start()

    def show() -> None:
        shown["yes"] = True
        if client.has_socket_connection:
            start()
        else:
            background_tasks.create(start_when_connected(), name=f"image view {key}")

    def hide() -> None:
        shown["yes"] = False
        timer.deactivate()
        _STREAMS.pop(key, None)
        model.deactivate()
        if not client.is_deleted:
            client.run_javascript(f"window.debugGuiImage && window.debugGuiImage.detach('{key}');")

    ctx.on_show(show)
    ctx.on_hide(hide)
