"""The ROS 1 master and slave APIs over XML-RPC (standard library only).

The master tells the bridge who publishes what; every ROS 1 node, the bridge included, runs
a small "slave" XML-RPC server through which the master announces new publishers
(``publisherUpdate``) and subscribers ask for a data connection (``requestTopic``).

Anyone who can reach these sockets can talk to them (ROS 1 has no authentication), so both
ends are bounded: requests and replies are limited in size before they are parsed, every
socket operation has a timeout and every connection to the server a total deadline (a
client trickling its request a byte at a time is cut off), the server serves a limited
number of connections at once, and arguments are checked before the adapter sees them.
"""

from __future__ import annotations

import http.client
import os
import threading
import xmlrpc.client
from collections.abc import Callable
from socketserver import ThreadingMixIn
from typing import Any
from xmlrpc.server import SimpleXMLRPCRequestHandler, SimpleXMLRPCServer

from ..._log import RateLimitedLog
from ...errors import LinkError
from ._deadline import deadline

#: Largest XML-RPC request or reply accepted; ROS 1 API calls are a few kilobytes.
MAX_XMLRPC_BYTES = 1 << 20
#: Connections the node API serves at once; more are refused until one finishes.
MAX_XMLRPC_CONNECTIONS = 32
#: Seconds a connection to the node API may sit idle before it is closed.
XMLRPC_TIMEOUT_S = 5.0
#: Seconds a connection to the node API may last in all, however busy: a request of a few
#: kilobytes takes milliseconds.
XMLRPC_DEADLINE_S = 10.0


class MasterRefusedError(LinkError):
    """The remote end answered, but with an error code (e.g. it does not know us)."""


Reply = list[Any]  # [code, status message, value], as every ROS 1 API call returns


class _Transport(xmlrpc.client.Transport):
    """A timeout on every socket operation and a reply read in bounded pieces (no gzip,
    whose expansion could not be bounded before parsing)."""

    accept_gzip_encoding = False

    def __init__(self, timeout_s: float) -> None:
        super().__init__()
        self._timeout = timeout_s

    def make_connection(self, host: Any) -> http.client.HTTPConnection:
        conn = super().make_connection(host)
        conn.timeout = self._timeout
        return conn

    def parse_response(self, response: http.client.HTTPResponse) -> Any:
        parser, unmarshaller = self.getparser()
        total = 0
        while data := response.read(65536):
            total += len(data)
            if total > MAX_XMLRPC_BYTES:
                raise ValueError(f"reply larger than {MAX_XMLRPC_BYTES} bytes")
            parser.feed(data)
        parser.close()
        return unmarshaller.close()


def call(uri: str, method: str, *args: Any, timeout_s: float = 2.0) -> Any:
    """Call a ROS 1 API method and return its value; LinkError if unreachable or refused.

    A new proxy per call: ServerProxy is not thread-safe and calls are rare.
    """
    try:
        with xmlrpc.client.ServerProxy(uri, transport=_Transport(timeout_s)) as proxy:
            code, status, value = getattr(proxy, method)(*args)
    except (OSError, xmlrpc.client.Error, http.client.HTTPException, ValueError, TypeError) as exc:
        raise LinkError(f"{method} on {uri}: {exc}") from None
    if code != 1:
        raise MasterRefusedError(f"{method} on {uri} refused: {status}")
    return value


class _Handler(SimpleXMLRPCRequestHandler):
    """Refuses a request body over the limit before reading it; quiet otherwise (the
    standard handler logs every request to stderr)."""

    timeout = XMLRPC_TIMEOUT_S
    server: _Server

    def do_POST(self) -> None:  # noqa: N802 (the http.server name)
        length = self.headers.get("content-length", "")
        if not length.isdigit() or int(length) > MAX_XMLRPC_BYTES:
            self.server.log.warning(
                f"refusing an XML-RPC request from {self.client_address[0]}: body of "
                f"{length or 'unknown'} bytes (limit {MAX_XMLRPC_BYTES})"
            )
            self.send_error(413 if length.isdigit() else 411)
            return
        super().do_POST()

    def log_message(self, format: str, *args: Any) -> None:
        pass


