"""Per frame, each drawn face's look carried into the eye frame: its texture-plane coordinates
and its Gouraud light as linear functions of the eye point (contract.Polygons.surface)."""

from __future__ import annotations

import numpy as np

from channel_worker.pipeline.scene.database import Database
from channel_worker.pipeline.scene.surfaces import LOOK_SMOOTH

from ._transform_kernels import DrawnInstances, surface_kernel


def eye_surfaces(database: Database, face_rows: np.ndarray, face_inst: np.ndarray,
                 drawn: DrawnInstances) -> tuple[np.ndarray | None, np.ndarray | None, np.ndarray | None]:
    """(look (N,) int32, surface (N, 3, 4) float64, smooth (N,) bool) of the drawn faces, or
    (None, None, None) when none of them has a look: a scene or a view without textures pays
    one comparison per face. smooth marks the Gouraud faces (their light is surface row 2).

    Args:
        face_rows: (N,) the drawn faces' rows of the database's FaceTable.
        face_inst: (N,) each face's drawn instance k.
        drawn: the drawn instances' rotations (model -> eye, model -> world) and origins in the
            eye frame (float64, eye-relative).

    A model-frame linear function f(P) = G . P + k becomes, with P = R^T (p - t) for eye point
    p (R model -> eye, t the instance origin), f = (R G) . p + (k - (R G) . t). The light of a
    Gouraud face is Lambert's at each of its three corners (the vertex normals turned into the
    world and dotted with the sun), made linear over the triangle by the dual basis of its
    edges (scene/surfaces.py); other faces with a look keep light 1 (their colour is lit).
    One compiled pass over the faces (surface_kernel): as numpy's einsums and fancy indexing
    it took 0.14 ms of the 0.2 ms transform stage on a 16-core Xeon, a serial stage that
    stood at 2.4 % of a 16-thread frame.
    """
    table = database.faces.surface
    look = table.look[face_rows]
    if not (look >= 0).any():
        return None, None, None
    maps = np.empty((face_rows.shape[0], 3, 4))
    gouraud = np.empty(face_rows.shape[0], np.bool_)
    smooth_look = database.looks[:, LOOK_SMOOTH] != 0.0
    surface_kernel(face_rows, face_inst, drawn, table.tex_map, table.look, smooth_look, table.normals,
                   table.basis, np.asarray(database.sun, np.float64), float(database.ambient), maps, gouraud)
    return look.astype(np.int32), maps, gouraud
