"""Where cloth went through cloth, measured: an outer garment on the body's side of an inner one, and a
garment's own triangles crossed by its own edges (metrics of outfits, issue 29)."""

from __future__ import annotations

import numpy as np
from numba import njit

from tryon.body.measure import mesh_edges
from tryon.sim.collision.cloth import build_tri_grid, nearest_over, tris_in_cells


@njit(cache=True, nogil=True)
def _signed_distances(points, inner_x, inner_faces, normals, grid_lo, grid_cell, grid_shape, cell_start, cell_tris,
                      reach):
    out = np.full(points.shape[0], np.nan)
    for i in range(points.shape[0]):
        f, s, _, _ = nearest_over(points[i, 0], points[i, 1], points[i, 2], inner_x, inner_faces, normals, grid_lo,
                                  grid_cell, grid_shape, cell_start, cell_tris, reach)
        if f >= 0:
            out[i] = s
    return out


def signed_distances(points: np.ndarray, inner_x: np.ndarray, inner_faces: np.ndarray, normals: np.ndarray,
                     reach: float) -> np.ndarray:
    """(n,) m: the signed distance of each of ``points`` (n, 3) m from another garment's surface (its points
    ``inner_x`` (m, 3), triangles ``inner_faces`` (f, 3) int64, unit ``normals`` (f, 3) pointing to the positive
    side) along the normal of the triangle it lies over (``cloth.nearest_over``); NaN where it lies over none
    of its triangles within ``reach`` m (past its hem, beside it)."""
    grid = build_tri_grid(inner_x, inner_faces, max(reach, 0.01), reach)
    return _signed_distances(np.ascontiguousarray(points, dtype=np.float64), inner_x, inner_faces, normals, grid.lo,
                             grid.cell, grid.shape, grid.cell_start, grid.cell_tris, reach)


def layer_depths(points: np.ndarray, inner_x: np.ndarray, inner_faces: np.ndarray, normals: np.ndarray,
                 reach: float) -> np.ndarray:
    """(n,) m: how far each of ``points`` (n, 3) m lies on the body's side of the inner garment (its points
    ``inner_x`` (m, 3), triangles ``inner_faces`` (f, 3) int64, outward unit ``normals`` (f, 3)), 0 where it is
    outside it or over none of its triangles within ``reach`` m (past its hem, beside it)."""
    s = signed_distances(points, inner_x, inner_faces, normals, reach)
    return np.where(s < 0.0, -s, 0.0)


@njit(cache=True, nogil=True, inline="always")
def crosses(r):
    """Does segment p-q cross triangle a, b, c (Moeller-Trumbore, ends and edges excluded)? ``r``: their
    coordinates (px, py, pz, qx, ..., cz), m; scalars only, no temporary arrays (a drape's shown mesh has tens
    of thousands of edge-triangle pairs to test)."""
    px, py, pz, qx, qy, qz, ax, ay, az, bx, by, bz, cx, cy, cz = r
    e1x, e1y, e1z = bx - ax, by - ay, bz - az
    e2x, e2y, e2z = cx - ax, cy - ay, cz - az
    dx, dy, dz = qx - px, qy - py, qz - pz
    hx, hy, hz = dy * e2z - dz * e2y, dz * e2x - dx * e2z, dx * e2y - dy * e2x
    det = e1x * hx + e1y * hy + e1z * hz
    if abs(det) < 1e-18:
        return False
    inv = 1.0 / det
    sx, sy, sz = px - ax, py - ay, pz - az
    u = inv * (sx * hx + sy * hy + sz * hz)
    if u <= 0.0 or u >= 1.0:
        return False
    kx, ky, kz = sy * e1z - sz * e1y, sz * e1x - sx * e1z, sx * e1y - sy * e1x
    v = inv * (dx * kx + dy * ky + dz * kz)
    if v <= 0.0 or u + v >= 1.0:
        return False
    t = inv * (e2x * kx + e2y * ky + e2z * kz)
    return 0.0 < t < 1.0


