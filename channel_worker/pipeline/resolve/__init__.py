"""Resolve stage: the shading of one sample (shading.py) and the filtering of samples into
pixels (resolve.py)."""
