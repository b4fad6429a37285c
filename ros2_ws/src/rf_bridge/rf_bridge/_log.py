"""Log lines that cannot flood: a misbehaving peer repeating one fault is reported once a
second with the number of repeats, so the log stays readable and nothing is hidden."""

from __future__ import annotations

import threading
import time
from typing import Any, Protocol


class Logger(Protocol):
    def info(self, message: str, /) -> Any: ...

    def warning(self, message: str, /) -> Any: ...

    def error(self, message: str, /) -> Any: ...


class RateLimitedLog:
    def __init__(self, logger: Logger, *, period_s: float = 1.0) -> None:
        self._logger = logger
        self._period = period_s
        self._last: dict[str, tuple[float, int]] = {}
        self._lock = threading.Lock()

    def _emit(self, level: str, message: str) -> None:
        now = time.monotonic()
        with self._lock:
            last, repeats = self._last.get(message, (-1e9, 0))
            if now - last < self._period:
                self._last[message] = (last, repeats + 1)
                return
            self._last[message] = (now, 0)
            if len(self._last) > 1000:
                self._last.clear()
        suffix = f" (and {repeats} more like it)" if repeats else ""
        getattr(self._logger, level)(message + suffix)

    def info(self, message: str) -> None:
        self._emit("info", message)

    def warning(self, message: str) -> None:
        self._emit("warning", message)

    def error(self, message: str) -> None:
        self._emit("error", message)
