"""What every process of the rig shares: the frame, eyepoint and channel types, the render
options and frame report, the rig file, the proto <-> type conversion, geodetic and colour
helpers, image I/O, and the gRPC and command-line plumbing.

This package is the leaf of the project's layers (docs/architecture.md): it imports nothing of
the project but the generated contracts in ``ig.v1``, and host_sim, channel_worker and
services.compositor import it side by side. It imports nothing heavy on its own: a module that
needs numba or OpenImageIO (colour, image_io) is imported only by the processes that need it.
"""
