"""A team log written from plain messages, for testing event generators (ours and users').

    with LogBuilder(tmp_path / "log") as log:
        log.add("blue1", "fall/state", String(data="fallen"), t=3.0)
        log.add("world", "game_state", state, t=3.5)
    found = detect(TeamLog(tmp_path / "log"), [Falls()])

Topics land as a match's merged log has them (``/blue1/fall/state``); times are seconds
from ``epoch_s``. The log is a real rosbag2 bag (rosbag2_layout writes it), so a
generator tested on it reads a recorded match the same way.
"""

from __future__ import annotations

import os
from pathlib import Path
from types import TracebackType
from typing import Any

from rclpy.serialization import serialize_message

from rosbag2_layout import BagWriter, type_name

__all__ = ["LogBuilder"]


class LogBuilder:
    """Writes a merged-log-shaped bag at ``path``; messages may come in any order (the
    reader orders them by time). A context manager (closes on exit)."""

    def __init__(self, path: str | os.PathLike[str], *, epoch_s: float = 1000.0) -> None:
        self._epoch_ns = int(epoch_s * 1e9)
        self._writer = BagWriter(Path(path), min_free_bytes=0, chunk_bytes=4096)

    def add(self, robot: str, topic: str, msg: Any, *, t: float) -> None:
        """``msg`` on ``/<robot>/<topic>`` (``robot=""``: at the root) at ``t`` seconds."""
        name = f"/{robot}/{topic}" if robot else f"/{topic.lstrip('/')}"
        self._writer.write(name, type_name(type(msg)), bytes(serialize_message(msg)),
                           self.ns(t))

    def ns(self, t: float) -> int:
        """The log time of ``t`` seconds."""
        return self._epoch_ns + round(t * 1e9)

    def close(self) -> None:
        self._writer.close()

    def __enter__(self) -> LogBuilder:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()
