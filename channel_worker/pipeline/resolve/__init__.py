"""Resolve stage: the filtering of a frame's sample store into pixels (resolve.py); the
shading of one sample is shade/."""
