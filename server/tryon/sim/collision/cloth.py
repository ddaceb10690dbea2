"""Cloth on cloth: an outer garment's points kept outside an inner garment's surface (outfits, issue 29).

The inner garment is a moving collider: its current triangles go into a uniform grid each time
(``build_tri_grid``, about a millisecond for a few thousand triangles), each triangle in every cell its box,
grown by the query reach, overlaps; a point then looks only at the triangles of its own cell. Which side is
outside is decided once, from the caller's directions away from the body (``face_sides``), and kept while the
cloth moves (``signed_face_normals``). ``push_outside_layer`` is the position-based
point-triangle constraint, one-sided: n . (p - q) >= gap, q the closest point of the nearest triangle, its
correction shared between the point and the triangle's corners by inverse mass and barycentric weight.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from tryon.geometry import closest_uv_on_triangle, triangle_normal

# Cells per axis at most: a garment's box (~1 x 1.8 x 0.6 m) at 3 cm cells needs ~60; the cap keeps a grid
# over a stray far point from allocating without bound (the cells just grow).
MAX_CELLS_PER_AXIS = 128
# m: a point whose closest point on the nearest triangle lies further than this beside the triangle's plane
# (along the surface, not across it) is past the inner garment's edge (below its hem, beyond a cuff) and is
# not pushed: it is not over that garment at all.
PAST_EDGE = 0.002
# ``nearest_over`` passes over a triangle whose box lies further than this x the squared distance of the nearest
# found so far: the box is never further than the triangle, and the factor keeps rounding from dropping a tie.
BOX_SLACK = 1.0 + 1e-9


class TriGrid(NamedTuple):
    """Triangles by cell: lo (3,) m the grid's corner, cell (float) m the cell size, shape (3,) int64 cells per
    axis; cell_start (c + 1,) int64 and cell_tris (t,) int64: the triangles of cell c are
    cell_tris[cell_start[c]:cell_start[c + 1]], c = (ix * shape[1] + iy) * shape[2] + iz."""

    lo: np.ndarray
    cell: float
    shape: np.ndarray
    cell_start: np.ndarray
    cell_tris: np.ndarray


@njit(cache=True, nogil=True)
def _cell_ranges(lo, cell, shape, vertices, faces, pad):
    """(f, 6) int64: each triangle's cell index ranges (ix0, ix1, iy0, iy1, iz0, iz1), inclusive, of its box grown
    by pad."""
    out = np.empty((faces.shape[0], 6), dtype=np.int64)
    for f in range(faces.shape[0]):
        for a in range(3):
            t0 = vertices[faces[f, 0], a]
            t1 = vertices[faces[f, 1], a]
            t2 = vertices[faces[f, 2], a]
            mn = min(t0, min(t1, t2)) - pad
            mx = max(t0, max(t1, t2)) + pad
            out[f, 2 * a] = max(0, min(shape[a] - 1, int((mn - lo[a]) / cell)))
            out[f, 2 * a + 1] = max(0, min(shape[a] - 1, int((mx - lo[a]) / cell)))
    return out


@njit(cache=True, nogil=True)
def fill_grid(vertices, faces, lo, cell, shape, pad):
    """CSR (cell_start (C + 1,) int64, cell_tris (K,) int64) of the triangles ``faces`` (f, 3) int64 over
    ``vertices`` (n, 3) m in the cells of a grid (corner ``lo`` (3,) m, cells ``cell`` m, ``shape`` (3,) int64; cell
    id ``(ix * shape[1] + iy) * shape[2] + iz``) that their boxes grown by ``pad`` m overlap. Serial. Each
    triangle's cells are found once for both passes (the count and the fill): twice, each with a small array
    of its own, they were half of an outfit step's grid building."""
    return fill_ranges(_cell_ranges(lo, cell, shape, vertices, faces, pad), shape)


