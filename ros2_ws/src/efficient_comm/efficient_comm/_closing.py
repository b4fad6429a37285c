"""One way for resources to be context managers: ``with X(...) as x:`` closes ``x`` on exit."""

from __future__ import annotations

from types import TracebackType
from typing import Self


class Closing:
    """Base for resources that release what they hold in :meth:`close`."""

    def close(self) -> None:
        raise NotImplementedError

    def __enter__(self) -> Self:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()
