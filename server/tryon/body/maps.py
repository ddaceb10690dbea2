"""Per-part collision structures: oriented bounding boxes and cylinder maps (SPEC sections 2 and 4).

For every body part we fix a local frame whose z axis runs along the part's axis segment and whose x
axis is the body's forward direction (+z world) made perpendicular to it (world +x when the axis is
itself along z). In that frame:

- the OBB is the part's local bounding box grown by ``margin`` (so the body offset outward by up to
  ``margin`` stays inside it);
- the cylinder map cuts the (theta, z) plane into ``n_theta x n_z`` cells and lists, per cell, every
  face of that part whose (theta, z) extent, grown by ``margin``, overlaps the cell. A ray from the
  axis perpendicular to it keeps theta and z, so the faces it can hit are exactly its cell's faces.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

# Angular resolution of the cylinder maps: 48 sectors of 7.5 degrees keep cells at about 2 cm on a
# torso (radius ~0.15 m). Each cell's face list is grown by the maps' margin (1 cm), so the lists shrink
# only slowly with the cells (~55 faces per torso cell at 32 x 2.5 cm, ~47 at 48 x 1.8 cm); still the
# collision per step measured ~20 % faster (``python3 -m tryon.bench.perf``: 2.9 -> 2.3 ms), with the same
# drapes bit for bit on the catalogue, for 0.5 M instead of 0.28 M list entries (built in ~9 ms).
N_THETA = 48
# Target cell height along the part axis, metres: about the torso's cell width, so cells are squarish.
CELL_HEIGHT = 0.018


@dataclass(frozen=True)
class PartMaps:
    """Stacked per-part collision structures for P parts (see docs/ARCHITECTURE.md).

    OBB (grown by ``margin``): obb_center (P, 3), obb_axes (P, 3, 3) rows unit, obb_half (P, 3),
    obb_corners (P, 8, 3), obb_normals (P, 6, 3) outward unit, obb_offsets (P, 6): p is inside part k's
    box iff ``obb_normals[k] @ p <= obb_offsets[k]`` row-wise.
    Cylinder map: cyl_origin (P, 3), cyl_axes (P, 3, 3) rows = local x, y, z (z along the part axis),
    cyl_zrange (P, 2), cyl_shape (P, 2) int64 (n_theta, n_z), cell_base (P,) int64; global cell id
    ``cell_base[k] + it * n_z + iz``; CSR ``cell_start (C + 1,) int64``, ``cell_faces (K,) int32``.
    margin: metres the boxes and cells were grown by. part_axes (P, 2, 3) m: the axis segments the frames were
    made from (a shape change of the same body builds its maps again on them).
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
    part_axes: np.ndarray


