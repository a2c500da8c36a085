"""Shading, below the visibility and resolve stages that both call it: the colour of one
sample (shading.py, texturing.py), the analytic coverage of pixels one edge crosses
(_coverage_kernels.py), the box filter inside a sub-area (_box_kernels.py), the sub-area's
sample store and coverage-mask layout (scratch.py) and the frame's shading group (group.py)."""