@njit(cache=True, nogil=True)
def fill_ranges(r, shape):
    """CSR (cell_start (C + 1,) int64, cell_tris (K,) int64) of triangles in the cells of their inclusive cell
    ranges r (f, 6) int64 (ix0, ix1, iy0, iy1, iz0, iz1) in a grid of ``shape`` (3,) int64 cells."""
    n_cells = shape[0] * shape[1] * shape[2]
    count = np.zeros(n_cells + 1, dtype=np.int64)
    for f in range(r.shape[0]):
        for ix in range(r[f, 0], r[f, 1] + 1):
            for iy in range(r[f, 2], r[f, 3] + 1):
                for iz in range(r[f, 4], r[f, 5] + 1):
                    count[(ix * shape[1] + iy) * shape[2] + iz + 1] += 1
    start = np.cumsum(count)
    fill = start[:-1].copy()
    tris = np.empty(start[-1], dtype=np.int64)
    for f in range(r.shape[0]):
        for ix in range(r[f, 0], r[f, 1] + 1):
            for iy in range(r[f, 2], r[f, 3] + 1):
                for iz in range(r[f, 4], r[f, 5] + 1):
                    c = (ix * shape[1] + iy) * shape[2] + iz
                    tris[fill[c]] = f
                    fill[c] += 1
    return start, tris


@njit(cache=True, nogil=True)
def tris_in_cells(r, shape, cell_start, cell_tris, seen, stamp, out):
    """How many triangles the cells of inclusive ranges r (6,) int64 (ix0, ix1, iy0, iy1, iz0, iz1) of a grid of
    ``shape`` (3,) cells (``fill_grid``'s CSR ``cell_start``, ``cell_tris``) hold, each once: their ids into ``out``
    (f,) int64. ``seen`` (f,) int64: a triangle already marked with ``stamp`` is passed over; the ones found are
    marked."""
    n = 0
    for ix in range(r[0], r[1] + 1):
        for iy in range(r[2], r[3] + 1):
            for iz in range(r[4], r[5] + 1):
                c = (ix * shape[1] + iy) * shape[2] + iz
                for q in range(cell_start[c], cell_start[c + 1]):
                    f = cell_tris[q]
                    if seen[f] != stamp:
                        seen[f] = stamp
                        out[n] = f
                        n += 1
    return n


def grid_frame(lo: np.ndarray, hi: np.ndarray, cell: float, pad: float) -> tuple[np.ndarray, float, np.ndarray]:
    """(origin (3,) m, cell size m, shape (3,) int64) of a grid over the box ``lo``-``hi`` (3,) m grown by ``pad`` m,
    cells of about ``cell`` m, at most ``MAX_CELLS_PER_AXIS`` along any axis."""
    origin = lo - pad
    extent = hi + pad - origin
    size = max(float(cell), float(extent.max()) / MAX_CELLS_PER_AXIS)
    return origin, size, np.maximum(1, np.ceil(extent / size)).astype(np.int64)


def build_tri_grid(vertices: np.ndarray, faces: np.ndarray, cell: float, pad: float) -> TriGrid:
    """A ``TriGrid`` of the triangles ``faces`` (f, 3) int64 over ``vertices`` (m, 3) m, cells of about ``cell``
    m, each triangle in every cell its box grown by ``pad`` m overlaps (a point within ``pad`` of a triangle
    finds it in its own cell)."""
    lo, size, shape = grid_frame(vertices.min(axis=0), vertices.max(axis=0), cell, pad)
    start, tris = fill_grid(vertices, faces, lo, size, shape, float(pad))
    return TriGrid(lo, size, shape, start, tris)


