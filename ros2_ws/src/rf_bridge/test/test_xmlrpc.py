"""The ROS 1 node API under hostile callers: bounded bodies, checked arguments, idle
connections closed, replies of unbounded size refused (no ROS 1 system needed)."""

from __future__ import annotations

import http.client
import select
import socket
import threading
import time
from collections.abc import Iterator
from typing import Any

import pytest
import rclpy.logging

from rf_bridge._log import RateLimitedLog
from rf_bridge.adapters.ros1 import xmlrpc
from rf_bridge.errors import LinkError
from rf_bridge.testing import CapturedLogs, wait_for


@pytest.fixture
def server(
    capfd: pytest.CaptureFixture[str],
) -> Iterator[tuple[xmlrpc.SlaveServer, CapturedLogs, list[Any]]]:
    records = CapturedLogs(capfd)
    updates: list[Any] = []
    slave = xmlrpc.SlaveServer(
        host="127.0.0.1",
        advertise_host="127.0.0.1",
        master_uri="http://127.0.0.1:1/",
        on_publishers=lambda topic, uris: updates.append((topic, uris)),
        on_request=lambda topic, protocols: ["TCPROS", "127.0.0.1", 1],
        publications=list,
        subscriptions=list,
        log=RateLimitedLog(rclpy.logging.get_logger("rf_bridge_test")),
    )
    try:
        yield slave, records, updates
    finally:
        slave.close()


def test_arguments_are_checked_before_the_adapter_sees_them(server: Any) -> None:
    slave, records, updates = server
    assert xmlrpc.call(slave.uri, "publisherUpdate", "/m", "/t", ["http://127.0.0.1:2/"]) == 0
    assert updates == [("/t", ["http://127.0.0.1:2/"])]
    with pytest.raises(xmlrpc.MasterRefusedError, match="bad arguments"):
        xmlrpc.call(slave.uri, "publisherUpdate", "/m", "/t", [1, 2])
    with pytest.raises(xmlrpc.MasterRefusedError, match="bad arguments"):
        xmlrpc.call(slave.uri, "requestTopic", "/m", ["/t"], [["TCPROS"]])
    assert updates == [("/t", ["http://127.0.0.1:2/"])]
    assert records.wait("refusing an XML-RPC call from '/m'")


def test_oversize_request_refused_before_it_is_read(server: Any) -> None:
    slave, records, _ = server
    port = int(slave.uri.rsplit(":", 1)[1].strip("/"))
    conn = http.client.HTTPConnection("127.0.0.1", port, timeout=5)
    conn.putrequest("POST", "/RPC2")
    conn.putheader("Content-Length", str(xmlrpc.MAX_XMLRPC_BYTES + 1))
    conn.endheaders()  # no body follows: the answer must not wait for it
    assert conn.getresponse().status == 413
    conn.close()
    assert records.wait("refusing an XML-RPC request")
    assert xmlrpc.call(slave.uri, "getPid", "/m") > 0  # still serving


def test_idle_connection_is_closed(server: Any, monkeypatch: pytest.MonkeyPatch) -> None:
    slave, _, _ = server
    monkeypatch.setattr(xmlrpc._Handler, "timeout", 0.2)
    port = int(slave.uri.rsplit(":", 1)[1].strip("/"))
    with socket.create_connection(("127.0.0.1", port), timeout=5) as idle:
        idle.sendall(b"POST /RPC2 HTTP/1.1\r\n")  # and nothing more
        assert idle.recv(4096) == b""  # closed by the server (the client waits up to 5 s)


def test_connections_beyond_the_limit_are_refused(server: Any) -> None:
    slave, records, _ = server
    port = int(slave.uri.rsplit(":", 1)[1].strip("/"))
    held = [
        socket.create_connection(("127.0.0.1", port), timeout=5)
        for _ in range(xmlrpc.MAX_XMLRPC_CONNECTIONS)
    ]
    try:  # the server accepts in order: the held ones took every slot before this one
        with socket.create_connection(("127.0.0.1", port), timeout=5) as extra:
            assert extra.recv(100) == b""
        assert records.wait("already open")
    finally:
        for s in held:
            s.close()
    assert wait_for(lambda: _answers(slave.uri), 10)  # slots come back


def _answers(uri: str) -> bool:
    try:
        return int(xmlrpc.call(uri, "getPid", "/m")) > 0
    except LinkError:
        return False


def test_reply_larger_than_the_limit_is_a_link_error() -> None:
    body = b"<?xml version='1.0'?><methodResponse>" + b" " * (xmlrpc.MAX_XMLRPC_BYTES + 10)
    with socket.create_server(("127.0.0.1", 0)) as listener:
        port = listener.getsockname()[1]

        def answer() -> None:
            conn, _ = listener.accept()
            with conn:
                request = b""
                while b"</methodCall>" not in request:  # all of it: unread bytes reset
                    chunk = conn.recv(65536)
                    if not chunk:
                        return
                    request += chunk
                conn.sendall(b"HTTP/1.0 200 OK\r\nContent-Type: text/xml\r\n\r\n" + body)

        thread = threading.Thread(target=answer, daemon=True)
        thread.start()
        with pytest.raises(LinkError, match="reply larger than"):
            xmlrpc.call(f"http://127.0.0.1:{port}/", "getPid", "/m")
        thread.join(timeout=10)


def test_a_trickling_client_is_cut_off_at_the_total_deadline(
    server: Any, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A byte every 200 ms never trips the idle timeout (5 s); the total deadline closes
    the connection anyway, and its slot serves others again."""
    slave, records, _ = server
    monkeypatch.setattr(xmlrpc, "XMLRPC_DEADLINE_S", 1.0)
    port = int(slave.uri.rsplit(":", 1)[1].strip("/"))
    request = b"POST /RPC2 HTTP/1.0\r\nContent-Type: text/xml\r\nX-Slow: " + b"a" * 100
    start = time.monotonic()
    with socket.create_connection(("127.0.0.1", port), timeout=5) as slow:
        closed = False
        for byte in request:
            try:
                slow.sendall(bytes((byte,)))
            except OSError:  # reset by the server
                closed = True
                break
            readable, _, _ = select.select([slow], [], [], 0.2)
            if readable:
                closed = slow.recv(100) == b""
                break
        elapsed = time.monotonic() - start
    assert closed, "the server kept the trickling connection open"
    assert 0.9 < elapsed < 3.0, elapsed
    assert records.wait("not done within 1 s")
    assert xmlrpc.call(slave.uri, "getPid", "/m") > 0
