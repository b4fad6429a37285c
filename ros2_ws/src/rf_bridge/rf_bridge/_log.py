"""Log lines that cannot flood: a misbehaving peer repeating one fault is reported once a
second with the number of repeats, so the log stays readable and nothing is hidden.

Each level calls the logger from its own line: rclpy's logger remembers the severity of
every call site and raises ``ValueError`` when one site logs at another severity, so a
single ``getattr(logger, level)(...)`` line would break the second level used.
"""

from __future__ import annotations

import threading
import time
from typing import Any, Protocol


class Logger(Protocol):
    def debug(self, message: str, /) -> Any: ...

    def info(self, message: str, /) -> Any: ...

    def warning(self, message: str, /) -> Any: ...

    def error(self, message: str, /) -> Any: ...


class RateLimitedLog:
    def __init__(self, logger: Logger, *, period_s: float = 1.0) -> None:
        self._logger = logger
        self._period = period_s
        self._last: dict[str, tuple[float, int]] = {}
        self._lock = threading.Lock()

    def _text(self, message: str) -> str | None:
        """The line to log (with the repeats held back since the last one), or None while
        the same message is being held back."""
        now = time.monotonic()
        with self._lock:
            last, repeats = self._last.get(message, (-1e9, 0))
            if now - last < self._period:
                self._last[message] = (last, repeats + 1)
                return None
            self._last[message] = (now, 0)
            if len(self._last) > 1000:
                self._last.clear()
        return message + (f" (and {repeats} more like it)" if repeats else "")

    def debug(self, message: str) -> None:
        if (text := self._text(message)) is not None:
            self._logger.debug(text)

    def info(self, message: str) -> None:
        if (text := self._text(message)) is not None:
            self._logger.info(text)

    def warning(self, message: str) -> None:
        if (text := self._text(message)) is not None:
            self._logger.warning(text)

    def error(self, message: str) -> None:
        if (text := self._text(message)) is not None:
            self._logger.error(text)
