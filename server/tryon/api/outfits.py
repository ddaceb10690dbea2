"""Outfits through the API: the garments of a request checked, loaded and layered as one mesh for the stream.

``POST /api/tryon`` and ``WS /ws/tryon`` take ``garment_ids`` (1 to 3, innermost first) and ``tuck``; the
simulation is ``tryon.sim.outfit.drape_outfit``. What a client gets back is written by ``service.outfit_json``.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
from fastapi import HTTPException, status

from tryon.api.schemas.tryon import TryOnRequest
from tryon.garment.catalogue import Catalogue
from tryon.garment.model import GarmentModel
from tryon.geometry import stack_meshes
from tryon.sim.outfit import piece_categories
from tryon.sim.tuck import layer_order


# Each entry's pieces (``file_pieces``) by id: an id stands for one file's content and preparation, so its pieces
# never change; a listing then loads each model once per process, not on every call.
_PIECES: dict[str, list[str] | None] = {}


def file_pieces(catalogue: Catalogue, garment_id: str) -> list[str] | None:
    """For an entry that is a file of separate garments worn together (a MakeHuman outfit: a shirt and
    trousers), each piece's category in the file's order (``sim.outfit.piece_categories``); None for one
    garment."""
    if garment_id not in _PIECES:
        try:
            model = catalogue.model(garment_id)
        except KeyError:  # deleted since it was listed
            return None
        _PIECES[garment_id] = piece_categories(model)
    return _PIECES[garment_id]


def check_garments(catalogue: Catalogue, request: TryOnRequest) -> None:
    """HTTPException for garments a request cannot have: an unknown ``garment_id`` is 404 (as before
    outfits); in ``garment_ids`` an unknown id, two bottoms, or a file that is itself a top and a bottom (a
    MakeHuman outfit, draped as layers when tried on alone) is 422 naming the field."""
    if not request.outfit:
        if catalogue.get(request.garment_id) is None:
            raise HTTPException(status.HTTP_404_NOT_FOUND, f"no garment with id {request.garment_id!r}")
        return
    metas = []
    for k, gid in enumerate(request.ids):
        meta = catalogue.get(gid)
        if meta is None:
            raise HTTPException(422, f"garment_ids[{k}]: no garment with id {gid!r} in the catalogue "
                                     "(see GET /api/garments)")
        metas.append(meta)
        if len(request.ids) > 1 and file_pieces(catalogue, gid) is not None:
            raise HTTPException(422, f"garment_ids[{k}]: {meta.name!r} is already an outfit (a top and a bottom in one "
                                     "file, layered when it is tried on alone): try it on by itself")
    try:
        layer_order([m.category for m in metas], request.tuck)
    except ValueError as e:
        raise HTTPException(422, f"garment_ids: {e}") from None


@dataclass
class OutfitMesh:
    """An outfit's garment models in layer order (innermost first) as one mesh: what the stream sends.

    models: the ``GarmentModel`` of each garment, in layer order. ``vertices`` / ``faces``: their full meshes one
    after the other (faces offset); ``expand`` turns the simulation's coarse positions (one (k_i, 3) array per
    garment) into that mesh's positions; ``ranges`` says which vertices and faces are whose."""

    models: list[GarmentModel]

    @cached_property
    def stacked(self) -> tuple[np.ndarray, np.ndarray]:
        return stack_meshes([(m.vertices, m.faces) for m in self.models])

    @property
    def vertices(self) -> np.ndarray:
        return self.stacked[0]

    @property
    def faces(self) -> np.ndarray:
        return self.stacked[1]

    def expand(self, coarse: list[np.ndarray]) -> np.ndarray:
        """(n, 3) m: every garment's full mesh from its coarse positions, in layer order."""
        return np.concatenate([m.expand(c) for m, c in zip(self.models, coarse)])

    @property
    def ranges(self) -> list[dict]:
        """Per garment (layer order): its id, layer, and where its vertices and faces are in the one mesh."""
        out, v, f = [], 0, 0
        for layer, m in enumerate(self.models):
            out.append({"garment_id": m.meta.id, "layer": layer, "vertex_start": v, "vertex_count": len(m.vertices),
                        "face_start": f, "face_count": len(m.faces)})
            v, f = v + len(m.vertices), f + len(m.faces)
        return out


def outfit_models(catalogue: Catalogue, request: TryOnRequest, simplification: float) -> list[GarmentModel]:
    """The request's garment models in its order (innermost first, before the tuck)."""
    return [catalogue.model(gid, simplification) for gid in request.ids]


def layered(models: list[GarmentModel], tuck: str) -> OutfitMesh:
    """``models`` (request order) as the outfit mesh, in layer order."""
    return OutfitMesh([models[i] for i in layer_order([m.meta.category for m in models], tuck)])
