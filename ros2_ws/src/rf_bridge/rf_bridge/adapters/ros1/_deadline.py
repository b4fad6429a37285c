"""A total deadline for a socket exchange with an untrusted peer.

A timeout per socket operation does not bound an exchange: a peer sending one byte every
few hundred milliseconds never lets an operation time out, and holds a connection slot
for as long as it likes. The deadline shuts the socket down when the exchange has not
finished in time, which wakes whatever thread is blocked on it.
"""

from __future__ import annotations

import contextlib
import socket
import threading
from collections.abc import Iterator


@contextlib.contextmanager
def deadline(sock: socket.socket, seconds: float) -> Iterator[threading.Event]:
    """Shut ``sock`` down unless the block ends within ``seconds``; the event it yields
    is set when that happened (so the caller can say why the exchange failed)."""
    expired = threading.Event()

    def expire() -> None:
        expired.set()
        with contextlib.suppress(OSError):
            sock.shutdown(socket.SHUT_RDWR)

    timer = threading.Timer(seconds, expire)
    timer.daemon = True
    timer.start()
    try:
        yield expired
    finally:
        timer.cancel()
