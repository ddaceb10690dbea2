"""The nearest body vertex of each part to garment points: one uniform grid per part, in the part's rest frame.

A re-pose (``repose.PoseTransition``) weighs every garment point by its distance to each body part's nearest
vertex, every step of the body's motion, and first asks which limbs come near the garment on their way. A
k-d tree per part (``scipy.spatial.cKDTree``) answered both exactly but cost ~9 ms a step for the T-shirt M's 874
points against the 10 parts (the step's own work is ~2 ms), the far parts most: a query walks the tree until it
has ruled out every nearer branch.

Here each part's vertices are binned in a uniform grid of ``CELL`` cubes over its box (``build_grids``, ~0.3 ms
for the whole body), and a query (``nearest_distances``) visits the cells in rings of growing Chebyshev radius
around the point's cell (the cell nearest to it when it is outside the box), until the nearest vertex found is
nearer than any cell not yet visited: the same exact distance as the tree's. A point far from a part rules the
part's far cells out after a ring or two. ``any_within`` is the bounded form: whether some point lies within a
given distance of a part, stopping at the first.

Every point is taken into the part's rest frame first (``moves``: each part's rigid motion, the part's vertices
where they are now are R v + t, so a point x is looked up as R^T (x - t)), so the grids are built only when a
part's own shape changes, never when it only turns.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

# m: the edge of a grid cell, ~5 x the body mesh's vertex spacing (~1-1.5 cm on the torso): cloth a few cm
# from a part finds its nearest vertex within the 27 cells around it. Finer cells make it search many rings of
# nearly empty cells: the weights of every part on the T-shirt M, the trousers M and the long-sleeve M where
# they are put on took 9.6, 3.5, 2.3, 2.2 ms (T-shirt) with 2, 4, 6, 10 cm cells, 15.6, 5.4, 3.5, 3.3 ms
# (trousers); the k-d trees of the parts 6.3 and 12.5 ms.
CELL = 0.06


class PartGrids(NamedTuple):
    """P parts' vertices binned in grids (``build_grids``): lo (P, 3) m, each grid's lowest corner; dims (P, 3)
    int64, its cells along x, y, z; base (P,) int64, its first cell's index in cell_start; cell_start (C + 1,)
    int64, where each cell's vertices begin in ``points``; points (V, 3) m, the vertices grouped by cell; cell: m,
    the cells' edge."""

    lo: np.ndarray
    dims: np.ndarray
    base: np.ndarray
    cell_start: np.ndarray
    points: np.ndarray
    cell: float


def build_grids(vertices: np.ndarray, vertex_part: np.ndarray, n_parts: int, cell: float = CELL) -> PartGrids:
    """The grids of the ``n_parts`` parts of a body whose vertices (n, 3) m belong to ``vertex_part`` (n,) int
    (parts without vertices get an empty 1-cell grid)."""
    vertices = np.ascontiguousarray(vertices, dtype=np.float64)
    vertex_part = np.ascontiguousarray(vertex_part, dtype=np.int64)
    lo = np.zeros((n_parts, 3))
    hi = np.zeros((n_parts, 3))
    _part_boxes(vertices, vertex_part, lo, hi)
    dims = np.maximum(np.floor((hi - lo) / cell).astype(np.int64) + 1, 1)
    base = np.zeros(n_parts, dtype=np.int64)
    base[1:] = np.cumsum(dims.prod(axis=1))[:-1]
    n_cells = int(dims.prod(axis=1).sum())
    cell_start = np.zeros(n_cells + 1, dtype=np.int64)
    points = np.empty((len(vertices), 3))
    _bin(vertices, vertex_part, lo, dims, base, float(cell), cell_start, points)
    return PartGrids(lo, dims, base, cell_start, points, float(cell))


@njit(cache=True)
def _part_boxes(vertices, vertex_part, lo, hi):
    seen = np.zeros(lo.shape[0], dtype=np.bool_)
    for i in range(vertices.shape[0]):
        k = vertex_part[i]
        for a in range(3):
            v = vertices[i, a]
            if not seen[k] or v < lo[k, a]:
                lo[k, a] = v
            if not seen[k] or v > hi[k, a]:
                hi[k, a] = v
        seen[k] = True


