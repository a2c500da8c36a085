"""Channel images through shared memory, when a worker and the compositor share a machine.

The worker owns a segment (a file under /dev/shm) holding a ring of slots; it writes a frame's
pixels straight into the next slot and sends the compositor a reference (segment, slot,
sequence: ig.v1.SharedImage) instead of the pixels. The compositor copies the pixels out of
the slot before its SubmitChannelImage returns, so a slot is free again once the worker has
its answer; the ring (SLOTS deep) covers a submission the worker gave up on (its deadline
passed) while the compositor was still reading.

Layout, little-endian::

    segment header (HEADER bytes): MAGIC, slots (uint32), slot capacity in bytes (uint64)
    slot i at HEADER + i * (HEADER + capacity rounded up to HEADER):
        slot header (HEADER bytes): sequence (uint64) of the image in the slot, 0 while written
        pixels (capacity bytes)

The sequence is written after the pixels and cleared before they are overwritten, and the
reader checks it before and after its copy: an image overwritten (or never written) is
refused, never stitched. Both sides are in this module, the one contract between them.
"""

from __future__ import annotations

import contextlib
import errno
import ipaddress
import mmap
import os
import re
import secrets
import socket
import struct
import threading
import weakref
from dataclasses import dataclass
from pathlib import Path

import numpy as np

#: Where segments live: POSIX shared memory on Linux (tmpfs, never written to disk).
SHM_DIR = Path("/dev/shm")
#: Slots of a worker's ring.
SLOTS = 4
#: Bytes of the segment header and of every slot's header (a cache line).
HEADER = 64
MAGIC = b"IGIMAGE1"
_SEGMENT_HEADER = struct.Struct("<8sIQ")
#: Segment names: the worker's prefix, its pid and a random part; nothing that is a path.
_NAME = re.compile(r"ig-[A-Za-z0-9_-]{1,64}-[0-9]{1,10}-[0-9a-f]{8}")


class SharedImageError(ValueError):
    """A shared image the compositor cannot read; the message names the field and value.

    Attributes:
        unavailable: the segment cannot be opened here (another machine or /dev/shm namespace,
            or a worker gone): the worker should send its images inline.
    """

    def __init__(self, message: str, *, unavailable: bool = False) -> None:
        super().__init__(message)
        self.unavailable = unavailable


def shared_memory_supported() -> bool:
    """Whether this machine has POSIX shared memory the way this module uses it."""
    return SHM_DIR.is_dir() and os.access(SHM_DIR, os.W_OK)


def is_local_address(address: str) -> bool:
    """Whether host:port names this machine: a loopback address, or one of its interfaces (an
    address a socket can bind to). A name that does not resolve is not local."""
    host = address.rpartition(":")[0].strip("[]")
    try:
        infos = socket.getaddrinfo(host, None, proto=socket.IPPROTO_TCP)
    except (OSError, UnicodeError):
        return False
    for family, _, _, _, sockaddr in infos:
        ip = ipaddress.ip_address(str(sockaddr[0]).split("%")[0])
        if ip.is_loopback:
            return True
        try:
            with socket.socket(family, socket.SOCK_DGRAM) as s:
                s.bind((sockaddr[0], 0))
            return True
        except OSError:
            continue
    return False


def _slot_stride(capacity: int) -> int:
    return HEADER + -(-capacity // HEADER) * HEADER


def remove_stale_segments(prefix: str) -> list[str]:
    """Unlink the segments of prefix whose worker process is gone (killed before it could
    clean up); returns their names. Segments of live processes are left alone."""
    removed = []
    for path in SHM_DIR.glob(f"ig-{prefix}-*"):
        parts = path.name.rsplit("-", 2)
        if not _NAME.fullmatch(path.name) or len(parts) != 3 or parts[0] != f"ig-{prefix}":
            continue
        try:
            os.kill(int(parts[1]), 0)
            continue  # alive (or another user's: not ours to remove)
        except ProcessLookupError:
            pass
        except PermissionError:
            continue
        try:
            path.unlink()
            removed.append(path.name)
        except OSError:
            pass
    return removed


class SharedImageRing:
    """A worker's segment: SLOTS slots of capacity bytes each, written in turn.

    Args:
        prefix: names the segment (the channel: letters, digits, - and _).
        capacity: bytes of the largest image a slot holds.
        slots: slots in the ring.

    Raises:
        OSError: the segment cannot be created (no /dev/shm, no space).
        ValueError: a bad prefix, capacity or slot count (named).
    """

    def __init__(self, prefix: str, capacity: int, *, slots: int = SLOTS) -> None:
        if not re.fullmatch(r"[A-Za-z0-9_-]{1,64}", prefix):
            raise ValueError(f"prefix: {prefix!r} is not 1-64 letters, digits, - and _")
        if capacity < 1 or slots < 1:
            raise ValueError(f"capacity {capacity}, slots {slots}: both must be >= 1")
        self.name = f"ig-{prefix}-{os.getpid()}-{secrets.token_hex(4)}"
        self.slots = slots
        self.capacity = capacity
        self._stride = _slot_stride(capacity)
        size = HEADER + slots * self._stride
        path = SHM_DIR / self.name
        fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_EXCL, 0o600)
        try:
            os.ftruncate(fd, size)
            self._map = mmap.mmap(fd, size)
        except OSError:
            path.unlink(missing_ok=True)
            raise
        finally:
            os.close(fd)
        self._map[:HEADER] = _SEGMENT_HEADER.pack(MAGIC, slots, capacity).ljust(HEADER, b"\0")
        self._buffer = np.frombuffer(self._map, np.uint8)
        self.sequence = 0
        self._closed = False
        # A ring dropped without close (a test, an exception) still leaves no file behind, at
        # the latest when the interpreter exits; SIGKILL leaves one, remove_stale_segments
        # clears it at the next start of the channel's worker.
        self._unlink = weakref.finalize(self, path.unlink, missing_ok=True)

    def reserve(self, shape: tuple[int, ...], dtype: np.dtype | type) -> tuple[int, int, np.ndarray]:
        """The next slot for an image: (slot, sequence, a writable array of shape and dtype over
        its pixels). Its sequence is cleared until commit, so a reader never takes it half written.

        Raises:
            ValueError: the image is larger than a slot.
        """
        nbytes = int(np.prod(shape)) * np.dtype(dtype).itemsize
        if nbytes > self.capacity:
            raise ValueError(f"image: {nbytes} bytes, more than the slot's {self.capacity}")
        self.sequence += 1
        slot = self.sequence % self.slots
        start = HEADER + slot * self._stride
        self._buffer[start:start + 8].view("<u8")[0] = 0
        pixels = self._buffer[start + HEADER:start + HEADER + nbytes].view(dtype).reshape(shape)
        return slot, self.sequence, pixels

    def commit(self, slot: int, sequence: int) -> None:
        """The slot's pixels are written: stamp its header with the image's sequence."""
        start = HEADER + slot * self._stride
        self._buffer[start:start + 8].view("<u8")[0] = sequence

    def close(self) -> None:
        """Unmap and remove the segment (the compositor's mapping, if any, stays valid until it
        lets go; no new one can be opened)."""
        if self._closed:
            return
        self._closed = True
        del self._buffer
        with contextlib.suppress(BufferError):  # a view of a slot is alive: the mapping goes with it
            self._map.close()
        self._unlink()


