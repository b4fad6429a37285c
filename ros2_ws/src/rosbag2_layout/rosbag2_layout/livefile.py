"""An MCAP file that is complete at every moment, so a recorder killed at any point leaves a
file that every MCAP reader opens with everything handed to the operating system.

MCAP readers find a file's end by its footer and closing magic; a file whose writer was
killed has neither, and mcap's seeking reader, rosbags and rosbag2 refuse it (our own
reader and ``recover`` could read it, other people's tools could not). So this stream keeps
the file's tail valid throughout:

``magic, header, records ..., PAD, footer(summary_start=0), magic``

PAD is a private record (opcode 0x80; MCAP readers skip opcodes they do not know) that
covers the space between the last written record and the footer. A footer without a
summary tells every reader to read the records in order (mcap's ``SeekingReader`` falls
back to its non-seeking reader, rosbags scans). New records go where PAD starts, in an
order that leaves a readable file after each system call:

1. if the records do not fit, a footer is written further on (the file grows; a reader
   still stops at the old footer, beyond which nothing was written yet), then PAD's
   length is changed to reach the new one;
2. a new PAD header is written where the new records will end (inside the old PAD);
3. the records except their first 9 bytes (opcode and length of the first one) are
   written (inside the old PAD, so invisible);
4. the first record's length goes over PAD's length: PAD now skips just the first record,
   and the others (message indexes) are read as they are;
5. its opcode goes over PAD's: the first record (the chunk) is visible.

A SIGKILL ends a large ``write`` at a page boundary at the most; steps 1, 4 and 5 write
at most 37 bytes each, and the footer is placed so as not to cross a page boundary.
:meth:`LiveMcapStream.close` writes the summary the same way and then cuts the file to
its end, so a finished file is a plain MCAP file with summary and footer, as mcap's writer
makes it (physical offsets equal the writer's, which it stores in its indexes).
"""

from __future__ import annotations

import struct
from typing import IO

__all__ = ["PAD_OPCODE", "LiveMcapStream"]

#: The private opcode of the padding record (0x80-0xFF are reserved for private records).
PAD_OPCODE = 0x80
_MAGIC = b"\x89MCAP0\r\n"
_HEADER_LEN = 9  # opcode (1) + record length (8)
_TAIL_LEN = 1 + 8 + 20 + len(_MAGIC)  # footer record and the closing magic
_PAGE = 4096


def _footer() -> bytes:
    # Footer: opcode 0x02, length 20, summary_start 0, summary_offset_start 0, summary_crc 0.
    return struct.pack("<BQQQI", 0x02, 20, 0, 0, 0) + _MAGIC


def _pad_header(length: int) -> bytes:
    return struct.pack("<BQ", PAD_OPCODE, length)


class LiveMcapStream:
    """The output stream of :class:`mcap.writer.Writer` for a file killed-safe at any point.

    Between ``start`` and ``finish`` the writer writes whole records (a closed chunk, its
    message indexes), each made part of the file at once; :meth:`flush` after ``start``
    writes the first valid file. Set :attr:`finishing` before the writer's ``finish``, and
    :meth:`close` after it makes the file a finished one.
    """

    def __init__(self, file: IO[bytes]) -> None:
        """``file``: opened for writing, empty, seekable (``FileSystem.open_new``'s)."""
        self._file = file
        self._pending = bytearray()
        self._pos = 0  # logical end: bytes the writer has written, as it counts them
        self._committed = 0  # bytes of the file that are records (PAD starts here)
        self._footer_at = 0  # where the footer starts (PAD ends here)
        self._started = False
        #: Set before the writer's ``finish``: its summary is placed whole by :meth:`close`.
        self.finishing = False
        self.closed = False
        #: How many times records were made part of the file (a caller learns from it that
        #: everything it wrote before is in the file).
        self.commits = 0

    # -- what mcap's Writer calls --------------------------------------------------------------

    def write(self, data: bytes | bytearray | memoryview) -> int:
        self._pending += data
        self._pos += len(data)
        if self._started and not self.finishing:  # whole records: a chunk, its indexes
            self._commit()
        return len(data)

    def tell(self) -> int:
        return self._pos

    def flush(self) -> None:
        if not self._started:
            self._begin()
        elif self._pending:
            self._commit()

    def close(self) -> None:
        """Make the file finished: the writer's summary and footer, the file cut to them.

        Call after ``Writer.finish()``; without it (an error) the file stays as committed.
        """
        if self.closed:
            return
        try:
            if not self._started:
                self._begin()
            if self._pending:
                tail = bytes(self._pending)
                self._pending.clear()
                self._place(tail)
                self._file.truncate(self._committed)
                self._file.flush()
        finally:
            self.closed = True
            self._file.close()

    def abandon(self) -> None:
        """Close the file without finishing it (it stays as committed, a valid file)."""
        if not self.closed:
            self.closed = True
            self._file.close()

    # -- layout ----------------------------------------------------------------------------------

    def _begin(self) -> None:
        """The magic and header, then PAD and footer: a valid empty file, in one write."""
        head = bytes(self._pending)
        self._pending.clear()
        self._committed = len(head)
        self._footer_at = self._footer_position(self._committed + _HEADER_LEN)
        body = self._footer_at - self._committed - _HEADER_LEN
        self._write_at(head + _pad_header(body) + bytes(body) + _footer(), 0)
        self._started = True

    def _commit(self) -> None:
        records = bytes(self._pending)
        self._pending.clear()
        self._place(records)

    def _place(self, records: bytes) -> None:
        """Steps 1-5 of the module docstring for ``records`` (whole records) at the end."""
        at = self._committed
        end = at + len(records)
        if end + _HEADER_LEN > self._footer_at:  # 1: grow
            footer_at = self._footer_position(end + _HEADER_LEN + len(records))
            self._write_at(_footer(), footer_at)
            self._write_at(struct.pack("<Q", footer_at - at - _HEADER_LEN), at + 1)
            self._footer_at = footer_at
        self._write_at(_pad_header(self._footer_at - end - _HEADER_LEN), end)  # 2
        if len(records) > _HEADER_LEN:
            self._write_at(records[_HEADER_LEN:], at + _HEADER_LEN)  # 3
        self._write_at(records[1:_HEADER_LEN], at + 1)  # 4
        self._write_at(records[:1], at)  # 5
        self._committed = end
        self.commits += 1

    def _write_at(self, data: bytes, offset: int) -> None:
        """One step: its bytes reach the operating system before the next step begins."""
        self._file.seek(offset)
        self._file.write(data)
        self._file.flush()

    @staticmethod
    def _footer_position(least: int) -> int:
        """``least`` or just after, where the footer and magic do not cross a page."""
        if least % _PAGE + _TAIL_LEN > _PAGE:
            return least - least % _PAGE + _PAGE
        return least
