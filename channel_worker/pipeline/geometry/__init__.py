"""Geometry stages: the view (view.py), culling (cull.py), the float64 world -> eye transform
(transform.py), backface elimination (backface.py), clipping (clip.py) and projection
(project.py)."""