@dataclass
class _Opened:
    name: str
    map: mmap.mmap
    buffer: np.ndarray
    slots: int
    capacity: int


class SharedImageReader:
    """The compositor's side: the segment of every channel, opened on first use and replaced
    when the channel's worker comes back with a new one."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._open: dict[str, _Opened] = {}

    def read(self, channel: str, segment: str, slot: int, sequence: int, shape: tuple[int, ...],
             dtype: np.dtype | type) -> np.ndarray:
        """A copy of the image in slot of segment (the slot is free for the worker once this
        returns).

        Raises:
            SharedImageError: the segment cannot be opened (unavailable), is not a ring of this
                layout, the slot is not in the ring or too small, or the slot does not hold
                image sequence (overwritten, or never written: a stale reference).
        """
        opened = self._segment(channel, segment)
        if not 0 <= slot < opened.slots:
            raise SharedImageError(f"shared.slot: {slot} is not a slot of segment {segment!r} "
                                   f"(it has {opened.slots})")
        nbytes = int(np.prod(shape)) * np.dtype(dtype).itemsize
        if nbytes > opened.capacity:
            raise SharedImageError(f"shared.slot: {nbytes} bytes of pixels do not fit segment {segment!r}'s "
                                   f"{opened.capacity}-byte slots")
        start = HEADER + slot * _slot_stride(opened.capacity)
        head = opened.buffer[start:start + 8].view("<u8")
        before = int(head[0])
        if before == sequence:
            out = np.empty(shape, dtype)
            out.reshape(-1).view(np.uint8)[:] = opened.buffer[start + HEADER:start + HEADER + nbytes]
            after = int(head[0])
            if after == sequence:
                return out
            before = after
        raise SharedImageError(f"shared.sequence: {sequence}, but slot {slot} of segment {segment!r} holds "
                               f"{before} (a stale reference: the image was overwritten or never written)")

    def _segment(self, channel: str, segment: str) -> _Opened:
        if not _NAME.fullmatch(segment):
            raise SharedImageError(f"shared.segment: {segment[:80]!r} is not a segment name")
        with self._lock:
            opened = self._open.get(channel)
            if opened is not None and opened.name == segment:
                return opened
            fresh = self._open_segment(segment)
            # The channel's worker came back with a new segment: let go of the old one. Its
            # mapping goes with the last reference (a copy still running on another thread
            # keeps it until done), and a dead worker's segment is freed once it is unlinked.
            self._open[channel] = fresh
            return fresh

    @staticmethod
    def _open_segment(segment: str) -> _Opened:
        try:
            fd = os.open(SHM_DIR / segment, os.O_RDONLY)
        except OSError as exc:
            why = "it does not exist here" if exc.errno == errno.ENOENT else exc.strerror
            raise SharedImageError(f"shared.segment: {segment!r} cannot be opened on the compositor's machine: "
                                   f"{why}", unavailable=True) from None
        try:
            size = os.fstat(fd).st_size
            if size < HEADER:
                raise SharedImageError(f"shared.segment: {segment!r} is {size} bytes, not a ring of images")
            mapped = mmap.mmap(fd, size, access=mmap.ACCESS_READ)
        finally:
            os.close(fd)
        magic, slots, capacity = _SEGMENT_HEADER.unpack_from(mapped, 0)
        if magic != MAGIC or slots < 1 or HEADER + slots * _slot_stride(capacity) > size:
            mapped.close()
            raise SharedImageError(f"shared.segment: {segment!r} is not a ring of images of this layout")
        return _Opened(segment, mapped, np.frombuffer(mapped, np.uint8), slots, capacity)

    def close(self) -> None:
        """Let go of every segment (each unmapped with its last reference)."""
        with self._lock:
            self._open.clear()
