"""Sub-area binning stage: each projected edge as line equations (edges.py), and per sub-area
the list of features touching it, nearest first (binning.py)."""
