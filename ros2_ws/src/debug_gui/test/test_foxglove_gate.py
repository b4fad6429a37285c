"""The gate in front of the SDK's server takes the SDK's advertise/subscribe race out of a
viewer's way: a server that advertises a channel and then answers the viewer's prompt
subscription with "Unknown channel ID" (foxglove-sdk 0.30 records the advertisement after
sending it) still serves the viewer, and the viewer never sees that answer."""

from __future__ import annotations

import asyncio
import json
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

from websockets.asyncio.client import connect
from websockets.asyncio.server import ServerConnection, serve

from debug_gui._foxglove_gate import SDK_SUBPROTOCOL, Gate

ADVERTISED, NEVER = 7, 99


class RacySdkServer:
    """Answers the gate's introduction, advertises channel 7, and refuses the first
    ``refusals`` subscriptions to it as unknown (the race), then confirms with a status."""

    def __init__(self, refusals: int) -> None:
        self.refusals = refusals
        self.subscribes: list[dict[str, Any]] = []
        self.port = 0
        self._ready = threading.Event()
        self._loop = asyncio.new_event_loop()
        self._stop: asyncio.Event | None = None
        self._thread = threading.Thread(target=self._run, daemon=True)

    def _run(self) -> None:
        try:
            self._loop.run_until_complete(self._serve())
        finally:
            self._loop.close()

    async def _serve(self) -> None:
        self._stop = asyncio.Event()
        async with serve(self._handle, "127.0.0.1", 0,
                         subprotocols=[SDK_SUBPROTOCOL]) as server:
            self.port = next(iter(server.sockets)).getsockname()[1]
            self._ready.set()
            await self._stop.wait()

    async def _handle(self, ws: ServerConnection) -> None:
        await ws.send(json.dumps({"op": "advertise", "channels": [
            {"id": ADVERTISED, "topic": "/robot/chatter", "encoding": "cdr",
             "schemaName": "std_msgs/msg/String", "schema": ""}]}))
        async for message in ws:
            request = json.loads(message)
            if request["op"] == "getParameters":  # the gate's introduction
                await ws.send(json.dumps({"op": "parameterValues", "parameters": [],
                                          "id": request["id"]}))
            elif request["op"] == "subscribe":
                self.subscribes.append(request)
                for sub in request["subscriptions"]:
                    channel = sub["channelId"]
                    if channel == ADVERTISED and self.refusals > 0:
                        self.refusals -= 1
                    elif channel == ADVERTISED:
                        await ws.send(json.dumps({"op": "status", "level": 0,
                                                  "message": f"subscribed {sub['id']}"}))
                        continue
                    await ws.send(json.dumps({"op": "status", "level": 2,
                                              "message": f"Unknown channel ID: {channel}"}))

    @contextmanager
    def running(self) -> Iterator[RacySdkServer]:
        self._thread.start()
        assert self._ready.wait(10)
        try:
            yield self
        finally:
            assert self._stop is not None
            self._loop.call_soon_threadsafe(self._stop.set)
            self._thread.join(10)


@contextmanager
def gate_before(server: RacySdkServer) -> Iterator[Gate]:
    gate = Gate(host="127.0.0.1", port=0, backend_port=server.port,
                may_connect=lambda _t: True, may_write=lambda _t: False,
                introduce=lambda _n, _w: None)
    gate.start()
    try:
        yield gate
    finally:
        gate.close()


async def _viewer(port: int, channel: int, until: str) -> list[dict[str, Any]]:
    """Subscribe to ``channel`` once it is advertised; the text messages up to ``until``."""
    seen: list[dict[str, Any]] = []
    async with connect(f"ws://127.0.0.1:{port}/", subprotocols=[SDK_SUBPROTOCOL]) as ws:
        async with asyncio.timeout(10):
            async for message in ws:
                parsed = json.loads(message)
                seen.append(parsed)
                if parsed["op"] == "advertise":
                    await ws.send(json.dumps({"op": "subscribe", "subscriptions": [
                        {"id": 1, "channelId": channel}]}))
                if until in str(parsed.get("message", "")):
                    return seen
    return seen


def test_a_subscription_the_race_refused_is_sent_again_and_the_refusal_not_shown() -> None:
    with RacySdkServer(refusals=3).running() as server, gate_before(server) as gate:
        seen = asyncio.run(_viewer(gate.port, ADVERTISED, "subscribed 1"))
    assert [m["op"] for m in seen] == ["advertise", "status"], seen
    assert seen[-1]["message"] == "subscribed 1"
    assert len(server.subscribes) == 4  # three refused, each sent again


def test_a_channel_never_advertised_is_still_refused_to_the_viewer() -> None:
    with RacySdkServer(refusals=0).running() as server, gate_before(server) as gate:
        seen = asyncio.run(_viewer(gate.port, NEVER, f"Unknown channel ID: {NEVER}"))
    assert seen[-1] == {"op": "status", "level": 2, "message": f"Unknown channel ID: {NEVER}"}
    assert len(server.subscribes) == 1
