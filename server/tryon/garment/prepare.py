"""From a clean garment mesh to a ``GarmentModel``: simplify, springs, masses, re-attachment.

``prepare(mesh, meta_fields, simplification, density) -> GarmentModel``; pure (no files), so the
catalogue can run it in a temp directory and a benchmark can time it.
"""

from __future__ import annotations

import numpy as np

from tryon.garment.ingest import CleanMesh, GarmentError
from tryon.garment.model import GarmentMeta, GarmentModel
from tryon.garment.simplify import attach, collapse_with_parents
from tryon.garment.springs import SPRING_KINDS, spring_model

# Areal density, kg/m^2, of a bare ``prepare`` given none (the benchmarks' scenes and the tests' models). The
# catalogue passes each entry's own: its fabric's (``fabric.FABRICS``: jersey 0.187, cotton twill 0.220) unless
# an ingestion gives one.
DEFAULT_DENSITY = 0.15
# The paper finds 20-30% of the vertices keep the drape: default simplification degree B.
DEFAULT_SIMPLIFICATION = 0.3


def triangle_areas(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(f,) triangle areas, m^2."""
    tri = vertices[faces]
    return 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)


def lumped_masses(coarse_vertices: np.ndarray, coarse_faces: np.ndarray, total_mass: float) -> np.ndarray:
    """(k,) kg: a third of each coarse triangle's area to each corner, scaled to ``total_mass``."""
    area = triangle_areas(coarse_vertices, coarse_faces)
    lumped = np.bincount(coarse_faces.reshape(-1), weights=np.repeat(area / 3.0, 3), minlength=len(coarse_vertices))
    return lumped * (total_mass / lumped.sum())


def prepare(mesh: CleanMesh, *, id: str, name: str, category: str, size: str | None, source_sha256: str,
            source_name: str, simplification: float = DEFAULT_SIMPLIFICATION,
            density: float = DEFAULT_DENSITY, fabric: str | None = None) -> GarmentModel:
    """Simplify (B = ``simplification``), build springs on the coarse mesh, lump masses (``density``
    kg/m^2 times the full mesh's area), re-attach the full mesh. ``fabric`` (a name in ``fabric.FABRICS``, or None:
    the category's) and ``density`` are recorded in the meta."""
    v, f = mesh.vertices, mesh.faces
    kept, coarse_faces, root = collapse_with_parents(f, len(v), simplification, v)
    if len(coarse_faces) == 0:
        raise GarmentError(f"simplified to B = {simplification:g}, the mesh keeps no triangle: ask for a larger B")
    coarse_v = v[kept]
    springs, rest, kind = spring_model(coarse_v, coarse_faces)
    mass = lumped_masses(coarse_v, coarse_faces, density * triangle_areas(v, f).sum())
    attach_face, attach_bary, attach_offset = attach(v, root, kept, coarse_faces)
    notes = list(mesh.notes)
    achieved = len(kept) / len(v)
    if achieved > simplification + 0.02:
        notes.append(f"simplified to {achieved:.2f} of the vertices, not {simplification:.2f}: further "
                     "collapses would have closed openings or folded the surface")
    counts = np.bincount(kind, minlength=3)
    meta = GarmentMeta(
        id=id, name=name, category=category, size=size, units=mesh.units, units_guessed=mesh.units_guessed,
        simplification=float(simplification), source_sha256=source_sha256, source_name=source_name,
        vertices=len(v), faces=len(f), coarse_vertices=len(kept), coarse_faces=len(coarse_faces),
        springs={name_: int(c) for name_, c in zip(SPRING_KINDS, counts)}, notes=notes, fabric=fabric,
        density=float(density),
    )
    return GarmentModel(
        meta=meta, vertices=v, faces=f.astype(np.int32), coarse_index=kept.astype(np.int32),
        coarse_faces=coarse_faces.astype(np.int32), springs=springs, rest=rest, kind=kind, mass=mass,
        attach_face=attach_face, attach_bary=attach_bary, attach_offset=attach_offset,
    )
