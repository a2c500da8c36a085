"""Visibility stage: per sample the nearest opaque feature and the nearer translucent ones
(visibility.py), and the scan-line renderer that cross-checks it (scanline.py)."""