@njit(cache=True, nogil=True)
def overlap(x, inner_x, inner_faces, reach):
    """Where a layer x (k, 3) m and the layer under it (``inner_x`` (m, 3) m, triangles ``inner_faces``
    (f, 3) int64) can touch: (active (k,) bool: the points within the inner layer's box grown by ``reach`` m,
    close (f,) bool: the inner triangles whose boxes come within ``reach`` of the active points' box)."""
    lo = np.full(3, np.inf)
    hi = np.full(3, -np.inf)
    for i in range(inner_x.shape[0]):
        for a in range(3):
            lo[a] = min(lo[a], inner_x[i, a])
            hi[a] = max(hi[a], inner_x[i, a])
    active = np.zeros(x.shape[0], dtype=np.bool_)
    alo = np.full(3, np.inf)
    ahi = np.full(3, -np.inf)
    for i in range(x.shape[0]):
        inside = True
        for a in range(3):
            if x[i, a] < lo[a] - reach or x[i, a] > hi[a] + reach:
                inside = False
        if inside:
            active[i] = True
            for a in range(3):
                alo[a] = min(alo[a], x[i, a])
                ahi[a] = max(ahi[a], x[i, a])
    close = np.zeros(inner_faces.shape[0], dtype=np.bool_)
    for f in range(inner_faces.shape[0]):
        near = True
        for a in range(3):
            p0 = inner_x[inner_faces[f, 0], a]
            p1 = inner_x[inner_faces[f, 1], a]
            p2 = inner_x[inner_faces[f, 2], a]
            if max(p0, max(p1, p2)) < alo[a] - reach or min(p0, min(p1, p2)) > ahi[a] + reach:
                near = False
        close[f] = near
    return active, close


@njit(cache=True, nogil=True)
def outward_from_axes(points, axes):
    """(k, 3) unit directions away from a body at ``points`` (k, 3) m: from the nearest point of the nearest
    of its parts' axis segments ``axes`` (P, 2, 3) m to the point."""
    out = np.zeros((points.shape[0], 3))
    for i in range(points.shape[0]):
        best = np.inf
        for p in range(axes.shape[0]):
            ax, ay, az = axes[p, 0, 0], axes[p, 0, 1], axes[p, 0, 2]
            ux, uy, uz = axes[p, 1, 0] - ax, axes[p, 1, 1] - ay, axes[p, 1, 2] - az
            uu = max(ux * ux + uy * uy + uz * uz, 1e-12)
            t = ((points[i, 0] - ax) * ux + (points[i, 1] - ay) * uy + (points[i, 2] - az) * uz) / uu
            t = min(1.0, max(0.0, t))
            gx = points[i, 0] - (ax + t * ux)
            gy = points[i, 1] - (ay + t * uy)
            gz = points[i, 2] - (az + t * uz)
            dd = gx * gx + gy * gy + gz * gz
            if dd < best:
                best = dd
                out[i, 0], out[i, 1], out[i, 2] = gx, gy, gz
        ln = max(math.sqrt(best), 1e-12)
        out[i, 0] /= ln
        out[i, 1] /= ln
        out[i, 2] /= ln
    return out


@njit(cache=True, nogil=True)
def face_sides(vertices, faces, outward):
    """(f,) +1 or -1 per triangle of ``faces`` (f, 3) int64 over ``vertices`` (m, 3): the sign that turns its
    winding normal (b - a) x (c - a) along ``outward`` (m, 3) (directions away from the body) summed over its
    corners. Each triangle by its own vote: a garment file's winding is not to be trusted, and a consistently
    wound garment turned as a whole by the vote of its piece did worse on the outfit bench (a skirt under a
    T-shirt, shorts under a long-sleeve: their triangles across the body's axes, at the crotch and between the
    legs, are better turned one by one)."""
    normal = signed_face_normals(vertices, faces, np.ones(faces.shape[0]))
    out = np.empty(faces.shape[0])
    for f in range(faces.shape[0]):
        vote = 0.0
        for a in range(3):
            vote += normal[f, a] * (outward[faces[f, 0], a] + outward[faces[f, 1], a] + outward[faces[f, 2], a])
        out[f] = -1.0 if vote < 0.0 else 1.0
    return out


@njit(cache=True, nogil=True)
def signed_face_normals(vertices, faces, sides):
    """(f, 3) unit winding normals of ``faces`` (f, 3) int64 over ``vertices`` (m, 3), times ``sides`` (f,)."""
    out = np.zeros((faces.shape[0], 3))
    for f in range(faces.shape[0]):
        nx, ny, nz = triangle_normal(vertices, faces[f, 0], faces[f, 1], faces[f, 2])
        ln = math.sqrt(nx * nx + ny * ny + nz * nz)
        if ln == 0.0:
            continue
        ln = sides[f] / ln
        out[f, 0] = nx * ln
        out[f, 1] = ny * ln
        out[f, 2] = nz * ln
    return out


