"""Terrain: the voxel database of JP H07-76990 (built offline by `ig terrain build`) and its loading.

The renderer that scans it is the pipeline stage channel_worker/pipeline/terrain.py.
"""
