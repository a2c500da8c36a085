"""Every image the rig reads or writes goes through OpenImageIO here.

`.exr` keeps the linear float data (RGB, plus a `Z` channel with the range from the eye when
given); every other extension (PNG in practice) gets sRGB-encoded 8-bit RGB. Frame metadata
(eyepoint, channel, frame number) travels as image attributes under the `ig:` prefix.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import OpenImageIO as oiio

from .colour import decode_srgb8, linear_to_srgb8

AttrValue = str | float | int


def write_image(path: str | Path, rgb_linear: np.ndarray, *, range_m: np.ndarray | None = None,
                attributes: dict[str, AttrValue] | None = None) -> None:
    """Write one image.

    Args:
        path: destination; `.exr` writes linear half-float RGB (and float32 `Z` if range_m is
            given), anything else writes sRGB 8-bit RGB.
        rgb_linear: (H, W, 3) linear RGB; or uint8, sRGB-encoded already (a composite of
            sRGB-wire channels): a PNG takes the bytes as they are, an EXR their linear values
            (8-bit levels: quantised).
        range_m: (H, W) metres from the eye, +inf for sky; stored only in EXR.
        attributes: metadata, stored as `ig:<key>` attributes.

    Raises:
        OSError: OpenImageIO could not create or write the file (its message is included).
    """
    path = Path(path)
    rgb_linear = np.asarray(rgb_linear)
    is_exr = path.suffix.lower() == ".exr"
    if rgb_linear.ndim != 3 or rgb_linear.shape[2] != 3:
        raise ValueError(f"rgb_linear: shape {rgb_linear.shape} is not (H, W, 3)")
    height, width = rgb_linear.shape[:2]
    if is_exr:
        rgb = decode_srgb8(rgb_linear) if rgb_linear.dtype == np.uint8 else \
            np.ascontiguousarray(rgb_linear, dtype=np.float32)
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
        data = np.ascontiguousarray(rgb_linear) if rgb_linear.dtype == np.uint8 else linear_to_srgb8(rgb_linear)
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
            if param.name.startswith("ig:") and isinstance(param.value, str | float | int):
                attrs[param.name[3:]] = param.value
    finally:
        inp.close()
    return np.asarray(pixels, dtype=np.float32).reshape(spec.height, spec.width, spec.nchannels), attrs


def encode_jpeg(srgb8: np.ndarray, scratch: str | Path, *, quality: int = 80) -> bytes:
    """Encode sRGB bytes as a baseline JPEG through OpenImageIO and return the file's bytes.

    A lossy preview only (the compositor's live view, docs/live-view.md): the rig's recorded
    frames stay PNG and EXR.

    Args:
        srgb8: (H, W, 3) uint8, sRGB-encoded already.
        scratch: a file path the caller owns, overwritten: OpenImageIO's Python binding writes
            to files only (its in-memory IOProxy is C++), so the JPEG goes through it and is read
            back; put it on a memory file system (/dev/shm) where there is one.
        quality: JPEG quality, 1-100.

    Raises:
        ValueError: srgb8 is not (H, W, 3) uint8, or quality is out of range.
        OSError: OpenImageIO could not write the file (its message is included).
    """
    srgb8 = np.ascontiguousarray(srgb8)
    if srgb8.dtype != np.uint8 or srgb8.ndim != 3 or srgb8.shape[2] != 3:
        raise ValueError(f"srgb8: {srgb8.dtype} {srgb8.shape} is not (H, W, 3) uint8")
    if not 1 <= quality <= 100:
        raise ValueError(f"quality: {quality} is not in [1, 100]")
    path = str(scratch)
    spec = oiio.ImageSpec(srgb8.shape[1], srgb8.shape[0], 3, oiio.UINT8)
    spec.attribute("Compression", f"jpeg:{quality}")
    # By the format's name: the scratch file's name need not end in .jpg.
    out = oiio.ImageOutput.create("jpeg")
    if out is None:
        raise OSError(f"{path}: OpenImageIO cannot write JPEG: {oiio.geterror()}")
    try:
        if not out.open(path, spec) or not out.write_image(srgb8):
            raise OSError(f"{path}: {out.geterror()}")
    finally:
        out.close()
    with open(path, "rb") as f:
        return f.read()
