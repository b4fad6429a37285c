"""Who may reach the GUI and who may change robots, and validation of everything typed in.

The rules: the server binds loopback unless told otherwise; serving beyond loopback needs a
token (anyone on the network could otherwise drive the robots); writes (parameters,
recorder control, saving layouts) always need the token. On loopback without ``--token``
the server makes one up and prints it in the URL, as Jupyter does, so the person who
started it can write and a page opened without it is read-only.
"""

from __future__ import annotations

import hmac
import ipaddress
import math
import re
import secrets
from dataclasses import dataclass

from .errors import AccessDenied, InvalidInput
from .robots import check_domain

_TOKEN = re.compile(r"^[A-Za-z0-9._~-]{8,128}$")
_NAME = re.compile(r"^/?[A-Za-z_][A-Za-z0-9_]*(/[A-Za-z_][A-Za-z0-9_]*)*$")
#: Highest display rate a view may ask for (a browser repaints at 60 Hz at best).
MAX_RATE_HZ = 1000.0


def is_loopback(host: str) -> bool:
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def check_token(token: str) -> str:
    if not _TOKEN.match(token):
        raise InvalidInput(
            "a token is 8 to 128 characters of letters, digits and . _ ~ - (URL-safe)"
        )
    return token


@dataclass(frozen=True, slots=True)
class AccessPolicy:
    """Bind address and token; :meth:`for_server` checks the combination."""

    host: str
    token: str
    #: The token was chosen by whoever started the server (not made up for loopback).
    explicit_token: bool

    @classmethod
    def for_server(cls, *, host: str = "127.0.0.1", token: str | None = None) -> AccessPolicy:
        """Policy for ``--host``/``--token``; InvalidInput where the combination is unsafe."""
        if not host or any(c.isspace() for c in host):
            raise InvalidInput(f"not a host to bind: {host!r}")
        if token is not None:
            check_token(token)
        if not is_loopback(host) and token is None:
            raise InvalidInput(
                f"--host {host} serves beyond this machine: give --token TOKEN too "
                "(writes and pages then need it)"
            )
        return cls(host=host, token=token or secrets.token_urlsafe(16),
                   explicit_token=token is not None)

    @property
    def loopback(self) -> bool:
        return is_loopback(self.host)

    def valid(self, token: str | None) -> bool:
        return token is not None and hmac.compare_digest(
            token.encode("utf-8", "replace"), self.token.encode()
        )

    def check_write(self, token: str | None) -> None:
        """Raise AccessDenied unless ``token`` is the server's token."""
        if not self.valid(token):
            raise AccessDenied("this change needs the server's token (open the URL it printed)")

    def check_read(self, token: str | None) -> None:
        """Beyond loopback, even looking needs the token."""
        if not self.loopback and not self.valid(token):
            raise AccessDenied("this server needs its token: open the URL it printed")


def check_name(name: object, *, what: str = "name") -> str:
    """A ROS topic, service or node name (relative or absolute), else InvalidInput."""
    if not isinstance(name, str) or not _NAME.match(name) or "//" in name:
        raise InvalidInput(f"not a valid ROS {what}: {name!r}")
    return name


def check_rate(rate_hz: object) -> float | None:
    """A display rate: None (everything) or a number in (0, MAX_RATE_HZ]."""
    if rate_hz is None:
        return None
    if isinstance(rate_hz, bool) or not isinstance(rate_hz, int | float) or not (
        math.isfinite(rate_hz) and 0 < rate_hz <= MAX_RATE_HZ
    ):
        raise InvalidInput(f"a rate is a number in (0, {MAX_RATE_HZ:g}] Hz, not {rate_hz!r}")
    return float(rate_hz)


def check_port(port: object) -> int:
    """A TCP port (0 = pick a free one)."""
    if isinstance(port, bool) or not isinstance(port, int) or not 0 <= port <= 65535:
        raise InvalidInput(f"a port is an integer 0..65535, not {port!r}")
    return port


def parse_domains(text: str) -> list[int]:
    """``"0,5"`` -> ``[0, 5]`` (distinct, validated)."""
    out: list[int] = []
    for part in text.split(","):
        part = part.strip()
        if not part.isdigit():
            raise InvalidInput(f"domains are comma-separated integers, not {text!r}")
        domain = check_domain(int(part))
        if domain not in out:
            out.append(domain)
    if not out:
        raise InvalidInput("no domain given")
    return out
