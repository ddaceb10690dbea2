"""A garment file of several separate garments (a MakeHuman outfit: a shirt and trousers in one file) split into
one ``GarmentModel`` per piece, so the simulation can layer them (``tryon.sim.outfit``) and the result can be
put back in the file's own vertex order.

Pieces are the connected components of the coarse mesh (simplification never joins two components); each
full vertex belongs to the piece of the coarse triangle it is attached to, each full triangle to the piece of
its first corner. No spring joins two pieces.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from tryon.garment.model import GarmentModel
from tryon.garment.topology import vertex_pieces


@dataclass(frozen=True)
class PieceOf:
    """Where one piece's arrays come from in the whole model: full (n_p,) and coarse (k_p,) vertex ids."""

    full: np.ndarray
    coarse: np.ndarray


def split_pieces(model: GarmentModel, categories: list[str]) -> tuple[list[GarmentModel], list[PieceOf]]:
    """One model per coarse piece of ``model`` (``categories[p]``: piece p's category, top | bottom | dress),
    and where each piece's vertices are in the whole. Piece p's id is ``"<id>#<p>"``."""
    k = len(model.coarse_index)
    _, coarse_piece = vertex_pieces(model.coarse_faces, k)
    face_piece = coarse_piece[model.coarse_faces[:, 0]]
    full_piece = face_piece[model.attach_face]
    full_face_piece = full_piece[model.faces[:, 0]]
    models, maps = [], []
    for p, category in enumerate(categories):
        coarse = np.flatnonzero(coarse_piece == p)
        full = np.flatnonzero(full_piece == p)
        coarse_new = np.full(k, -1, dtype=np.int64)
        coarse_new[coarse] = np.arange(len(coarse))
        full_new = np.full(len(model.vertices), -1, dtype=np.int64)
        full_new[full] = np.arange(len(full))
        coarse_faces = np.flatnonzero(face_piece == p)
        face_new = np.full(len(model.coarse_faces), -1, dtype=np.int64)
        face_new[coarse_faces] = np.arange(len(coarse_faces))
        keep = coarse_piece[model.springs[:, 0]] == p
        meta = replace(model.meta, id=f"{model.meta.id}#{p}", category=category, vertices=len(full),
                       faces=int(np.count_nonzero(full_face_piece == p)), coarse_vertices=len(coarse),
                       coarse_faces=len(coarse_faces))
        models.append(GarmentModel(
            meta=meta,
            vertices=model.vertices[full],
            faces=full_new[model.faces[full_face_piece == p]].astype(np.int32),
            coarse_index=full_new[model.coarse_index[coarse]].astype(np.int32),
            coarse_faces=coarse_new[model.coarse_faces[coarse_faces]].astype(np.int32),
            springs=coarse_new[model.springs[keep]].astype(np.int32),
            rest=model.rest[keep], kind=model.kind[keep], mass=model.mass[coarse],
            attach_face=face_new[model.attach_face[full]].astype(np.int32),
            attach_bary=model.attach_bary[full], attach_offset=model.attach_offset[full],
        ))
        maps.append(PieceOf(full=full, coarse=coarse))
    return models, maps
