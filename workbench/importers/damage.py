"""Truncated and corrupt binary logs: what a PX4 ULog or ArduPilot DataFlash reader could not read.

pyulog and pymavlink stop silently at a log cut mid-message (a recorder that lost power, a
copy that did not finish). These walkers follow the logs' own framing to find out: a ULog is
a 16-byte header then messages of ``uint16 size, uint8 type, payload`` (docs.px4.io, "ULog
File Format"); a DataFlash log is records ``0xA3 0x95 type`` of the length their ``FMT``
record declares. A log whose last message or record runs past the end of the file is
truncated; bytes between DataFlash records that are no record were skipped (corruption). A
cut exactly at a message boundary leaves no trace in either format and is not detected.
Trailing 0x00 / 0xFF bytes of a DataFlash log are block padding, not damage.

Public: :class:`Damage`, :func:`ulog_damage`, :func:`dataflash_damage`.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

ULOG_HEADER = 16  # bytes: magic (7), version (1), timestamp (8)
DATAFLASH_HEAD = (0xA3, 0x95)


@dataclass(frozen=True)
class Damage:
    """What could not be read: ``cut_bytes`` at the end (part of one message of ``cut_of`` bytes;
    0 when the log ends on a whole message), ``skipped_bytes`` between records, ``whole_bytes`` the
    length up to the end of the last whole message; ``corrupt`` the library reported corruption."""

    file_bytes: int
    whole_bytes: int
    cut_bytes: int
    cut_of: int | None
    skipped_bytes: int = 0
    corrupt: bool = False

    @property
    def any(self) -> bool:
        """Whether anything was lost."""
        return bool(self.cut_bytes or self.skipped_bytes or self.corrupt)

    def text(self, name: str) -> str:
        """One phrase for a summary or an error: ``log.ulg is truncated at byte 38904 (...)``."""
        parts = []
        if self.cut_bytes:
            of = f" of {self.cut_of}" if self.cut_of else ""
            parts.append(f"truncated at byte {self.file_bytes}: its last message is cut ({self.cut_bytes}{of} "
                         f"bytes present, 1 message lost; what followed it is not in the file)")
        if self.skipped_bytes:
            parts.append(f"{self.skipped_bytes} bytes that are no record skipped")
        if self.corrupt and not parts:
            parts.append("corrupt (the reader skipped unreadable bytes)")
        return f"{name} is " + "; ".join(parts) if parts else f"{name}: whole"


def ulog_damage(data: bytes, corrupt: bool = False) -> Damage:
    """Walk the messages of the ULog ``data`` (module docstring); ``corrupt`` as pyulog reported."""
    size = len(data)
    if size < ULOG_HEADER:
        return Damage(size, 0, size, ULOG_HEADER, corrupt=corrupt)
    pos = ULOG_HEADER
    while pos + 3 <= size:
        (msg_size,) = struct.unpack_from("<H", data, pos)
        end = pos + 3 + msg_size
        if end > size:
            return Damage(size, pos, size - pos, 3 + msg_size, corrupt=corrupt)
        pos = end
    return Damage(size, pos, size - pos, None, corrupt=corrupt)  # a partial 3-byte header, or nothing


def dataflash_damage(data: bytes, lengths: dict[int, int]) -> Damage:
    """Walk the records of the DataFlash ``data`` with ``lengths`` (record type -> bytes, from the
    log's FMT records as pymavlink read them)."""
    size, pos, skipped, last_whole = len(data), 0, 0, 0
    while pos + 3 <= size:
        if data[pos] == DATAFLASH_HEAD[0] and data[pos + 1] == DATAFLASH_HEAD[1] and data[pos + 2] in lengths:
            end = pos + lengths[data[pos + 2]]
            if end > size:
                return Damage(size, pos, size - pos, lengths[data[pos + 2]], skipped)
            pos = last_whole = end
        else:
            pos += 1
            skipped += 1
    tail = data[last_whole:]
    if tail.strip(b"\x00") == b"" or tail.strip(b"\xff") == b"":  # block padding, not damage
        return Damage(size, last_whole, 0, None, skipped - (pos - last_whole))
    tail_skipped = pos - last_whole
    return Damage(size, last_whole, size - last_whole, None, skipped - tail_skipped)
