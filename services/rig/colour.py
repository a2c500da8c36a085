"""sRGB <-> linear colour (IEC 61966-2-1), for scene colours, terrain databases and images.

Scenes and terrain databases store sRGB-encoded colours; everything inside the pipeline is
linear light; images written as 8-bit are sRGB again. The 8-bit encoder is a numba pass,
because it runs on every stitched frame on the compositor's critical path.
"""

from __future__ import annotations

import numpy as np
from numba import njit


def srgb_to_linear(c: np.ndarray) -> np.ndarray:
    """sRGB-encoded [0, 1] -> linear."""
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def _srgb_encode(c: np.ndarray) -> np.ndarray:
    """The sRGB transfer function (IEC 61966-2-1) on linear values in [0, 1]."""
    return np.where(c <= 0.0031308, 12.92 * c, 1.055 * np.power(c, 1.0 / 2.4) - 0.055)


# Linear values quantised to 16 bits address this table: a step of 1/65535 moves the sRGB value
# by at most 12.92/65535 (the steepest slope, at black), a fifth of an 8-bit level, and the
# table is ten times faster than evaluating the power per pixel of a 3072 x 768 frame.
_LUT_SIZE = 1 << 16
#: The table itself (public: the worker's parallel encoder reads it too, channel_worker/submit.py).
SRGB8_TABLE = np.round(_srgb_encode(np.arange(_LUT_SIZE) / (_LUT_SIZE - 1)) * 255.0).astype(np.uint8)


def linear_to_srgb8(rgb: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    """Encode linear RGB (any shape, last axis channels) as sRGB 8-bit; NaN -> 0, clipped to [0, 1].

    Args:
        rgb: linear values.
        out: where to write (a C-contiguous uint8 array of rgb's shape: a worker's shared-memory
            slot, say); None: a new array.

    Raises:
        ValueError: out is not a C-contiguous uint8 array of rgb's shape.
    """
    c = np.ascontiguousarray(rgb, dtype=np.float32)
    if out is None:
        out = np.empty(c.shape, np.uint8)
    elif out.shape != c.shape or out.dtype != np.uint8 or not out.flags.c_contiguous:
        raise ValueError(f"out: {out.dtype} {out.shape} is not a contiguous uint8 array of shape {c.shape}")
    _encode_kernel(c.reshape(-1), SRGB8_TABLE, out.reshape(-1))
    return out


@njit(cache=True, inline="always")
def srgb8_of(v, table):
    """One linear value's sRGB byte: clipped to [0, 1] (NaN: 0), quantised to the table's
    16 bits, looked up (every encoder of the project, serial or parallel, uses this)."""
    top = table.shape[0] - 1
    if not v > 0.0:  # also NaN
        return table[0]
    if v >= 1.0:
        return table[top]
    return table[int(v * np.float32(top) + np.float32(0.5))]


# nogil: a worker encodes while its receiver thread takes the host's next frame.
@njit(cache=True, nogil=True)
def _encode_kernel(c, lut, out):
    """One pass of clip, quantise and table look-up (the numpy chain of the same took ~10 x
    longer on a stitched 3072 x 768 frame, on the compositor's critical path)."""
    for i in range(c.shape[0]):
        out[i] = srgb8_of(c[i], lut)


def srgb8_to_linear(srgb: np.ndarray) -> np.ndarray:
    """Inverse of linear_to_srgb8, float32."""
    return srgb_to_linear(srgb.astype(np.float32) / np.float32(255.0)).astype(np.float32)


#: srgb8_to_linear of every byte: decoding an 8-bit image is one look-up per component (the
#: compositor's blend, row profiles and EXR recording of sRGB-wire channels).
SRGB8_TO_LINEAR = srgb8_to_linear(np.arange(256, dtype=np.uint8))
SRGB8_TO_LINEAR.flags.writeable = False


def decode_srgb8(srgb: np.ndarray) -> np.ndarray:
    """srgb8_to_linear of a uint8 array by table, bit for bit the same, float32."""
    if srgb.dtype != np.uint8:
        raise ValueError(f"srgb: dtype {srgb.dtype} is not uint8")
    return SRGB8_TO_LINEAR[srgb]