@njit(cache=True, nogil=True)
def nearest_over(px, py, pz, inner_x, inner_faces, normals, grid_lo, grid_cell, grid_shape, cell_start, cell_tris,
                 reach):
    """The triangle p lies over: the nearest within ``reach`` m whose closest point is not past its edge
    (``PAST_EDGE``). Returns (triangle or -1, signed distance along its normal m, u, v of the closest point)."""
    ix = int((px - grid_lo[0]) / grid_cell)
    iy = int((py - grid_lo[1]) / grid_cell)
    iz = int((pz - grid_lo[2]) / grid_cell)
    if px < grid_lo[0] or py < grid_lo[1] or pz < grid_lo[2] or ix >= grid_shape[0] or iy >= grid_shape[1] \
            or iz >= grid_shape[2]:
        return -1, 0.0, 0.0, 0.0
    c = (ix * grid_shape[1] + iy) * grid_shape[2] + iz
    best, best_dd, best_s, best_u, best_v = -1, reach * reach, 0.0, 0.0, 0.0
    for q in range(cell_start[c], cell_start[c + 1]):
        f = cell_tris[q]
        a, b, cc = inner_faces[f, 0], inner_faces[f, 1], inner_faces[f, 2]
        nx, ny, nz = normals[f, 0], normals[f, 1], normals[f, 2]
        if nx == 0.0 and ny == 0.0 and nz == 0.0:
            continue  # a degenerate triangle
        ax, ay, az = inner_x[a, 0], inner_x[a, 1], inner_x[a, 2]
        bx, by, bz = inner_x[b, 0], inner_x[b, 1], inner_x[b, 2]
        cx, cy, cz = inner_x[cc, 0], inner_x[cc, 1], inner_x[cc, 2]
        # no nearer than its box: a triangle whose box is further than the best so far is passed over without the
        # closest point (the slack keeps a tie the exact test would take)
        gx = max(0.0, min(ax, min(bx, cx)) - px, px - max(ax, max(bx, cx)))
        gy = max(0.0, min(ay, min(by, cy)) - py, py - max(ay, max(by, cy)))
        gz = max(0.0, min(az, min(bz, cz)) - pz, pz - max(az, max(bz, cz)))
        if gx * gx + gy * gy + gz * gz > best_dd * BOX_SLACK:
            continue
        u, v = closest_uv_on_triangle(px, py, pz, ax, ay, az, bx, by, bz, cx, cy, cz)
        dx = px - (ax + u * (bx - ax) + v * (cx - ax))
        dy = py - (ay + u * (by - ay) + v * (cy - ay))
        dz = pz - (az + u * (bz - az) + v * (cz - az))
        dd = dx * dx + dy * dy + dz * dz
        if dd >= best_dd:
            continue
        s = dx * nx + dy * ny + dz * nz
        beside = dd - s * s  # squared distance along the surface: past the triangle's edge
        if beside > PAST_EDGE * PAST_EDGE:
            continue
        best, best_dd, best_s, best_u, best_v = f, dd, s, u, v
    return best, best_s, best_u, best_v


