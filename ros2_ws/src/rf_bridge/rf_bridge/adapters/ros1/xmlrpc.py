"""The ROS 1 master and slave APIs over XML-RPC (standard library only).

The master tells the bridge who publishes what; every ROS 1 node, the bridge included, runs
a small "slave" XML-RPC server through which the master announces new publishers
(``publisherUpdate``) and subscribers ask for a data connection (``requestTopic``).
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

from ...errors import LinkError


class MasterRefusedError(LinkError):
    """The remote end answered, but with an error code (e.g. it does not know us)."""


Reply = list[Any]  # [code, status message, value], as every ROS 1 API call returns


class _Transport(xmlrpc.client.Transport):
    def __init__(self, timeout_s: float) -> None:
        super().__init__()
        self._timeout = timeout_s

    def make_connection(self, host: Any) -> http.client.HTTPConnection:
        conn = super().make_connection(host)
        conn.timeout = self._timeout
        return conn


def call(uri: str, method: str, *args: Any, timeout_s: float = 2.0) -> Any:
    """Call a ROS 1 API method and return its value; LinkError if unreachable or refused.

    A new proxy per call: ServerProxy is not thread-safe and calls are rare.
    """
    try:
        with xmlrpc.client.ServerProxy(uri, transport=_Transport(timeout_s)) as proxy:
            code, status, value = getattr(proxy, method)(*args)
    except (OSError, xmlrpc.client.Error, http.client.HTTPException, ValueError) as exc:
        raise LinkError(f"{method} on {uri}: {exc}") from None
    if code != 1:
        raise MasterRefusedError(f"{method} on {uri} refused: {status}")
    return value


class _Quiet(SimpleXMLRPCRequestHandler):
    def log_message(self, format: str, *args: Any) -> None:
        pass


class _Server(ThreadingMixIn, SimpleXMLRPCServer):
    daemon_threads = True


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
    ) -> None:
        self._server = _Server(
            (host, 0), requestHandler=_Quiet, logRequests=False, allow_none=False
        )
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
        self._on_publishers(topic, list(publishers))
        return [1, "", 0]

    def requestTopic(self, caller_id: Any, topic: Any, protocols: Any) -> Reply:  # noqa: N802
        try:
            return [1, "ready", self._on_request(topic, protocols)]
        except LookupError as exc:
            return [0, str(exc), []]

    def close(self) -> None:
        self._server.shutdown()
        self._server.server_close()