def part_frames(part_axes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Local frames of the parts: origins (P, 3) (axis start) and axes (P, 3, 3) rows x, y, z.

    z = unit axis direction; x = world +z (the body's front) with its z component removed, or world +x
    when the axis is (nearly) along world z; y = z cross x, so (x, y, z) is right-handed.
    """
    part_axes = np.asarray(part_axes, dtype=np.float64)
    origin = part_axes[:, 0].copy()
    z = part_axes[:, 1] - part_axes[:, 0]
    z /= np.maximum(np.linalg.norm(z, axis=1, keepdims=True), 1e-12)
    front = np.array([0.0, 0.0, 1.0])
    side = np.array([1.0, 0.0, 0.0])
    x = front - (z @ front)[:, None] * z
    weak = np.linalg.norm(x, axis=1) < 0.3  # axis within ~17 degrees of world z
    x[weak] = side - (z[weak] @ side)[:, None] * z[weak]
    x /= np.linalg.norm(x, axis=1, keepdims=True)
    y = np.cross(z, x)
    return origin, np.stack([x, y, z], axis=1)


@njit(cache=True, nogil=True)
def _local_bounds(vertices, faces, face_part, origin, axes, n_parts):
    """Per-part min/max (P, 2, 3) of the local coordinates of the vertices of that part's faces."""
    lo = np.full((n_parts, 3), np.inf)
    hi = np.full((n_parts, 3), -np.inf)
    for f in range(faces.shape[0]):
        k = face_part[f]
        for c in range(3):
            v = faces[f, c]
            for a in range(3):
                d = 0.0
                for b in range(3):
                    d += (vertices[v, b] - origin[k, b]) * axes[k, a, b]
                if d < lo[k, a]:
                    lo[k, a] = d
                if d > hi[k, a]:
                    hi[k, a] = d
    return lo, hi


@njit(cache=True, nogil=True)
def _face_cells(vertices, faces, face_part, origin, axes, zrange, shape, margin, out_range):
    """Each face's cell range in its part's map, written to ``out_range`` (f, 4) as
    (it_start, it_count, iz_start, iz_end inclusive); returns the total number of (face, cell) pairs.

    The theta range is the shortest arc containing the three vertex angles (the triangle does not
    contain the axis), grown by the angle ``margin / r_min``; a triangle whose grown arc exceeds half a
    turn, or that comes within 2 margins of the axis, covers every sector.
    """
    two_pi = 2.0 * math.pi
    total = 0
    for f in range(faces.shape[0]):
        k = face_part[f]
        n_theta = shape[k, 0]
        n_z = shape[k, 1]
        z_lo = np.inf
        z_hi = -np.inf
        r_min = np.inf
        a0 = 0.0
        a1 = 0.0
        a2 = 0.0
        for c in range(3):
            v = faces[f, c]
            lx = 0.0
            ly = 0.0
            lz = 0.0
            for b in range(3):
                d = vertices[v, b] - origin[k, b]
                lx += d * axes[k, 0, b]
                ly += d * axes[k, 1, b]
                lz += d * axes[k, 2, b]
            a = math.atan2(ly, lx)
            if c == 0:
                a0 = a
            elif c == 1:
                a1 = a
            else:
                a2 = a
            r = math.sqrt(lx * lx + ly * ly)
            r_min = min(r_min, r)
            z_lo = min(z_lo, lz)
            z_hi = max(z_hi, lz)
        # sort the three angles (a0 <= a1 <= a2)
        if a0 > a1:
            a0, a1 = a1, a0
        if a1 > a2:
            a1, a2 = a2, a1
        if a0 > a1:
            a0, a1 = a1, a0
        g0 = a1 - a0
        g1 = a2 - a1
        g2 = a0 + two_pi - a2
        if g2 >= g0 and g2 >= g1:
            start = a0
            width = a2 - a0
        elif g0 >= g1:
            start = a1
            width = a0 + two_pi - a1
        else:
            start = a2
            width = a1 + two_pi - a2
        full = r_min < 2.0 * margin
        if not full:
            grow = margin / r_min
            start -= grow
            width += 2.0 * grow
            full = width > math.pi
        if full:
            it0 = 0
            count = n_theta
        else:
            it0 = int(math.floor((start + math.pi) / two_pi * n_theta))
            it1 = int(math.floor((start + width + math.pi) / two_pi * n_theta))
            count = min(it1 - it0 + 1, n_theta)
            it0 = it0 % n_theta
        dz = (zrange[k, 1] - zrange[k, 0]) / n_z
        iz0 = int(math.floor((z_lo - margin - zrange[k, 0]) / dz))
        iz1 = int(math.floor((z_hi + margin - zrange[k, 0]) / dz))
        iz0 = min(max(iz0, 0), n_z - 1)
        iz1 = min(max(iz1, 0), n_z - 1)
        out_range[f, 0] = it0
        out_range[f, 1] = count
        out_range[f, 2] = iz0
        out_range[f, 3] = iz1
        total += count * (iz1 - iz0 + 1)
    return total


@njit(cache=True, nogil=True)
def _fill_cells(face_part, face_range, shape, cell_base, n_cells):
    """CSR (cell_start (C+1,), cell_faces (K,)) from the per-face cell ranges (counting sort)."""
    counts = np.zeros(n_cells + 1, dtype=np.int64)
    n_faces = face_part.shape[0]
    for f in range(n_faces):
        k = face_part[f]
        n_theta = shape[k, 0]
        n_z = shape[k, 1]
        for j in range(face_range[f, 1]):
            it = (face_range[f, 0] + j) % n_theta
            for iz in range(face_range[f, 2], face_range[f, 3] + 1):
                counts[cell_base[k] + it * n_z + iz + 1] += 1
    for c in range(n_cells):
        counts[c + 1] += counts[c]
    cell_faces = np.empty(counts[n_cells], dtype=np.int32)
    fill = counts[:n_cells].copy()
    for f in range(n_faces):
        k = face_part[f]
        n_theta = shape[k, 0]
        n_z = shape[k, 1]
        for j in range(face_range[f, 1]):
            it = (face_range[f, 0] + j) % n_theta
            for iz in range(face_range[f, 2], face_range[f, 3] + 1):
                c = cell_base[k] + it * n_z + iz
                cell_faces[fill[c]] = f
                fill[c] += 1
    return counts, cell_faces


# Sign patterns of the eight OBB corners, in local (x, y, z) half-extent units.
_CORNER_SIGNS = np.array(
    [[-1, -1, -1], [1, -1, -1], [1, 1, -1], [-1, 1, -1], [-1, -1, 1], [1, -1, 1], [1, 1, 1], [-1, 1, 1]],
    dtype=np.float64,
)


def _boxes_and_shapes(vertices, faces, face_part, origin, axes, n_parts: int, margin: float) -> tuple:
    """Each part's OBB and cylinder-map extent from its faces (``faces`` (f, 3) of part ``face_part`` (f,)), in
    the part frames ``origin`` (P, 3), ``axes`` (P, 3, 3), grown by ``margin`` m: (center (P, 3), half (P, 3),
    corners (P, 8, 3), normals (P, 6, 3) +x +y +z -x -y -z, offsets (P, 6), zrange (P, 2), shape (P, 2) int64:
    theta and z cells). A part without faces gets an empty box (offsets -inf) and a single cell."""
    lo, hi = _local_bounds(vertices, faces, face_part, origin, axes, n_parts)
    empty = ~np.isfinite(lo[:, 0])
    lo[empty] = 0.0
    hi[empty] = 0.0
    # OBB in the part frame, grown by the margin.
    lo_g = lo - margin
    hi_g = hi + margin
    half = 0.5 * (hi_g - lo_g)
    center = origin + np.einsum("pa,pab->pb", 0.5 * (lo_g + hi_g), axes)
    corners = center[:, None, :] + np.einsum("ca,pa,pab->pcb", _CORNER_SIGNS, half, axes)
    normals = np.concatenate([axes, -axes], axis=1)  # +x, +y, +z, -x, -y, -z
    offsets = np.einsum("pjb,pb->pj", normals, center) + np.concatenate([half, half], axis=1)
    offsets[empty] = -np.inf
    # Cylinder maps.
    zrange = np.stack([lo_g[:, 2], hi_g[:, 2]], axis=1)
    zrange[empty] = (0.0, 1.0)
    n_z = np.maximum(1, np.ceil((zrange[:, 1] - zrange[:, 0]) / CELL_HEIGHT)).astype(np.int64)
    n_z[empty] = 1
    shape = np.stack([np.full(n_parts, N_THETA, dtype=np.int64), n_z], axis=1)
    return center, half, corners, normals, offsets, zrange, shape


def _cell_layout(shape: np.ndarray) -> tuple[np.ndarray, np.ndarray, int]:
    """Each part's cell count (P,), the global id of its first cell (P,) int64, and the cells in all, for cylinder
    maps of ``shape`` (P, 2) (theta, z cells)."""
    sizes = shape[:, 0] * shape[:, 1]
    return sizes, np.concatenate([[0], np.cumsum(sizes)[:-1]]).astype(np.int64), int(sizes.sum())


def build_part_maps(
    vertices: np.ndarray, faces: np.ndarray, face_part: np.ndarray, part_axes: np.ndarray, margin: float
) -> PartMaps:
    """OBBs and cylinder maps of every part of a body mesh.

    vertices (n, 3) metres; faces (f, 3) int; face_part (f,) part index per face; part_axes (P, 2, 3)
    each part's axis segment (start, end) in metres; margin (m): how far the boxes and cells are grown
    so that the body offset outward by up to ``margin`` is still covered. A part without faces gets an
    empty box (offsets -inf, so nothing is inside) and a single empty cell.
    """
    vertices = np.ascontiguousarray(vertices, dtype=np.float64)
    faces = np.ascontiguousarray(faces, dtype=np.int64)
    face_part = np.ascontiguousarray(face_part, dtype=np.int64)
    margin = float(margin)
    n_parts = len(part_axes)
    origin, axes = part_frames(part_axes)
    center, half, corners, normals, offsets, zrange, shape = _boxes_and_shapes(vertices, faces, face_part, origin,
                                                                               axes, n_parts, margin)
    sizes, cell_base, n_cells = _cell_layout(shape)
    face_range = np.empty((len(faces), 4), dtype=np.int64)
    _face_cells(vertices, faces, face_part, origin, axes, zrange, shape, margin, face_range)
    cell_start, cell_faces = _fill_cells(face_part, face_range, shape, cell_base, n_cells)

    return PartMaps(
        obb_center=center,
        obb_axes=axes.copy(),
        obb_half=half,
        obb_corners=corners,
        obb_normals=normals,
        obb_offsets=offsets,
        cyl_origin=origin,
        cyl_axes=axes,
        cyl_zrange=zrange,
        cyl_shape=shape,
        cell_base=cell_base,
        cell_start=cell_start,
        cell_faces=cell_faces,
        margin=margin,
        part_axes=np.asarray(part_axes, dtype=np.float64).copy(),
    )


def rebuild_part_maps(maps: PartMaps, vertices: np.ndarray, faces: np.ndarray, face_part: np.ndarray,
                      part_axes: np.ndarray, changed: np.ndarray) -> PartMaps:
    """``build_part_maps`` of a body whose ``vertices`` (n, 3) m moved, since ``maps`` were built for it, only
    in the parts ``changed`` (q,) int: those parts' boxes and cells are built again from their own faces, every
    other part's are ``maps``' (its cell lists copied as they are), the same arrays as a full build gives. A
    re-posed limb changing shape step by step (``sim.repose``) rebuilds only its 2-4 parts: ~2.5 ms instead of
    ~8 ms for the whole body."""
    vertices = np.ascontiguousarray(vertices, dtype=np.float64)
    faces = np.ascontiguousarray(faces, dtype=np.int64)
    face_part = np.ascontiguousarray(face_part, dtype=np.int64)
    n_parts = len(part_axes)
    redo = np.zeros(n_parts, dtype=bool)
    redo[np.asarray(changed, dtype=np.int64)] = True
    ids = np.flatnonzero(redo[face_part])  # the changed parts' faces, in order
    sub_faces, sub_part = faces[ids], face_part[ids]
    margin = float(maps.margin)
    origin, axes = part_frames(part_axes)
    center, half, corners, normals, offsets, zrange, shape = _boxes_and_shapes(vertices, sub_faces, sub_part, origin,
                                                                               axes, n_parts, margin)
    keep = ~redo  # the parts as they were
    center[keep], half[keep], corners[keep] = maps.obb_center[keep], maps.obb_half[keep], maps.obb_corners[keep]
    normals[keep], offsets[keep] = maps.obb_normals[keep], maps.obb_offsets[keep]
    zrange[keep], shape[keep] = maps.cyl_zrange[keep], maps.cyl_shape[keep]
    sizes, cell_base, n_cells = _cell_layout(shape)
    face_range = np.empty((len(ids), 4), dtype=np.int64)
    _face_cells(vertices, sub_faces, sub_part, origin, axes, zrange, shape, margin, face_range)
    sub_start, sub_faces_of = _fill_cells(sub_part, face_range, shape, cell_base, n_cells)
    # splice: each part's per-cell counts and face lists, from the old maps or the new build
    counts, lists = [], []
    for k in range(n_parts):
        if redo[k]:
            a, b = cell_base[k], cell_base[k] + sizes[k]
            start = sub_start[a:b + 1]
            lists.append(ids[sub_faces_of[start[0]:start[-1]]].astype(np.int32))
        else:
            a, b = maps.cell_base[k], maps.cell_base[k] + sizes[k]
            start = maps.cell_start[a:b + 1]
            lists.append(maps.cell_faces[start[0]:start[-1]])
        counts.append(np.diff(start))
    cell_start = np.zeros(n_cells + 1, dtype=np.int64)
    np.cumsum(np.concatenate(counts), out=cell_start[1:])
    return PartMaps(
        obb_center=center, obb_axes=axes.copy(), obb_half=half, obb_corners=corners, obb_normals=normals,
        obb_offsets=offsets, cyl_origin=origin, cyl_axes=axes, cyl_zrange=zrange, cyl_shape=shape,
        cell_base=cell_base, cell_start=cell_start, cell_faces=np.concatenate(lists), margin=margin,
        part_axes=np.asarray(part_axes, dtype=np.float64).copy(),
    )
