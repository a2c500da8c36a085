"""The worker's image on its way to the compositor: encoded in the rig's wire format (sRGB
bytes or half floats), handed over in shared memory when the compositor shares the machine,
inline in the request otherwise (docs/latency.md).
"""

from __future__ import annotations

import logging
import time
from typing import Any, NamedTuple

import grpc
import numpy as np
from numba import njit, prange

from ig.v1 import compositor_pb2
from services.rig.colour import SRGB8_TABLE, linear_to_srgb8, srgb8_of
from services.rig.frame import ChannelSpec
from services.rig.grpc_util import RPC_DEADLINE_S
from services.rig.rigfile import WireSpec, check_wire_format
from services.rig.shared_images import (
    SharedImageRing,
    is_local_address,
    remove_stale_segments,
    shared_memory_supported,
)

log = logging.getLogger("ig.worker")

#: The pixel format and the numpy type of each wire format.
PIXEL_FORMATS: dict[str, tuple[int, np.dtype]] = {"srgb8": (compositor_pb2.PIXEL_FORMAT_RGB_SRGB8, np.dtype(np.uint8)),
                 "half": (compositor_pb2.PIXEL_FORMAT_RGB_F16, np.dtype("<f2"))}


def encode_rgb_f16(rgb: np.ndarray) -> bytes:
    """PIXEL_FORMAT_RGB_F16: linear RGB (H, W, 3) as little-endian half floats, top row first."""
    out = np.empty(rgb.shape, "<f2")
    to_half(rgb, out)
    return out.tobytes()


def to_half(rgb: np.ndarray, out: np.ndarray) -> None:
    """Round float RGB to IEEE half floats into out (same shape, "<f2"): bit for bit what
    numpy's astype gives, in a quarter of the time for float32 (1.8 ms instead of 7 for a
    1024 x 768 channel, on the critical path of every frame).

    Raises:
        ValueError: out is not a C-contiguous little-endian half-float array of rgb's shape.
    """
    if out.shape != rgb.shape or out.dtype != np.dtype("<f2") or not out.flags.c_contiguous:
        raise ValueError(f"out: {out.dtype} {out.shape} is not a contiguous <f2 array of shape {rgb.shape}")
    if rgb.dtype == np.float32 and rgb.flags.c_contiguous and np.little_endian:
        _half_bits(rgb.reshape(-1).view(np.uint32), out.reshape(-1).view(np.uint16))
    else:
        np.copyto(out, rgb, casting="unsafe")


@njit(cache=True, nogil=True)
def _half_bits(src, dst):
    """IEEE float32 bits -> float16 bits, rounding to nearest even, as numpy does (numba has no
    float16 type, hence the bits; the branches are the cases of the half format)."""
    for i in range(src.size):
        u = src[i]
        sign = (u >> np.uint32(16)) & np.uint32(0x8000)
        a = u & np.uint32(0x7FFFFFFF)  # magnitude
        if a >= np.uint32(0x47800000):  # >= 65536 (or inf, NaN): inf, or a quiet NaN
            h = np.uint32(0x7E00) if a > np.uint32(0x7F800000) else np.uint32(0x7C00)
        elif a >= np.uint32(0x38800000):  # >= 2^-14: a normal half (65520 and up round to inf)
            # Re-bias the exponent (127 -> 15) and round the 23-bit mantissa to 10 bits: adding
            # 0xFFF plus the lowest kept bit before the shift rounds half to even.
            h = (a + np.uint32(0xC8000FFF) + ((a >> np.uint32(13)) & np.uint32(1))) >> np.uint32(13)
        elif a >= np.uint32(0x33000000):  # >= 2^-25: a subnormal half, units of 2^-24
            shift = np.uint32(126) - (a >> np.uint32(23))
            mantissa = (a & np.uint32(0x7FFFFF)) | np.uint32(0x800000)
            h = mantissa >> shift
            rest = mantissa & ((np.uint32(1) << shift) - np.uint32(1))
            half = np.uint32(1) << (shift - np.uint32(1))
            if rest > half or (rest == half and (h & np.uint32(1))):
                h += np.uint32(1)
        else:  # rounds to zero
            h = np.uint32(0)
        dst[i] = np.uint16(h | sign)