@njit(cache=True)
def _cell_of(v, lo, dims, cell, out):
    """The cell (3,) int64 of grid ``lo``, ``dims`` (3,) nearest to point v (3,), into ``out``."""
    for a in range(3):
        c = int(np.floor((v[a] - lo[a]) / cell))
        out[a] = min(max(c, 0), dims[a] - 1)


@njit(cache=True)
def _bin(vertices, vertex_part, lo, dims, base, cell, cell_start, points):
    """Counting sort of the vertices by cell: fills ``cell_start`` (C + 1,) and ``points`` (n, 3)."""
    n = vertices.shape[0]
    ids = np.empty(n, dtype=np.int64)
    c = np.empty(3, dtype=np.int64)
    for i in range(n):
        k = vertex_part[i]
        _cell_of(vertices[i], lo[k], dims[k], cell, c)
        ids[i] = base[k] + (c[0] * dims[k, 1] + c[1]) * dims[k, 2] + c[2]
        cell_start[ids[i] + 1] += 1
    for j in range(1, cell_start.shape[0]):
        cell_start[j] += cell_start[j - 1]
    fill = cell_start[:-1].copy()
    for i in range(n):
        points[fill[ids[i]]] = vertices[i]
        fill[ids[i]] += 1


@njit(cache=True)
def _box_gap2(p, lo, cell, i, j, k):
    """Squared distance (m^2) from p (3,) to cell (i, j, k) of a grid whose lowest corner is ``lo`` (3,)."""
    d2 = 0.0
    for a, c in ((0, i), (1, j), (2, k)):
        low = lo[a] + c * cell
        gap = max(low - p[a], p[a] - low - cell, 0.0)
        d2 += gap * gap
    return d2


@njit(cache=True)
def _nearest(p, grids_lo, grids_dims, base, cell_start, points, cell, stop, limit):
    """Distance (m) from p (3,), in the part's rest frame, to the nearest vertex of one part's grid
    (``grids_lo`` (3,), ``grids_dims`` (3,) int64, ``base``) if it is nearer than ``limit`` m (inf if not, or
    for an empty part); ends early once a vertex nearer than ``stop`` m is found (that distance; ``stop`` = 0
    for the exact nearest)."""
    c = np.empty(3, dtype=np.int64)
    _cell_of(p, grids_lo, grids_dims, cell, c)
    nx, ny, nz = grids_dims[0], grids_dims[1], grids_dims[2]
    limit2 = limit * limit
    best2 = limit2
    r = 0
    while True:
        i0, i1 = max(c[0] - r, 0), min(c[0] + r, nx - 1)
        j0, j1 = max(c[1] - r, 0), min(c[1] + r, ny - 1)
        k0, k1 = max(c[2] - r, 0), min(c[2] + r, nz - 1)
        for i in range(i0, i1 + 1):
            for j in range(j0, j1 + 1):
                shell = abs(i - c[0]) == r or abs(j - c[1]) == r
                k = k0
                while k <= k1:
                    g = base + (i * ny + j) * nz + k
                    if (shell or abs(k - c[2]) == r) and cell_start[g] < cell_start[g + 1] and \
                            _box_gap2(p, grids_lo, cell, i, j, k) < best2:
                        for q in range(cell_start[g], cell_start[g + 1]):
                            d0 = points[q, 0] - p[0]
                            d1 = points[q, 1] - p[1]
                            d2 = points[q, 2] - p[2]
                            d = d0 * d0 + d1 * d1 + d2 * d2
                            if d < best2:
                                best2 = d
                    if shell or k == c[2] + r:
                        k += 1
                    else:
                        k = c[2] + r  # the cells between are inside the rings already visited
        if best2 < stop * stop:
            return np.sqrt(best2)
        # the nearest any cell not yet visited can be: those lie in the grid's box beyond a face of the visited
        # cube, on a side where the grid goes on (the distance from p to that part of the box)
        bound2 = np.inf
        for a in range(3):
            for side in range(2):
                if side == 0 and c[a] - r > 0:
                    lo_a, hi_a = grids_lo[a], grids_lo[a] + (c[a] - r) * cell
                elif side == 1 and c[a] + r < grids_dims[a] - 1:
                    lo_a, hi_a = grids_lo[a] + (c[a] + r + 1) * cell, grids_lo[a] + grids_dims[a] * cell
                else:
                    continue
                d2 = 0.0
                for b in range(3):
                    if b == a:
                        lo_b, hi_b = lo_a, hi_a
                    else:
                        lo_b, hi_b = grids_lo[b], grids_lo[b] + grids_dims[b] * cell
                    gap = max(lo_b - p[b], p[b] - hi_b, 0.0)
                    d2 += gap * gap
                bound2 = min(bound2, d2)
        if bound2 == np.inf or bound2 >= best2:
            return np.sqrt(best2) if best2 < limit2 else np.inf
        r += 1


