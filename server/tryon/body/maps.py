"""Per-part collision structures: oriented bounding boxes and cylinder maps (SPEC sections 2 and 4)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class PartMaps:
    """Stacked per-part collision structures for P parts (see docs/ARCHITECTURE.md).

    OBB (grown by ``margin``): obb_center (P, 3), obb_axes (P, 3, 3) rows unit, obb_half (P, 3),
    obb_corners (P, 8, 3), obb_normals (P, 6, 3) outward unit, obb_offsets (P, 6): p is inside part k's
    box iff ``obb_normals[k] @ p <= obb_offsets[k]`` row-wise.
    Cylinder map: cyl_origin (P, 3), cyl_axes (P, 3, 3) rows = local x, y, z (z along the part axis),
    cyl_zrange (P, 2), cyl_shape (P, 2) int64 (n_theta, n_z), cell_base (P,) int64; global cell id
    ``cell_base[k] + it * n_z + iz``; CSR ``cell_start (C + 1,) int64``, ``cell_faces (K,) int32``.
    margin: metres the boxes and cells were grown by.
    """

    obb_center: np.ndarray
    obb_axes: np.ndarray
    obb_half: np.ndarray
    obb_corners: np.ndarray
    obb_normals: np.ndarray
    obb_offsets: np.ndarray
    cyl_origin: np.ndarray
    cyl_axes: np.ndarray
    cyl_zrange: np.ndarray
    cyl_shape: np.ndarray
    cell_base: np.ndarray
    cell_start: np.ndarray
    cell_faces: np.ndarray
    margin: float