@njit(cache=True, nogil=True)
def _find_crossings(x, edges, faces, grid_lo, grid_cell, grid_shape, cell_start, cell_tris, hits):
    """How many (edge, triangle) pairs cross; the first ``len(hits)`` of them written to ``hits`` (c, 2) int64."""
    seen = np.full(faces.shape[0], -1, dtype=np.int64)
    # each triangle's plane (unnormalised normal, offset): an edge with both ends on one side of it is passed over
    # before the full test
    plane = np.empty((faces.shape[0], 4))
    for f in range(faces.shape[0]):
        a, b, cc = faces[f, 0], faces[f, 1], faces[f, 2]
        e1x, e1y, e1z = x[b, 0] - x[a, 0], x[b, 1] - x[a, 1], x[b, 2] - x[a, 2]
        e2x, e2y, e2z = x[cc, 0] - x[a, 0], x[cc, 1] - x[a, 1], x[cc, 2] - x[a, 2]
        nx, ny, nz = e1y * e2z - e1z * e2y, e1z * e2x - e1x * e2z, e1x * e2y - e1y * e2x
        plane[f, 0], plane[f, 1], plane[f, 2] = nx, ny, nz
        plane[f, 3] = nx * x[a, 0] + ny * x[a, 1] + nz * x[a, 2]
    count = 0
    r = np.empty(6, dtype=np.int64)
    near = np.empty(faces.shape[0], dtype=np.int64)
    for e in range(edges.shape[0]):
        i, j = edges[e, 0], edges[e, 1]
        for a in range(3):
            lo, hi = min(x[i, a], x[j, a]), max(x[i, a], x[j, a])
            r[2 * a] = max(0, min(grid_shape[a] - 1, int((lo - grid_lo[a]) / grid_cell)))
            r[2 * a + 1] = max(0, min(grid_shape[a] - 1, int((hi - grid_lo[a]) / grid_cell)))
        for m in range(tris_in_cells(r, grid_shape, cell_start, cell_tris, seen, e, near)):
            f = near[m]
            a, b, cc = faces[f, 0], faces[f, 1], faces[f, 2]
            if i == a or i == b or i == cc or j == a or j == b or j == cc:
                continue
            si = plane[f, 0] * x[i, 0] + plane[f, 1] * x[i, 1] + plane[f, 2] * x[i, 2] - plane[f, 3]
            sj = plane[f, 0] * x[j, 0] + plane[f, 1] * x[j, 1] + plane[f, 2] * x[j, 2] - plane[f, 3]
            if si * sj >= 0.0:
                continue
            if crosses((x[i, 0], x[i, 1], x[i, 2], x[j, 0], x[j, 1], x[j, 2], x[a, 0], x[a, 1], x[a, 2],
                        x[b, 0], x[b, 1], x[b, 2], x[cc, 0], x[cc, 1], x[cc, 2])):
                if count < hits.shape[0]:
                    hits[count, 0] = e
                    hits[count, 1] = f
                count += 1
    return count


def find_crossings(x: np.ndarray, edges: np.ndarray, faces: np.ndarray, grid, capacity: int = 0) -> np.ndarray:
    """(c, 2) int64: every (edge, triangle) pair of one mesh (``x`` (n, 3) m float64, ``edges`` (e, 2) int64,
    ``faces`` (f, 3) int64, ``grid`` their ``build_tri_grid``) that crosses, the edge sharing no corner with the
    triangle; ``capacity``: the expected number at most (a second search if there are more)."""
    hits = np.empty((max(0, capacity), 2), dtype=np.int64)
    n = _find_crossings(x, edges, faces, grid.lo, grid.cell, grid.shape, grid.cell_start, grid.cell_tris, hits)
    if n > len(hits):
        hits = np.empty((n, 2), dtype=np.int64)
        _find_crossings(x, edges, faces, grid.lo, grid.cell, grid.shape, grid.cell_start, grid.cell_tris, hits)
    return hits[:n]


def self_intersections(vertices: np.ndarray, faces: np.ndarray, cell: float = 0.02,
                       edges: np.ndarray | None = None) -> int:
    """How many (edge, triangle) pairs of one mesh (``vertices`` (n, 3) m, ``faces`` (f, 3)) cross, the edge
    sharing no corner with the triangle: 0 for a garment whose cloth never passes through itself. Each pair
    is counted once (a triangle met in several cells of an edge's box is tested once). ``edges`` (e, 2) int64:
    the mesh's edges if known (``GarmentModel.edges``), else found here. ~6 ms for a catalogue drape's shown mesh."""
    x = np.ascontiguousarray(vertices, dtype=np.float64)
    f = np.ascontiguousarray(faces, dtype=np.int64)
    if edges is None:
        edges = mesh_edges(f)
    grid = build_tri_grid(x, f, cell, 0.0)
    return int(_find_crossings(x, edges, f, grid.lo, grid.cell, grid.shape, grid.cell_start, grid.cell_tris,
                               np.empty((0, 2), dtype=np.int64)))