class ImageSubmission(NamedTuple):
    """A SubmitChannelImageRequest whose pixels stay in the worker's buffer until the request is
    serialised (SubmitStub): its fields read as the request's.

    Attributes:
        head: every field of the request but pixels.
        pixels: the image in the request's pixel_format (a view of the worker's buffer, valid
            until the next frame is encoded); empty when the request's shared field says where
            the pixels are.
    """

    head: compositor_pb2.SubmitChannelImageRequest
    pixels: memoryview

    def __getattr__(self, name: str) -> Any:
        return getattr(self.head, name)


#: The wire tag of SubmitChannelImageRequest.pixels: its field number, length-delimited.
_PIXELS_TAG = bytes([compositor_pb2.SubmitChannelImageRequest.DESCRIPTOR.fields_by_name["pixels"].number << 3 | 2])


def serialize_submission(submission: ImageSubmission) -> bytes:
    """The wire form of the request with its pixels: the other fields serialised by protobuf, the
    pixels field appended after them (a protobuf parser takes fields in any order).

    The pixels are copied once, into the message: building the request with them would copy
    them into a bytes object, into the message, and again when gRPC serialises it.
    """
    if not submission.pixels.nbytes:
        return submission.head.SerializeToString()
    size, length = submission.pixels.nbytes, bytearray()
    while size >= 0x80:
        length.append(size & 0x7F | 0x80)
        size >>= 7
    length.append(size)
    return b"".join((submission.head.SerializeToString(), _PIXELS_TAG, length, submission.pixels))


class SubmitStub:
    """CompositorService.SubmitChannelImage taking an ImageSubmission (serialize_submission)."""

    def __init__(self, channel: grpc.Channel) -> None:
        method = compositor_pb2.DESCRIPTOR.services_by_name["CompositorService"].methods_by_name["SubmitChannelImage"]
        self.SubmitChannelImage = channel.unary_unary(
            f"/{method.containing_service.full_name}/{method.name}", request_serializer=serialize_submission,
            response_deserializer=compositor_pb2.SubmitChannelImageResponse.FromString)


def encode_srgb8(rgb: np.ndarray, out: np.ndarray) -> None:
    """linear_to_srgb8 of the rendered image into out, its rows shared among the worker's
    render threads: bit for bit the serial encoder, which took 3 ms of a 1024 x 768 channel
    on one core, on the critical path between the render and the compositor.

    Raises:
        ValueError: out is not a C-contiguous uint8 array of rgb's shape.
    """
    if out.shape != rgb.shape or out.dtype != np.uint8 or not out.flags.c_contiguous:
        raise ValueError(f"out: {out.dtype} {out.shape} is not a contiguous uint8 array of shape {rgb.shape}")
    if rgb.ndim != 3 or rgb.dtype != np.float32 or not rgb.flags.c_contiguous:
        linear_to_srgb8(rgb, out)
        return
    h = rgb.shape[0]
    _srgb8_rows(rgb.reshape(h, -1), SRGB8_TABLE, out.reshape(h, -1))


@njit(cache=True, parallel=True)
def _srgb8_rows(rgb, table, out):
    """services.rig.colour's encoder (srgb8_of), a row per task."""
    for y in prange(rgb.shape[0]):
        for i in range(rgb.shape[1]):
            out[y, i] = srgb8_of(rgb[y, i], table)


def warm_encoders() -> None:
    """Compile (or load) the encoders of every wire format: a worker's first frame must not wait
    for the compiler."""
    rgb = np.zeros((2, 2, 3), np.float32)
    encode_rgb_f16(rgb)
    linear_to_srgb8(rgb)
    encode_srgb8(rgb, np.empty(rgb.shape, np.uint8))


def refused_shared(exc: grpc.RpcError) -> bool:
    """Whether the compositor refused a shared-memory image because it cannot open the segment
    (compositor.proto: FAILED_PRECONDITION, "shared." ...), so the image must go inline."""
    return exc.code() == grpc.StatusCode.FAILED_PRECONDITION and (exc.details() or "").startswith("shared.")


