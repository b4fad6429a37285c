"""The image view's frame socket when its browser goes: a normal end, not a server error.

Drives ``debug_gui.ui.image._stream`` with Starlette's own ``WebSocket`` over an ASGI
channel that behaves as uvicorn's does once the browser has gone (a disconnect message,
then sending fails with an ``OSError``), without a server or a browser.
"""

from __future__ import annotations

import asyncio
from collections.abc import Callable, MutableMapping
from typing import Any

from starlette.websockets import WebSocket

from debug_gui.ui import image


class _Model:
    """What ``_stream`` asks of a view's model before the first frame: listeners."""

    def __init__(self) -> None:
        self.listeners = 0

    def add_listener(self, _callback: Callable[[], None]) -> Callable[[], None]:
        self.listeners += 1

        def remove() -> None:
            self.listeners -= 1

        return remove


class _GoneBrowser:
    """An ASGI channel: the browser connects, then its tab closes (and the view hides)."""

    def __init__(self, key: str) -> None:
        self.key = key
        self.sent: list[MutableMapping[str, Any]] = []
        self.incoming: list[MutableMapping[str, Any]] = [{"type": "websocket.connect"},
                         {"type": "websocket.disconnect", "code": 1001}]

    async def receive(self) -> MutableMapping[str, Any]:
        message = self.incoming.pop(0)
        if message["type"] == "websocket.disconnect":
            image._STREAMS.pop(self.key, None)  # the view hid as the tab went
        return message

    async def send(self, message: MutableMapping[str, Any]) -> None:
        if not self.incoming:  # gone: uvicorn raises ClientDisconnected, an OSError
            raise OSError("client disconnected")
        self.sent.append(message)


def test_a_browser_going_ends_the_stream_quietly() -> None:
    key = "test-gone-browser"
    model = _Model()
    channel = _GoneBrowser(key)
    image._STREAMS[key] = model  # type: ignore[assignment]
    socket = WebSocket({"type": "websocket", "path": f"{image.ROUTE}/{key}", "headers": []},
                       channel.receive, channel.send)
    try:
        asyncio.run(image._stream(socket, key))  # raised WebSocketDisconnect before
    finally:
        image._STREAMS.pop(key, None)
    assert [m["type"] for m in channel.sent] == ["websocket.accept"]
    assert model.listeners == 0  # the feed's listener is gone with the browser


def test_an_unknown_stream_is_refused() -> None:
    channel = _GoneBrowser("nosuch")
    socket = WebSocket({"type": "websocket", "path": f"{image.ROUTE}/nosuch", "headers": []},
                       channel.receive, channel.send)
    asyncio.run(image._stream(socket, "nosuch"))
    assert channel.sent == [{"type": "websocket.close", "code": 4404, "reason": ""}]

