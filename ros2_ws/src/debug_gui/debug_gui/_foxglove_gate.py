"""The gate in front of the foxglove-sdk server: both protocol names, the token, write checks.

The SDK's WebSocket server (foxglove-sdk 0.30) accepts only the subprotocol name
``foxglove.sdk.v1``, which is the Foxglove WebSocket protocol v1 under a new name; viewers and
libraries written before that rename (Lichtblick until its December 2025 release, clients
written against the published spec) offer only ``foxglove.websocket.v1`` and are refused with HTTP
400. The SDK also has no hook to see a client's handshake or to refuse a single request.
So the endpoint serves through this gate: an asyncio WebSocket server in a thread of its
own that accepts either name, checks the token a client presents (``?token=T`` in the URL,
which a browser's WebSocket can send, or ``Authorization: Bearer T``), and pumps frames to
and from the SDK server on an ephemeral loopback port unchanged. A client that may not write
gets its writes (setParameters, service calls, client publishing) answered with the
protocol's own failure messages instead of forwarded; reads are untouched.

Back-pressure survives the hop: the gate awaits each send to the viewer before it reads the
next frame from the SDK, so a slow viewer fills the SDK's per-client queue, where the SDK
drops the oldest data messages as it does for a direct client.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import secrets
import struct
import threading
from collections.abc import Callable
from http import HTTPStatus
from urllib.parse import parse_qs, urlsplit

from websockets.asyncio.client import ClientConnection, connect
from websockets.asyncio.server import ServerConnection, serve
from websockets.datastructures import Headers
from websockets.exceptions import ConnectionClosed
from websockets.http11 import Request, Response
from websockets.typing import Subprotocol

from .errors import DebugGuiError

__all__ = ["SDK_SUBPROTOCOL", "SUBPROTOCOLS", "Gate", "presented_token"]

SDK_SUBPROTOCOL = Subprotocol("foxglove.sdk.v1")
SUBPROTOCOLS = (SDK_SUBPROTOCOL, Subprotocol("foxglove.websocket.v1"))

# Client -> server operations that change something on a robot.
_WRITE_OPS = frozenset({"setParameters", "advertise"})
_CLIENT_MESSAGE_DATA = 0x01
_SERVICE_CALL_REQUEST = 0x02
_STATUS_ERROR = 2
_START_TIMEOUT_S = 10.0
_UNKNOWN_CHANNEL = "Unknown channel ID: "
#: How soon and how often a subscription the SDK's race refused is sent again.
_RESUBSCRIBE_S = 0.05
_RESUBSCRIBE_TRIES = 40


class _Resubscriber:
    """One connection's advertised channels and the viewer's subscriptions, to take a race
    in the SDK's server out of the viewer's way.

    The SDK's server (foxglove-sdk 0.30, ``ConnectedClient::advertise_channels``) sends a
    channel's advertisement first and records the channel as advertised to that client
    afterwards. A viewer that subscribes at once can be answered "Unknown channel ID" for
    the channel it was just offered, when the server's sending thread has not got on yet
    (a loaded machine); the subscription is then dropped and the viewer shows nothing. The
    gate sees both directions: such an answer, for a channel advertised on this connection
    and still subscribed, is not forwarded, and the subscription is sent again shortly
    (at most :data:`_RESUBSCRIBE_TRIES` times). An unknown channel the server never
    advertised here is the viewer's mistake: that answer passes.
    """

    def __init__(self) -> None:
        self.advertised: set[int] = set()
        self.subscriptions: dict[int, dict[str, int]] = {}  # channel id -> {id, channelId}
        self.tries: dict[int, int] = {}
        self.pending: set[asyncio.Future[None]] = set()  # kept until done (asyncio's rule)

    def downstream(self, message: str) -> int | None:
        """Note what the server advertised; the channel to subscribe to again if
        ``message`` is the race's answer (then it must not reach the viewer)."""
        if '"advertise"' not in message and '"unadvertise"' not in message and (
                _UNKNOWN_CHANNEL not in message):
            return None
        try:
            parsed = json.loads(message)
            op = parsed.get("op")
            if op == "advertise":
                self.advertised.update(int(c["id"]) for c in parsed["channels"])
            elif op == "unadvertise":
                for channel in parsed["channelIds"]:
                    self.advertised.discard(int(channel))
                    self.subscriptions.pop(int(channel), None)
            elif op == "status" and str(parsed.get("message", "")).startswith(_UNKNOWN_CHANNEL):
                channel = int(str(parsed["message"]).removeprefix(_UNKNOWN_CHANNEL))
                tries = self.tries.get(channel, 0)
                if (channel in self.advertised and channel in self.subscriptions
                        and tries < _RESUBSCRIBE_TRIES):
                    self.tries[channel] = tries + 1
                    return channel
        except (ValueError, KeyError, TypeError, AttributeError):
            pass  # not ours to judge: forwarded as it came
        return None

    def upstream(self, message: str | bytes) -> None:
        """Note the viewer's subscriptions."""
        if not isinstance(message, str) or "subscribe" not in message:
            return
        try:
            parsed = json.loads(message)
            if parsed.get("op") == "subscribe":
                for sub in parsed["subscriptions"]:
                    self.subscriptions[int(sub["channelId"])] = {
                        "id": int(sub["id"]), "channelId": int(sub["channelId"])}
            elif parsed.get("op") == "unsubscribe":
                gone = {int(i) for i in parsed["subscriptionIds"]}
                self.subscriptions = {c: s for c, s in self.subscriptions.items()
                                      if s["id"] not in gone}
        except (ValueError, KeyError, TypeError, AttributeError):
            pass  # the SDK answers malformed requests itself

    def again(self, channel: int) -> str | None:
        """The subscribe request to send again for ``channel``, if still wanted."""
        sub = self.subscriptions.get(channel)
        if sub is None or channel not in self.advertised:
            return None
        return json.dumps({"op": "subscribe", "subscriptions": [sub]})


