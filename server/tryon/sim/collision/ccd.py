"""Continuous collision of a mesh with itself over a step (issue 53 item 1): every point moves straight from where
the step began (x0) to where it ends (x), and a point-triangle or an edge-edge pair of the mesh crosses where the
four points become coplanar (a zero of the cubic ``_volume`` in the step's fraction t) with the point over the
triangle or the two segments meeting (Provot 1997; Bridson, Fedkiw and Anderson 2002). ``event_side`` says whether
a pair crossed an odd number of times and which side it must be on; the conservative tests (``far_from_*``,
``paths_apart``) pass over pairs that cannot meet within a thickness.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from tryon.geometry import closest_uv_on_triangle

# m: a point whose closest point on a triangle lies further than this along the triangle's plane is beside it,
# not over it (rounding's allowance: a point over the triangle projects onto it exactly).
BESIDE = 1e-5
# bisections of a step to find where a point meets a triangle's plane: 2^-30 of the step's path
CCD_BISECTIONS = 30


@njit(cache=True, nogil=True)
def unit_normal(x, a, b, c):
    """The winding unit normal of triangle (a, b, c) of x (n, 3), and False if it is degenerate."""
    ux, uy, uz = x[b, 0] - x[a, 0], x[b, 1] - x[a, 1], x[b, 2] - x[a, 2]
    vx, vy, vz = x[c, 0] - x[a, 0], x[c, 1] - x[a, 1], x[c, 2] - x[a, 2]
    nx, ny, nz = uy * vz - uz * vy, uz * vx - ux * vz, ux * vy - uy * vx
    ln = math.sqrt(nx * nx + ny * ny + nz * nz)
    if ln < 1e-14:
        return 0.0, 0.0, 0.0, False
    return nx / ln, ny / ln, nz / ln, True


@njit(cache=True, nogil=True)
def moved_apart(x, x0, i, k):
    """m: how far point i moved from x0 to x relative to point k (the length of the difference of their moves)."""
    dx = (x[i, 0] - x0[i, 0]) - (x[k, 0] - x0[k, 0])
    dy = (x[i, 1] - x0[i, 1]) - (x[k, 1] - x0[k, 1])
    dz = (x[i, 2] - x0[i, 2]) - (x[k, 2] - x0[k, 2])
    return math.sqrt(dx * dx + dy * dy + dz * dz)


@njit(cache=True, nogil=True)
def _still(x, x0, i):
    """Whether point i is exactly where it was."""
    return x[i, 0] == x0[i, 0] and x[i, 1] == x0[i, 1] and x[i, 2] == x0[i, 2]


@njit(cache=True, nogil=True)
def over_triangle(px, py, pz, x, a, b, c, nx, ny, nz):
    """(u, v, over): the closest point of triangle (a, b, c) of x to p, and whether p lies over it (within
    ``BESIDE`` of it along its plane, unit normal n)."""
    u, v = closest_uv_on_triangle(px, py, pz, x[a, 0], x[a, 1], x[a, 2], x[b, 0], x[b, 1], x[b, 2],
                                  x[c, 0], x[c, 1], x[c, 2])
    dx = px - (x[a, 0] + u * (x[b, 0] - x[a, 0]) + v * (x[c, 0] - x[a, 0]))
    dy = py - (x[a, 1] + u * (x[b, 1] - x[a, 1]) + v * (x[c, 1] - x[a, 1]))
    dz = pz - (x[a, 2] + u * (x[b, 2] - x[a, 2]) + v * (x[c, 2] - x[a, 2]))
    along = dx * nx + dy * ny + dz * nz
    return u, v, dx * dx + dy * dy + dz * dz - along * along <= BESIDE * BESIDE


@njit(cache=True, nogil=True)
def _volume(i, a, b, c, d, x, x0, t):
    """(p_i - p_a) . ((p_b - p_a) x (p_d - p_c)) m^3 with every point at (1 - t) x0 + t x. With c = a, d the third
    corner: zero when point i lies in triangle (a, b, d)'s plane, its sign the side of the winding normal it is
    on; with i = c: zero when the lines of edges (a, b) and (c, d) meet, its sign which side of the other's line
    each passes."""
    s = 1.0 - t
    ax, ay, az = s * x0[a, 0] + t * x[a, 0], s * x0[a, 1] + t * x[a, 1], s * x0[a, 2] + t * x[a, 2]
    cx, cy, cz = s * x0[c, 0] + t * x[c, 0], s * x0[c, 1] + t * x[c, 1], s * x0[c, 2] + t * x[c, 2]
    px, py, pz = s * x0[i, 0] + t * x[i, 0] - ax, s * x0[i, 1] + t * x[i, 1] - ay, s * x0[i, 2] + t * x[i, 2] - az
    ux, uy, uz = s * x0[b, 0] + t * x[b, 0] - ax, s * x0[b, 1] + t * x[b, 1] - ay, s * x0[b, 2] + t * x[b, 2] - az
    vx, vy, vz = s * x0[d, 0] + t * x[d, 0] - cx, s * x0[d, 1] + t * x[d, 1] - cy, s * x0[d, 2] + t * x[d, 2] - cz
    return px * (uy * vz - uz * vy) + py * (uz * vx - ux * vz) + pz * (ux * vy - uy * vx)


@njit(cache=True, nogil=True)
def _bisect(i, a, b, c, d, x, x0, lo, hi, v_lo):
    """t in [lo, hi] where ``_volume`` (v_lo at lo, the other sign at hi) is zero, by bisection."""
    for _ in range(CCD_BISECTIONS):
        mid = 0.5 * (lo + hi)
        if (_volume(i, a, b, c, d, x, x0, mid) > 0.0) == (v_lo > 0.0):
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


@njit(cache=True, nogil=True)
def event_side(i, a, b, c, d, x, x0, point):
    """(side, crossed) of a point-triangle pair (``point``: i the point, triangle (a, b, d), c = a) or an edge pair
    (edges (a, b) and (c, d), i = c) as every point moves straight from x0 to x: each zero of their ``_volume``
    (a cubic in t: its roots found between the zeros of its derivative) where the point lies over the triangle
    or the segments meet is a crossing; crossed when there is an odd number of them, and side the sign of the
    volume just before the first (where they must go back to), else its sign at the end (the side they are on:
    a point that went round the triangle's edge is on its other side rightly)."""
    v0 = _volume(i, a, b, c, d, x, x0, 0.0)
    v1 = _volume(i, a, b, c, d, x, x0, 1.0 / 3.0)
    v2 = _volume(i, a, b, c, d, x, x0, 2.0 / 3.0)
    v3 = _volume(i, a, b, c, d, x, x0, 1.0)
    if _still(x, x0, i) and _still(x, x0, a) and _still(x, x0, b) and _still(x, x0, c) and _still(x, x0, d):
        return (1.0 if v3 > 0.0 else -1.0), False  # nothing moved: rounding in the in-between points is no event
    # the cubic through the four values, and the zeros of its derivative 3 c3 t^2 + 2 c2 t + c1 in (0, 1): the
    # step is cut there into at most three pieces, on each of which the cubic is monotone (scalars, not arrays:
    # this runs for every listed pair in every pass)
    c1 = -5.5 * v0 + 9.0 * v1 - 4.5 * v2 + v3
    c2 = 9.0 * v0 - 22.5 * v1 + 18.0 * v2 - 4.5 * v3
    c3 = -4.5 * v0 + 13.5 * v1 - 13.5 * v2 + 4.5 * v3
    cut1, cut2 = 1.0, 1.0
    qa, qb, qc = 3.0 * c3, 2.0 * c2, c1
    if abs(qa) > 1e-30:
        disc = qb * qb - 4.0 * qa * qc
        if disc > 0.0:
            r = math.sqrt(disc)
            t1, t2 = (-qb - r) / (2.0 * qa), (-qb + r) / (2.0 * qa)
            t1, t2 = min(t1, t2), max(t1, t2)
            if 0.0 < t1 < 1.0:
                cut1 = t1
                if t2 < 1.0:
                    cut2 = t2
            elif 0.0 < t2 < 1.0:
                cut1 = t2
    elif abs(qb) > 1e-30:
        t = -qc / qb
        if 0.0 < t < 1.0:
            cut1 = t
    crossings = 0
    side = 0.0
    lo, v_lo = 0.0, v0
    for k in range(3):
        hi = cut1 if k == 0 else (cut2 if k == 1 else 1.0)
        if hi <= lo:
            continue
        v_hi = v3 if hi == 1.0 else _volume(i, a, b, c, d, x, x0, hi)
        if (v_lo > 0.0) != (v_hi > 0.0):
            t = _bisect(i, a, b, c, d, x, x0, lo, hi, v_lo)
            if _meets(i, a, b, c, d, x, x0, t, point):
                if crossings == 0:
                    side = 1.0 if v_lo > 0.0 else -1.0
                crossings += 1
        lo, v_lo = hi, v_hi
    if crossings % 2 == 1:
        return side, True
    return (1.0 if v3 > 0.0 else -1.0), False


@njit(cache=True, nogil=True)
def _meets(i, a, b, c, d, x, x0, t, point):
    """Whether, with every point at (1 - t) x0 + t x, point i lies over triangle (a, b, d) (``point``) or the
    segments (a, b) and (c, d) meet, within ``BESIDE``."""
    if point:
        xt = _at(x, x0, t, np.array([i, a, b, d]))
        nx, ny, nz, ok = unit_normal(xt, 1, 2, 3)
        if not ok:
            return True  # the triangle is degenerate where the point meets its plane: taken as crossed
        return over_triangle(xt[0, 0], xt[0, 1], xt[0, 2], xt, 1, 2, 3, nx, ny, nz)[2]
    xt = _at(x, x0, t, np.array([a, b, c, d]))
    sc, tc = closest_on_segments(xt, 0, 1, 2, 3)
    apart = xt[2] + tc * (xt[3] - xt[2]) - xt[0] - sc * (xt[1] - xt[0])
    return apart @ apart <= BESIDE * BESIDE


@njit(cache=True, nogil=True)
def _at(x, x0, t, ids):
    """(len(ids), 3) m: the points ``ids`` at (1 - t) x0 + t x."""
    out = np.empty((len(ids), 3))
    for k in range(len(ids)):
        for ax in range(3):
            out[k, ax] = (1.0 - t) * x0[ids[k], ax] + t * x[ids[k], ax]
    return out


@njit(cache=True, nogil=True)
def closest_on_segments(x, p1, p2, q1, q2):
    """(s, t): parameters of the closest points p1 + s (p2 - p1) and q1 + t (q2 - q1) of two segments of x (n, 3)
    (Ericson, Real-Time Collision Detection 5.1.9), each clamped to [0, 1]."""
    d1x, d1y, d1z = x[p2, 0] - x[p1, 0], x[p2, 1] - x[p1, 1], x[p2, 2] - x[p1, 2]
    d2x, d2y, d2z = x[q2, 0] - x[q1, 0], x[q2, 1] - x[q1, 1], x[q2, 2] - x[q1, 2]
    rx, ry, rz = x[p1, 0] - x[q1, 0], x[p1, 1] - x[q1, 1], x[p1, 2] - x[q1, 2]
    a = d1x * d1x + d1y * d1y + d1z * d1z
    e = d2x * d2x + d2y * d2y + d2z * d2z
    if a <= 1e-20 or e <= 1e-20:
        return 0.0, 0.0
    f = d2x * rx + d2y * ry + d2z * rz
    c = d1x * rx + d1y * ry + d1z * rz
    b = d1x * d2x + d1y * d2y + d1z * d2z
    den = a * e - b * b
    s = min(1.0, max(0.0, (b * f - c * e) / den)) if den > 1e-20 else 0.0
    t = (b * s + f) / e
    if t < 0.0:
        t = 0.0
        s = min(1.0, max(0.0, -c / a))
    elif t > 1.0:
        t = 1.0
        s = min(1.0, max(0.0, (b - c) / a))
    return s, t


@njit(cache=True, nogil=True)
def far_from_triangle(i, f, x, x0, faces, thickness):
    """Whether point i began the step further from triangle f than it moved relative to the triangle's corners in
    it, plus ``thickness``: then they cannot meet (every point of a linearly moving triangle moves as a mix of its
    corners, so the point's move relative to it is no longer than relative to its furthest corner; cloth falling
    as a whole moves little relative to itself). Cloth's near neighbours, always within each other's boxes, are
    passed over so."""
    a, b, c = faces[f, 0], faces[f, 1], faces[f, 2]
    u, v = closest_uv_on_triangle(x0[i, 0], x0[i, 1], x0[i, 2], x0[a, 0], x0[a, 1], x0[a, 2], x0[b, 0], x0[b, 1],
                                  x0[b, 2], x0[c, 0], x0[c, 1], x0[c, 2])
    dd = 0.0
    for ax in range(3):
        q = x0[a, ax] + u * (x0[b, ax] - x0[a, ax]) + v * (x0[c, ax] - x0[a, ax])
        dd += (x0[i, ax] - q) ** 2
    reach = thickness + max(moved_apart(x, x0, i, a), max(moved_apart(x, x0, i, b), moved_apart(x, x0, i, c)))
    return dd > reach * reach


@njit(cache=True, nogil=True)
def far_from_edge(p1, p2, q1, q2, x, x0, thickness):
    """``far_from_triangle`` for two edges."""
    s, t = closest_on_segments(x0, p1, p2, q1, q2)
    dd = 0.0
    for ax in range(3):
        dd += (x0[q1, ax] + t * (x0[q2, ax] - x0[q1, ax]) - x0[p1, ax] - s * (x0[p2, ax] - x0[p1, ax])) ** 2
    reach = thickness + max(max(moved_apart(x, x0, p1, q1), moved_apart(x, x0, p1, q2)),
                            max(moved_apart(x, x0, p2, q1), moved_apart(x, x0, p2, q2)))
    return dd > reach * reach


@njit(cache=True, nogil=True)
def paths_apart(x, x0, p, q, r, a, b, c, pad):
    """Whether the box of points p, q, r's paths (x0 to x) and that of a, b, c's lie more than ``pad`` m apart on an
    axis: then nothing of the one can meet the other within the step."""
    for ax in range(3):
        lo1 = min(min(min(x[p, ax], x0[p, ax]), min(x[q, ax], x0[q, ax])), min(x[r, ax], x0[r, ax]))
        hi1 = max(max(max(x[p, ax], x0[p, ax]), max(x[q, ax], x0[q, ax])), max(x[r, ax], x0[r, ax]))
        lo2 = min(min(min(x[a, ax], x0[a, ax]), min(x[b, ax], x0[b, ax])), min(x[c, ax], x0[c, ax]))
        hi2 = max(max(max(x[a, ax], x0[a, ax]), max(x[b, ax], x0[b, ax])), max(x[c, ax], x0[c, ax]))
        if lo1 > hi2 + pad or lo2 > hi1 + pad:
            return True
    return False
