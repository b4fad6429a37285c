"""The future a client's ``call_async`` returns, on every backend.

rclpy's own future runs done-callbacks either as executor tasks (where an exception escapes
from ``spin``) or directly (where it becomes a warning). Components deserve one behaviour:
done-callbacks run in the executor thread, are timed, and an exception in one is logged and
counted like any other callback's.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

Invoker = Callable[[Callable[["Future"], None], "Future"], None]


class Future:
    """A single-threaded future: completed and observed in the executor thread."""

    __slots__ = ("_callbacks", "_done", "_exception", "_invoke", "_result")

    def __init__(self, invoke: Invoker) -> None:
        self._invoke = invoke
        self._callbacks: list[Callable[[Future], None]] = []
        self._done = False
        self._result: Any = None
        self._exception: BaseException | None = None

    def done(self) -> bool:
        return self._done

    def result(self) -> Any:
        """The response (None while pending); re-raises the call's exception if it failed."""
        if self._exception is not None:
            raise self._exception
        return self._result

    def exception(self) -> BaseException | None:
        return self._exception

    def add_done_callback(self, callback: Callable[[Future], None]) -> None:
        if self._done:
            self._invoke(callback, self)
        else:
            self._callbacks.append(callback)

    def set_result(self, result: Any) -> None:
        self._result = result
        self._finish()

    def set_exception(self, exception: BaseException) -> None:
        self._exception = exception
        self._finish()

    def _finish(self) -> None:
        self._done = True
        callbacks, self._callbacks = self._callbacks, []
        for callback in callbacks:
            self._invoke(callback, self)