class ImageSender:
    """Encodes a channel's rendered images in the wire format and submits them, one at a time.

    Shared memory is offered when the rig allows it, the machine has it and the compositor's
    address is this machine's: the pixels are encoded straight into the next slot of the
    worker's ring (services/rig/shared_images.py), and the request carries only the reference.
    If the compositor cannot open the segment (another /dev/shm: a container, or another
    machine behind a local-looking address), it refuses that image; the sender then sends it
    inline, logs why once, and sends inline from then on. Inline, the image is encoded into a
    buffer of the sender's own, which the request's serialiser copies once (ImageSubmission).

    Args:
        channel: the channel (its name names the segment; its size, the buffers).
        compositor_address: host:port of the compositor (is it on this machine?).
        wire: the rig's WireSpec (or the command line's).

    Raises:
        ValueError: wire.format is not a wire format (named).
    """

    def __init__(self, channel: ChannelSpec, *, compositor_address: str, wire: WireSpec | None = None) -> None:
        wire = wire or WireSpec()
        self.wire = check_wire_format(wire.format, "wire")
        self.pixel_format, dtype = PIXEL_FORMATS[self.wire]
        self.shape = (channel.height, channel.width, 3)
        self._inline = np.empty(self.shape, dtype)
        self.ring: SharedImageRing | None = None
        #: Why images go inline ("" while shared memory is used).
        self.inline_because = self._offer_shared(channel, compositor_address, wire)
        if self.inline_because:
            log.info("worker %s: %s images inline (%s)", channel.name, self.wire, self.inline_because)
        else:
            assert self.ring is not None
            log.info("worker %s: %s images in shared memory (/dev/shm/%s, %d slots)", channel.name, self.wire,
                     self.ring.name, self.ring.slots)

    def _offer_shared(self, channel: ChannelSpec, compositor_address: str, wire: WireSpec) -> str:
        """Open the ring if shared memory may be used; else say why not."""
        if not wire.shared_memory:
            return "shared memory is turned off"
        if not shared_memory_supported():
            return "no /dev/shm on this machine"
        if not is_local_address(compositor_address):
            return f"the compositor {compositor_address} is not on this machine"
        # Segments of this channel's workers killed before they could remove them.
        for name in remove_stale_segments(channel.name):
            log.info("worker %s: removed the segment of a worker gone: /dev/shm/%s", channel.name, name)
        try:
            self.ring = SharedImageRing(channel.name, self._inline.nbytes)
        except (OSError, ValueError) as exc:
            return f"cannot create a shared-memory segment: {exc}"
        return ""

    @property
    def shared(self) -> bool:
        """Whether images go through shared memory now."""
        return self.ring is not None

    def submit(self, stub: Any, head: compositor_pb2.SubmitChannelImageRequest, rgb: np.ndarray) -> None:
        """Encode rgb (the rendered (H, W, 3) linear image) and submit it with head's fields
        (pixel_format, shared and submit_unix_s are set here).

        Raises:
            grpc.RpcError: the compositor refused the image or could not be reached.
        """
        head.pixel_format = self.pixel_format
        if self.ring is not None:
            slot, sequence, pixels = self.ring.reserve(self.shape, self._inline.dtype)
            self._encode(rgb, pixels)
            del pixels  # no view of the slot outlives the frame (the ring can then be closed)
            self.ring.commit(slot, sequence)
            head.shared.CopyFrom(compositor_pb2.SharedImage(segment=self.ring.name, slot=slot, sequence=sequence))
            head.submit_unix_s = time.time()
            try:
                stub.SubmitChannelImage(ImageSubmission(head, memoryview(b"")), timeout=RPC_DEADLINE_S)
                return
            except grpc.RpcError as exc:
                if not refused_shared(exc):
                    raise
                self.inline_because = f"the compositor cannot open the segment: {exc.details()}"
                log.warning("worker %s: images go inline from now on: %s", head.channel_name, self.inline_because)
                self.close()
                head.ClearField("shared")
        self._encode(rgb, self._inline)
        head.submit_unix_s = time.time()
        stub.SubmitChannelImage(ImageSubmission(head, self._inline.data.cast("B")), timeout=RPC_DEADLINE_S)

    def _encode(self, rgb: np.ndarray, out: np.ndarray) -> None:
        if self.wire == "srgb8":
            encode_srgb8(rgb, out)
        else:
            to_half(rgb, out)

    def close(self) -> None:
        """Remove the shared-memory segment, if any (worker exit, SIGTERM included)."""
        if self.ring is not None:
            self.ring.close()
            self.ring = None
