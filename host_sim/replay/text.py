"""Telling a text flight log from a binary file, for the text readers (CSV, IGC, X-Plane FDR).

Random bytes read as text are lines of garbage: a reader would count some as damaged records,
find none at all, and end in "0 usable record(s), need at least 2 (no problems)", which
sends the user looking for a problem in a flight log when the file is none. A binary file is
refused as such, from its first bytes.
"""

from __future__ import annotations

from pathlib import Path

#: Bytes read to tell a text log from a binary file.
SNIFF_BYTES = 4096
#: Share of control bytes (not tab, line ends or form feed) above which a file is binary:
#: random bytes have 11 %, a text log a few damaged lines' worth.
BINARY_SHARE = 0.05


def head(path: Path) -> bytes:
    """The first SNIFF_BYTES bytes of a file."""
    with open(path, "rb") as f:
        return f.read(SNIFF_BYTES)


def refuse_binary(path: Path, first: bytes, what: str) -> None:
    """Raise if the first bytes of path are binary data rather than a text log.

    Args:
        path: the log, named in the message.
        first: its first bytes (head(path)).
        what: the log kind for the message ("CSV log", "IGC log").

    Raises:
        ValueError: more control bytes than a damaged text log has, naming the file and counts.
    """
    # A logger that lost power leaves a few NUL bytes in a text log (a damaged line, counted);
    # a binary file is full of control bytes.
    control = sum(1 for byte in first if byte < 32 and byte not in b"\t\n\r\f")
    if control > BINARY_SHARE * len(first):
        raise ValueError(f"{path.name}: not a text {what} ({control} of its first {len(first)} bytes are "
                         f"control bytes: binary data)")