def presented_token(request: Request) -> str | None:
    """The token a client presented in its handshake, or None."""
    query = parse_qs(urlsplit(request.path).query)
    if query.get("token"):
        return query["token"][0]
    auth = Headers(request.headers).get("Authorization", "")
    if auth.startswith("Bearer "):
        return auth.removeprefix("Bearer ").strip()
    return None


def _refusal(message: str | bytes, why: str) -> str | None:
    """The protocol message that answers a refused write, or None if it is no write."""
    if isinstance(message, bytes):
        if message[:1] == bytes([_SERVICE_CALL_REQUEST]) and len(message) >= 9:
            service_id, call_id = struct.unpack_from("<II", message, 1)
            return json.dumps({"op": "serviceCallFailure", "serviceId": service_id,
                               "callId": call_id, "message": why})
        if message[:1] == bytes([_CLIENT_MESSAGE_DATA]):
            return json.dumps({"op": "status", "level": _STATUS_ERROR, "message": why})
        return None
    try:
        op = json.loads(message).get("op")
    except (ValueError, AttributeError):
        return None  # the SDK answers malformed JSON itself
    if op in _WRITE_OPS:
        return json.dumps({"op": "status", "level": _STATUS_ERROR, "message": why})
    return None


class Gate:
    """An asyncio WebSocket server in its own thread that forwards to the SDK server.

    ``may_connect(token)`` decides whether a handshake is accepted at all (401 otherwise);
    ``may_write(token)`` whether the connection's writes are forwarded.

    The SDK's server listens on loopback without any check, so a local process could
    connect to it directly and write. To close that door the gate introduces each of its
    connections: its first request is a ``getParameters`` whose id is a fresh nonce, which
    ``introduce(nonce, may_write)`` announced to the endpoint beforehand; the endpoint learns
    the SDK's client id from that request and accepts writes only from clients introduced
    as writers. The gate waits for the answer (and swallows it) before it forwards anything
    the viewer sends.
    """

    def __init__(self, *, host: str, port: int, backend_port: int,
                 may_connect: Callable[[str | None], bool],
                 may_write: Callable[[str | None], bool],
                 introduce: Callable[[str, bool], None]) -> None:
        self._host = host
        self._port = port
        self._backend = f"ws://127.0.0.1:{backend_port}/"
        self._may_connect = may_connect
        self._may_write = may_write
        self._introduce = introduce
        self._loop = asyncio.new_event_loop()
        self._stopping: asyncio.Event | None = None
        self._started = threading.Event()
        self._error: BaseException | None = None
        self._thread = threading.Thread(target=self._run, name="foxglove-gate", daemon=True)
        self.port = 0

    def start(self) -> None:
        """Listen; raises DebugGuiError if the address cannot be bound."""
        self._thread.start()
        if not self._started.wait(_START_TIMEOUT_S):
            raise DebugGuiError("the Foxglove endpoint did not start listening in time")
        if self._error is not None:
            raise DebugGuiError(f"cannot serve Foxglove on {self._host}:{self._port}: "
                                f"{self._error}") from self._error

    def close(self) -> None:
        """Stop listening and drop every connection; idempotent."""
        if self._thread.is_alive() and self._stopping is not None:
            self._loop.call_soon_threadsafe(self._stopping.set)
            self._thread.join(timeout=5.0)

    def _run(self) -> None:
        try:
            self._loop.run_until_complete(self._serve())
        finally:
            self._started.set()
            self._loop.close()

    async def _serve(self) -> None:
        self._stopping = asyncio.Event()
        try:
            server = await serve(
                self._handle, self._host, self._port, subprotocols=list(SUBPROTOCOLS),
                process_request=self._check_handshake, compression=None, max_size=2**24)
        except OSError as exc:
            self._error = exc
            return
        self.port = server.sockets[0].getsockname()[1] if server.sockets else 0
        self._started.set()
        await self._stopping.wait()
        server.close()
        await server.wait_closed()

    def _check_handshake(self, connection: ServerConnection, request: Request) -> Response | None:
        if self._may_connect(presented_token(request)):
            return None
        return connection.respond(
            HTTPStatus.UNAUTHORIZED,
            "this Foxglove endpoint needs the token: ws://HOST:PORT/?token=TOKEN\n")

    async def _handle(self, client: ServerConnection) -> None:
        request = client.request
        writes = request is not None and self._may_write(presented_token(request))
        try:
            async with connect(self._backend, subprotocols=[SDK_SUBPROTOCOL], compression=None,
                               max_size=None, ping_interval=None) as backend:
                link = _Resubscriber()
                await self._introduce_to(backend, client, link, writes=writes)
                down = asyncio.ensure_future(self._pump(backend, client, link))
                up = asyncio.ensure_future(self._pump_up(client, backend, link, writes=writes))
                _, pending = await asyncio.wait({down, up}, return_when=asyncio.FIRST_COMPLETED)
                for task in pending:
                    task.cancel()
        except (OSError, ConnectionClosed, TimeoutError):
            pass  # the SDK server stopped or the viewer left: the connection ends either way

    async def _introduce_to(self, backend: ClientConnection, client: ServerConnection,
                            link: _Resubscriber, *, writes: bool) -> None:
        """Tell the endpoint who this SDK client is; forward what arrives meanwhile."""
        nonce = secrets.token_hex(16)
        self._introduce(nonce, writes)
        await backend.send(json.dumps({"op": "getParameters", "parameterNames": [],
                                       "id": nonce}))
        async with asyncio.timeout(_START_TIMEOUT_S):
            async for message in backend:
                if isinstance(message, str) and nonce in message:
                    return  # the answer to the introduction: the viewer never asked for it
                if isinstance(message, str):
                    link.downstream(message)
                await client.send(message)

    @staticmethod
    async def _pump(source: ClientConnection, sink: ServerConnection,
                    link: _Resubscriber) -> None:
        with contextlib.suppress(ConnectionClosed):
            async for message in source:
                if isinstance(message, str) and (
                        channel := link.downstream(message)) is not None:
                    task = asyncio.ensure_future(Gate._subscribe_again(source, link, channel))
                    link.pending.add(task)
                    task.add_done_callback(link.pending.discard)
                    continue
                await sink.send(message)

    @staticmethod
    async def _subscribe_again(backend: ClientConnection, link: _Resubscriber,
                               channel: int) -> None:
        await asyncio.sleep(_RESUBSCRIBE_S)
        request = link.again(channel)
        if request is not None:
            with contextlib.suppress(ConnectionClosed):
                await backend.send(request)

    @staticmethod
    async def _pump_up(source: ServerConnection, sink: ClientConnection,
                       link: _Resubscriber, *, writes: bool) -> None:
        why = "this connection may not write: present the token (ws://HOST:PORT/?token=TOKEN)"
        with contextlib.suppress(ConnectionClosed):
            async for message in source:
                refusal = None if writes else _refusal(message, why)
                if refusal is None:
                    link.upstream(message)
                    await sink.send(message)
                else:
                    await source.send(refusal)
