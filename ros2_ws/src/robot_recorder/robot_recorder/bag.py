"""Reading recorded bags back, for robot_recorder's users (the format is rosbag2_layout's).

:func:`read_messages` yields every readable message, also of files a killed recorder cut
short; :func:`recover` writes a complete bag from such a bag. Both are rosbag2_layout's,
with robot_recorder's errors (:class:`PlaybackError` for a bag that cannot be read).
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterable, Iterator
from pathlib import Path

from rosbag2_layout import BagMessage, BagReader, QosDict, Rosbag2Error
from rosbag2_layout import mcap_files as _mcap_files
from rosbag2_layout import recover as _recover
from rosbag2_layout import reindex as _reindex

from .errors import PlaybackError

__all__ = ["BagMessage", "mcap_files", "offered_qos", "read_messages", "read_metadata_records",
           "recover", "reindex", "unfinished_files"]


@contextlib.contextmanager
def _playback_errors() -> Iterator[None]:
    try:
        yield
    except Rosbag2Error as exc:
        raise PlaybackError(str(exc)) from exc


def read_messages(
    bag: str | Path,
    *,
    topics: Iterable[str] | None = None,
    problems: list[str] | None = None,
) -> Iterator[BagMessage]:
    """Every readable message in log-time order (files cut short: as written).

    Pass a list as ``problems`` to learn which files ended early and where.
    """
    with _playback_errors():
        reader = BagReader(Path(bag))
        try:
            yield from reader.messages(topics=list(topics) if topics is not None else None)
        finally:
            if problems is not None:
                problems.extend(reader.problems)


def mcap_files(bag: str | Path) -> list[Path]:
    """The MCAP files of a bag in recording order (``[bag]`` for one file)."""
    with _playback_errors():
        return _mcap_files(bag)


def read_metadata_records(bag: str | Path) -> dict[str, dict[str, str]]:
    """MCAP metadata records by name (later files win), e.g. ``"team_clock"``."""
    with _playback_errors():
        return BagReader(Path(bag)).metadata_records()


def offered_qos(bag: str | Path) -> dict[str, list[QosDict]]:
    """The QoS profiles each topic's publishers offered when it was recorded."""
    with _playback_errors():
        return {name: t.qos_profiles for name, t in BagReader(Path(bag)).topic_records().items()}


def recover(bag: str | Path, out: str | Path) -> int:
    """Write every readable message of ``bag`` as a complete bag ``out``; returns the count.

    A missing or unreadable ``bag`` raises :class:`PlaybackError` and leaves no ``out``.
    """
    with _playback_errors():
        return _recover(bag, out)


def reindex(bag: str | Path) -> int:
    """Make bag directory ``bag`` whole where it is (file names kept); returns the count."""
    with _playback_errors():
        return _reindex(bag)


def unfinished_files(bag: str | Path) -> list[Path]:
    """The bag's files whose writer did not finish them (killed, or still recording)."""
    with _playback_errors():
        return BagReader(Path(bag)).unfinished()