@njit(cache=True, nogil=True)
def nearest_distances(x, moves, wanted, lo, dims, base, cell_start, points, cell, soften, spread, out):
    """Distance (m) from each point x (k, 3) m to the nearest vertex of each part, the parts moved by ``moves``
    (P, 4, 4) from the grids' rest shape, into ``out`` (k, P): exact (the grid's rings are searched until no
    cell left can hold a nearer vertex) for the part whose box is nearest the point, at distance d, and for
    every part nearer than (d + soften) * spread - soften; inf for the parts beyond (with inverse-power weights
    (distance + soften) ** -q, each of those weighs under spread ** -q of the nearest part). A point with none
    of the ``wanted`` (P,) bool parts that near has only that first distance (its weights on the wanted parts
    are 0 whatever the others are). ``spread`` = inf: every distance exact. Each point on its own: no shared
    writes."""
    n_parts = lo.shape[0]
    p = np.empty((n_parts, 3))
    gap = np.empty(n_parts)
    for n in range(x.shape[0]):
        first = -1
        for k in range(n_parts):
            g2 = 0.0
            for a in range(3):  # R^T (x - t): into the part's rest frame
                v = ((x[n, 0] - moves[k, 0, 3]) * moves[k, 0, a] + (x[n, 1] - moves[k, 1, 3]) * moves[k, 1, a]
                     + (x[n, 2] - moves[k, 2, 3]) * moves[k, 2, a])
                p[k, a] = v
                side = max(lo[k, a] - v, v - (lo[k, a] + dims[k, a] * cell), 0.0)
                g2 += side * side
            gap[k] = np.sqrt(g2)
            if cell_start[base[k]] < cell_start[base[k] + dims[k, 0] * dims[k, 1] * dims[k, 2]] and (
                    first < 0 or gap[k] < gap[first]):
                first = k
        if first < 0:
            out[n, :] = np.inf
            continue
        near = _nearest(p[first], lo[first], dims[first], base[first], cell_start, points, cell, 0.0, np.inf)
        cut = (near + soften) * spread - soften
        out[n, :] = np.inf
        out[n, first] = near
        needed = wanted[first]
        for k in range(n_parts):
            needed = needed or (wanted[k] and gap[k] < cut)
        if not needed:
            continue
        for k in range(n_parts):
            if k == first:
                out[n, k] = near
            elif gap[k] >= cut:
                out[n, k] = np.inf
            else:
                out[n, k] = _nearest(p[k], lo[k], dims[k], base[k], cell_start, points, cell, 0.0, cut)


@njit(cache=True, nogil=True)
def any_within(x, move, k, lo, dims, base, cell_start, points, cell, reach) -> bool:
    """Whether some point of x (k, 3) m lies within ``reach`` m of a vertex of part ``k`` moved by ``move``
    (4, 4). Points farther than ``reach`` from the part's grid box are not looked up."""
    p = np.empty(3)
    for n in range(x.shape[0]):
        outside = 0.0
        for a in range(3):
            p[a] = ((x[n, 0] - move[0, 3]) * move[0, a] + (x[n, 1] - move[1, 3]) * move[1, a]
                    + (x[n, 2] - move[2, 3]) * move[2, a])
            below = lo[k, a] - p[a]
            above = p[a] - (lo[k, a] + dims[k, a] * cell)
            gap = max(below, above, 0.0)
            outside += gap * gap
        if outside >= reach * reach:
            continue
        if _nearest(p, lo[k], dims[k], base[k], cell_start, points, cell, reach, reach) < reach:
            return True
    return False
