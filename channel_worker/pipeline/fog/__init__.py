"""Layered fog stage: the per-frame table of average extinction and its per-sample look-up
(fog.py)."""
