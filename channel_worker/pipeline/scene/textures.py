"""TEMPORARY stand-in until the texture store lands (helper branch tex)."""
from __future__ import annotations
from collections.abc import Sequence
from pathlib import Path
import numpy as np
from channel_worker.pipeline.contract import TextureStore
MAX_LEVELS = 12
def empty_store() -> TextureStore:
    return TextureStore(np.zeros((1, 3), np.float32), np.zeros((1, MAX_LEVELS, 3), np.int64),
                        np.ones(1, np.int64), np.full(1, 0.5), np.zeros((1, 3), np.float32))
def load_image(path) -> np.ndarray:
    raise ValueError(f"{path}: not yet")
def bundled_texture_path(name: str) -> Path:
    raise ValueError(name)
def procedural(kind: str, size: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return (0.3 + 0.2 * rng.random((size, size, 3))).astype(np.float32)
def build_store(images: Sequence[np.ndarray], names: Sequence[str]) -> TextureStore:
    texels, level, levels, means = [], [], [], []
    off = 0
    for img in images:
        mean = img.reshape(-1, 3).mean(axis=0)
        sig = (img / mean - 1.0).astype(np.float32)
        lv = np.zeros((MAX_LEVELS, 3), np.int64)
        n = 0
        while True:
            h, w = sig.shape[:2]
            lv[n] = (off, int(np.log2(w)), int(np.log2(h)))
            texels.append(sig.reshape(-1, 3)); off += h * w; n += 1
            if h == 1 and w == 1:
                break
            sig = sig.reshape(max(h // 2, 1), min(h, 2), max(w // 2, 1), min(w, 2), 3).mean(axis=(1, 3))
        lv[n:] = lv[n - 1]
        level.append(lv); levels.append(n); means.append(mean)
    return TextureStore(np.concatenate(texels).astype(np.float32), np.array(level), np.array(levels),
                        np.full(len(images), 0.5), np.array(means, np.float32))
