"""``--port 0``: the port chosen is the web server's, not the next process's."""

from __future__ import annotations

import errno
import socket

import pytest

from debug_gui.server import free_port


def test_a_free_port_is_held_for_a_server_binding_it_with_reuseaddr() -> None:
    port = free_port("127.0.0.1")
    # Another process binding that port as plain sockets do (and so bind(0) and outgoing
    # connections, which skip ports in use) cannot have it ...
    with socket.socket() as other, pytest.raises(OSError) as refused:
        other.bind(("127.0.0.1", port))
    assert refused.value.errno == errno.EADDRINUSE
    # ... while the web server, binding with SO_REUSEADDR as uvicorn does, gets it at once.
    with socket.socket() as server:
        server.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        server.bind(("127.0.0.1", port))
        server.listen(1)
        with socket.create_connection(("127.0.0.1", port), timeout=5):
            accepted, _ = server.accept()
            accepted.close()
