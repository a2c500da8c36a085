"""Per frame, each drawn face's look carried into the eye frame: its texture-plane coordinates
and its Gouraud light as linear functions of the eye point (contract.Polygons.surface)."""

from __future__ import annotations

import numpy as np

from channel_worker.pipeline.scene.database import Database
from channel_worker.pipeline.scene.surfaces import LOOK_SMOOTH


def eye_surfaces(database: Database, face_rows: np.ndarray, face_inst: np.ndarray,
                 to_eye_rot: np.ndarray, world_rot: np.ndarray,
                 rel: np.ndarray) -> tuple[np.ndarray | None, np.ndarray | None, np.ndarray | None]:
    """(look (N,) int32, surface (N, 3, 4) float64, smooth (N,) bool) of the drawn faces, or
    (None, None, None) when none of them has a look: a scene or a view without textures pays
    one comparison per face. smooth marks the Gouraud faces (their light is surface row 2).

    Args:
        face_rows: (N,) the drawn faces' rows of the database's FaceTable.
        face_inst: (N,) each face's drawn instance k.
        to_eye_rot, world_rot: (n, 3, 3) instance k's model -> eye and model -> world rotations.
        rel: (n, 3) instance k's origin in the eye frame, metres (float64, eye-relative).

    A model-frame linear function f(P) = G . P + k becomes, with P = R^T (p - t) for eye point
    p (R model -> eye, t the instance origin), f = (R G) . p + (k - (R G) . t). The light of a
    Gouraud face is Lambert's at each of its three corners (the vertex normals turned into the
    world and dotted with the sun), made linear over the triangle by the dual basis of its
    edges (scene/surfaces.py); other faces with a look keep light 1 (their colour is lit).
    """
    table = database.faces.surface
    look = table.look[face_rows]
    lit = np.nonzero(look >= 0)[0]
    if lit.shape[0] == 0:
        return None, None, None
    rows = face_rows[lit]
    inst = face_inst[lit]
    rot = to_eye_rot[inst]
    t = rel[inst]
    maps = np.zeros((face_rows.shape[0], 3, 4))
    maps[:, 2, 3] = 1.0
    g = np.einsum("mij,mkj->mki", rot, table.tex_map[rows, :, :3])  # (m, 2, 3) eye frame
    maps[lit, :2, :3] = g
    maps[lit, :2, 3] = table.tex_map[rows, :, 3] - np.einsum("mki,mi->mk", g, t)
    smooth = database.looks[look[lit], LOOK_SMOOTH] != 0.0
    if smooth.any():
        s_rows = rows[smooth]
        s_inst = inst[smooth]
        # Lambert at the three corners, from the vertex normals in the world frame.
        world_n = np.einsum("mij,mkj->mki", world_rot[s_inst], table.normals[s_rows])
        amb = database.ambient
        light = amb + (1.0 - amb) * np.clip(world_n @ database.sun, 0.0, 1.0)  # (m, 3)
        basis = table.basis[s_rows]
        grad = ((light[:, 1] - light[:, 0])[:, None] * basis[:, 0]
                + (light[:, 2] - light[:, 0])[:, None] * basis[:, 1])  # model frame
        k = light[:, 0] - np.einsum("mi,mi->m", grad, basis[:, 2])
        s_rot = to_eye_rot[s_inst]
        g_eye = np.einsum("mij,mj->mi", s_rot, grad)
        idx = lit[smooth]
        maps[idx, 2, :3] = g_eye
        maps[idx, 2, 3] = k - np.einsum("mi,mi->m", g_eye, rel[s_inst])
    gouraud = np.zeros(face_rows.shape[0], bool)
    gouraud[lit[smooth]] = True
    return look.astype(np.int32), maps, gouraud
