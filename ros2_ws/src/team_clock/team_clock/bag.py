"""Reading robots' logs for team_clock; the format itself is rosbag2_layout's.

A log is one ``.mcap`` file or a rosbag2 bag directory; :class:`LogReader` is
rosbag2_layout's :class:`~rosbag2_layout.BagReader` with team_clock's errors (a log that
cannot be read raises :class:`LogFormatError`). Merged logs are written with
rosbag2_layout's :class:`~rosbag2_layout.BagWriter`, re-exported here.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from dataclasses import dataclass

from rosbag2_layout import BagReader, BagWriter, Rosbag2Error
from rosbag2_layout.reader import Record

from .errors import LogFormatError

__all__ = ["BagWriter", "LogReader", "log_errors"]


@contextlib.contextmanager
def log_errors() -> Iterator[None]:
    """rosbag2_layout's reading errors as :class:`LogFormatError` (team_clock's root)."""
    try:
        yield
    except Rosbag2Error as exc:
        raise LogFormatError(str(exc)) from exc


@dataclass
class LogReader(BagReader):
    """A robot's log; see :class:`rosbag2_layout.BagReader` (``truncated``, ``problems``)."""

    def __post_init__(self) -> None:
        with log_errors():
            super().__post_init__()

    def records(self, *, topics: list[str] | None = None, start_ns: int | None = None,
                end_ns: int | None = None) -> Iterator[Record]:
        with log_errors():
            yield from super().records(topics=topics, start_ns=start_ns, end_ns=end_ns)

    def topics(self) -> set[str]:
        with log_errors():
            return super().topics()

    def metadata(self) -> Iterator[tuple[str, dict[str, str]]]:
        with log_errors():
            yield from super().metadata()
