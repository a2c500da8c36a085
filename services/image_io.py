"""Every image the rig reads or writes goes through OpenImageIO here.

`.exr` keeps the linear float data (RGB, plus a `Z` channel with the range from the eye when
given); every other extension (PNG in practice) gets sRGB-encoded 8-bit RGB. Frame metadata
(eyepoint, channel, frame number) travels as image attributes under the `ig:` prefix.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import OpenImageIO as oiio
from numba import njit

AttrValue = str | float | int


def _srgb_encode(c: np.ndarray) -> np.ndarray:
    """The sRGB transfer function (IEC 61966-2-1) on linear values in [0, 1]."""
    return np.where(c <= 0.0031308, 12.92 * c, 1.055 * np.power(c, 1.0 / 2.4) - 0.055)


# Linear values quantised to 16 bits address this table: a step of 1/65535 moves the sRGB value
# by at most 12.92/65535 (the steepest slope, at black), a fifth of an 8-bit level, and the
# table is ten times faster than evaluating the power per pixel of a 3072 x 768 frame.
_LUT_SIZE = 1 << 16
_SRGB8_LUT = np.round(_srgb_encode(np.arange(_LUT_SIZE) / (_LUT_SIZE - 1)) * 255.0).astype(np.uint8)


def linear_to_srgb8(rgb: np.ndarray) -> np.ndarray:
    """Encode linear RGB (any shape, last axis channels) as sRGB 8-bit; NaN -> 0, clipped to [0, 1]."""
    c = np.ascontiguousarray(rgb, dtype=np.float32)
    out = np.empty(c.shape, np.uint8)
    _encode_kernel(c.reshape(-1), _SRGB8_LUT, out.reshape(-1))
    return out


@njit(cache=True)
def _encode_kernel(c, lut, out):
    """One pass of clip, quantise and table look-up (the numpy chain of the same took ~10 x
    longer on a stitched 3072 x 768 frame, on the compositor's critical path)."""
    top = lut.shape[0] - 1
    for i in range(c.shape[0]):
        v = c[i]
        if not v > 0.0:  # also NaN
            out[i] = lut[0]
        elif v >= 1.0:
            out[i] = lut[top]
        else:
            out[i] = lut[int(v * np.float32(top) + np.float32(0.5))]


def srgb8_to_linear(srgb: np.ndarray) -> np.ndarray:
    """Inverse of linear_to_srgb8, float32."""
    c = srgb.astype(np.float32) / 255.0
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4).astype(np.float32)


def write_image(path: str | Path, rgb_linear: np.ndarray, *, range_m: np.ndarray | None = None,
                attributes: dict[str, AttrValue] | None = None) -> None:
    """Write one image.

    Args:
        path: destination; `.exr` writes linear half-float RGB (and float32 `Z` if range_m is
            given), anything else writes sRGB 8-bit RGB.
        rgb_linear: (H, W, 3) linear RGB.
        range_m: (H, W) metres from the eye, +inf for sky; stored only in EXR.
        attributes: metadata, stored as `ig:<key>` attributes.

    Raises:
        OSError: OpenImageIO could not create or write the file (its message is included).
    """
    path = Path(path)
    rgb = np.ascontiguousarray(rgb_linear, dtype=np.float32)
    if rgb.ndim != 3 or rgb.shape[2] != 3:
        raise ValueError(f"rgb_linear: shape {rgb.shape} is not (H, W, 3)")
    height, width = rgb.shape[:2]
    is_exr = path.suffix.lower() == ".exr"
    if is_exr:
        if range_m is not None:
            pixels = np.concatenate([rgb, np.asarray(range_m, np.float32)[..., None]], axis=2)
            spec = oiio.ImageSpec(width, height, 4, oiio.FLOAT)
            spec.channelnames = ("R", "G", "B", "Z")
            # half for colour keeps files small; Z needs float32 to hold kilometres to the cm.
            spec.channelformats = (oiio.HALF, oiio.HALF, oiio.HALF, oiio.FLOAT)
        else:
            pixels = rgb
            spec = oiio.ImageSpec(width, height, 3, oiio.HALF)
            spec.channelnames = ("R", "G", "B")
        spec.attribute("compression", "zip")
        data = pixels
    else:
        spec = oiio.ImageSpec(width, height, 3, oiio.UINT8)
        data = linear_to_srgb8(rgb)
    for key, value in (attributes or {}).items():
        if not is_exr or isinstance(value, bool):
            # PNG keeps only text chunks: numbers are stored as their repr and read back as text.
            value = str(value)
        spec.attribute(f"ig:{key}", value)
    path.parent.mkdir(parents=True, exist_ok=True)
    out = oiio.ImageOutput.create(str(path))
    if out is None:
        raise OSError(f"{path}: OpenImageIO cannot write this format: {oiio.geterror()}")
    try:
        if not out.open(str(path), spec):
            raise OSError(f"{path}: {out.geterror()}")
        if not out.write_image(data):
            raise OSError(f"{path}: {out.geterror()}")
    finally:
        out.close()


def read_image(path: str | Path) -> tuple[np.ndarray, dict[str, AttrValue]]:
    """Read an image written by write_image.

    Returns:
        (pixels, attributes): pixels (H, W, C) float32 as stored (8-bit files are scaled to
        [0, 1] but left sRGB-encoded); attributes holds the `ig:` metadata without the prefix,
        plus `channelnames`.
    """
    path = Path(path)
    inp = oiio.ImageInput.open(str(path))
    if inp is None:
        raise OSError(f"{path}: {oiio.geterror()}")
    try:
        spec = inp.spec()
        pixels = inp.read_image(0, 0, 0, spec.nchannels, oiio.FLOAT)
        if pixels is None:
            raise OSError(f"{path}: {inp.geterror()}")
        attrs: dict[str, AttrValue] = {"channelnames": ",".join(spec.channelnames)}
        for param in spec.extra_attribs:
            if param.name.startswith("ig:"):
                attrs[param.name[3:]] = param.value
    finally:
        inp.close()
    return np.asarray(pixels, dtype=np.float32).reshape(spec.height, spec.width, spec.nchannels), attrs