@njit(cache=True, nogil=True)
def push_outside_layer(x, x_prev, inv_mass, active, inner_x, inner_prev, inner_inv_mass, inner_faces, normals,
                       grid_lo, grid_cell, grid_shape, cell_start, cell_tris, gap, reach, near, has_plane,
                       plane_point, plane_normal, max_push, pressed):
    """Keep every ``active`` (k,) bool point of x (k, 3) m at least ``gap`` m outside the inner layer (its
    points inner_x (m, 3), triangles ``inner_faces`` (f, 3) int64 with outward unit ``normals`` (f, 3), in the
    grid ``grid_*``, ``cell_start``, ``cell_tris`` of a ``TriGrid``), in place.

    For a point over a triangle (``nearest_over``) with signed distance s < gap along its normal, the
    constraint C = s - gap >= 0 is projected: lambda = (gap - s) / (w_p + sum_k w_k b_k^2), the point moves by
    w_p lambda n and corner k by -w_k b_k lambda n (w: inverse masses; b: the closest point's barycentric
    weights), so the inner garment carries the outer one's weight; with the inner inverse masses 0 it is a
    fixed collider. The previous positions move with the positions (the push adds no velocity).

    A point pushed, or within ``near`` m beyond ``gap``, gets a contact plane (``has_plane`` (k,) bool,
    ``plane_point`` (k, 3) m, ``plane_normal`` (k, 3)) as the body collision leaves one: the next step's
    substeps keep it on the plane (with friction), so the springs cannot pull it back through the layer
    between two layer collisions. ``max_push`` m: the most a point moves in one call (a layer that starts
    centimetres inside another comes out over a few calls, its springs following, instead of in one jump).
    ``pressed`` (m,) bool out: the inner corners an outer point pushed against (set, never cleared here).
    Returns how many points were pushed. Serial: a triangle's corners are shared between points, so the loop
    is not split between threads.
    """
    pushed = 0
    for i in range(x.shape[0]):
        if not active[i]:
            continue
        f, s, u, v = nearest_over(x[i, 0], x[i, 1], x[i, 2], inner_x, inner_faces, normals, grid_lo, grid_cell,
                                  grid_shape, cell_start, cell_tris, reach)
        if f < 0 or s >= gap + near:
            continue
        if s >= gap:  # near: a plane where the layer lies, no push
            has_plane[i] = True
            for ax in range(3):
                plane_point[i, ax] = x[i, ax] - (s - gap) * normals[f, ax]
                plane_normal[i, ax] = normals[f, ax]
            continue
        a, b, c = inner_faces[f, 0], inner_faces[f, 1], inner_faces[f, 2]
        ba, bb, bc = 1.0 - u - v, u, v
        wp = inv_mass[i]
        denominator = wp + inner_inv_mass[a] * ba * ba + inner_inv_mass[b] * bb * bb + inner_inv_mass[c] * bc * bc
        if denominator <= 0.0:
            continue
        lam = min(gap - s, max_push) / denominator
        pressed[a] = True
        pressed[b] = True
        pressed[c] = True
        wa, wb, wc = inner_inv_mass[a] * ba * lam, inner_inv_mass[b] * bb * lam, inner_inv_mass[c] * bc * lam
        for ax in range(3):
            n = normals[f, ax]
            d = wp * lam * n
            x[i, ax] += d
            x_prev[i, ax] += d
            inner_x[a, ax] -= wa * n
            inner_prev[a, ax] -= wa * n
            inner_x[b, ax] -= wb * n
            inner_prev[b, ax] -= wb * n
            inner_x[c, ax] -= wc * n
            inner_prev[c, ax] -= wc * n
            plane_point[i, ax] = x[i, ax]
            plane_normal[i, ax] = n
        has_plane[i] = True
        pushed += 1
    return pushed


def push_layer(x: np.ndarray, x_prev: np.ndarray, inv_mass: np.ndarray, active: np.ndarray, inner_x: np.ndarray,
               inner_prev: np.ndarray, inner_inv_mass: np.ndarray, inner_faces: np.ndarray, normals: np.ndarray,
               grid: TriGrid, gap: float, reach: float, near: float = 0.0,
               planes: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None, max_push: float = np.inf,
               pressed: np.ndarray | None = None) -> int:
    """``push_outside_layer`` with the grid as one ``TriGrid``, the planes as (has_plane, point, normal) or None
    (no planes kept), ``pressed`` None (not wanted)."""
    if planes is None:
        planes = (np.zeros(len(x), dtype=np.bool_), np.empty((len(x), 3)), np.empty((len(x), 3)))
    if pressed is None:
        pressed = np.zeros(len(inner_x), dtype=np.bool_)
    return push_outside_layer(x, x_prev, inv_mass, active, inner_x, inner_prev, inner_inv_mass, inner_faces,
                              normals, grid.lo, grid.cell, grid.shape, grid.cell_start, grid.cell_tris, gap, reach,
                              near, *planes, float(max_push), pressed)