class _Server(ThreadingMixIn, SimpleXMLRPCServer):
    daemon_threads = True
    block_on_close = False
    request_queue_size = 2 * MAX_XMLRPC_CONNECTIONS  # a burst is refused in words, not stalled

    def __init__(self, address: tuple[str, int], log: RateLimitedLog) -> None:
        super().__init__(address, requestHandler=_Handler, logRequests=False, allow_none=False)
        self.log = log
        self._slots = threading.BoundedSemaphore(MAX_XMLRPC_CONNECTIONS)

    def process_request(self, request: Any, client_address: Any) -> None:
        if not self._slots.acquire(blocking=False):
            self.log.warning(
                f"refusing an XML-RPC connection from {client_address[0]}: "
                f"{MAX_XMLRPC_CONNECTIONS} already open"
            )
            self.shutdown_request(request)
            return
        super().process_request(request, client_address)

    def process_request_thread(self, request: Any, client_address: Any) -> None:
        try:
            with deadline(request, XMLRPC_DEADLINE_S) as expired:
                super().process_request_thread(request, client_address)
            if expired.is_set():
                self.log.warning(
                    f"closed an XML-RPC connection from {client_address[0]}: not done within "
                    f"{XMLRPC_DEADLINE_S:g} s"
                )
        finally:
            self._slots.release()


class SlaveServer:
    """The bridge's node API. ``on_publishers(topic, uris)`` and ``on_request(topic,
    protocols)`` (returns a protocol reply or raises LookupError) come from the adapter."""

    def __init__(
        self,
        *,
        host: str,
        advertise_host: str,
        master_uri: str,
        on_publishers: Callable[[str, list[str]], None],
        on_request: Callable[[str, list[list[Any]]], list[Any]],
        publications: Callable[[], list[list[str]]],
        subscriptions: Callable[[], list[list[str]]],
        log: RateLimitedLog,
    ) -> None:
        self._log = log
        self._server = _Server((host, 0), log)
        port = self._server.server_address[1]
        self.uri = f"http://{advertise_host}:{port}/"
        self._master_uri = master_uri
        self._on_publishers = on_publishers
        self._on_request = on_request
        self._publications = publications
        self._subscriptions = subscriptions
        s = self._server
        s.register_function(self.publisherUpdate, "publisherUpdate")
        s.register_function(self.requestTopic, "requestTopic")
        s.register_function(lambda caller: [1, "", self._master_uri], "getMasterUri")
        s.register_function(lambda caller: [1, "", os.getpid()], "getPid")
        s.register_function(lambda caller: [1, "", self._publications()], "getPublications")
        s.register_function(lambda caller: [1, "", self._subscriptions()], "getSubscriptions")
        s.register_function(lambda caller: [1, "", []], "getBusInfo")
        s.register_function(lambda caller: [1, "", [[], [], []]], "getBusStats")
        s.register_function(lambda caller, key, value: [1, "", 0], "paramUpdate")
        s.register_function(
            lambda caller, msg="": [1, "ignored: the bridge stops with its host", 0], "shutdown"
        )
        self._thread = threading.Thread(target=s.serve_forever, name="ros1-slave", daemon=True)
        self._thread.start()

    def publisherUpdate(self, caller_id: Any, topic: Any, publishers: Any) -> Reply:  # noqa: N802
        if (
            not isinstance(topic, str)
            or not isinstance(publishers, list)
            or not all(isinstance(uri, str) for uri in publishers)
        ):
            return self._bad(caller_id, "publisherUpdate(caller_id, topic, [uri, ...])")
        self._on_publishers(topic, publishers)
        return [1, "", 0]

    def requestTopic(self, caller_id: Any, topic: Any, protocols: Any) -> Reply:  # noqa: N802
        if not isinstance(topic, str) or not isinstance(protocols, list):
            return self._bad(caller_id, "requestTopic(caller_id, topic, [[protocol, ...], ...])")
        try:
            return [1, "ready", self._on_request(topic, protocols)]
        except LookupError as exc:
            return [0, str(exc), []]

    def _bad(self, caller_id: Any, expected: str) -> Reply:
        self._log.warning(f"refusing an XML-RPC call from {caller_id!r}: expected {expected}")
        return [-1, f"bad arguments: expected {expected}", 0]

    def close(self) -> None:
        self._server.shutdown()
        self._server.server_close()
        self._thread.join(timeout=5.0)
