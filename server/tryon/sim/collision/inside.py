"""Is a point of a triangle's plane inside the triangle? Three tests (SPEC section 4).

- ``inside_angle``: the paper's method: P is inside iff at two vertices the two angles P makes with the
  adjacent edges add up to the vertex's interior angle. Angles via atan2(|u x v|, u . v) rather than
  acos, which loses half its digits near 0 and pi (a point on an edge would be misjudged).
- ``inside_area``: the three sub-triangle areas PAB + PBC + PCA add up to ABC.
- ``inside_barycentric``: barycentric coordinates from dot products (the test inside Moeller-Trumbore):
  u, v >= 0 and u + v <= 1.

All three count points on an edge or at a vertex as inside (relative tolerance ``EPS``), so a ray through
a shared edge always hits one of the two triangles. Benchmark (``benchmark()``: 2,000,000 ray hits on
random triangles, 1/8 of them inside; one core of the 2-core dev container while other jobs ran, numba
0.68; all three counted the same 250,293 hits inside):

    barycentric  13-18 ns per test
    area         15-18 ns per test
    angle        225-233 ns per test   (6 atan2 + 6 square roots)

so ``inside_triangle`` (the default, used by the collision response) is the barycentric test. The paper
found the angle test 10 % faster than the area test; with atan2 (needed for edge points, see above)
instead of its acos the angle test is an order of magnitude slower here, and the two others, which
need no trigonometry, are close to the memory bandwidth of loading the triangle.
"""

from __future__ import annotations

import math
import time

import numpy as np
from numba import njit

# Relative tolerance: a point within EPS x (triangle size) of an edge counts as on it.
EPS = 1e-9


@njit(cache=True, nogil=True, inline="always")
def _angle(ux, uy, uz, vx, vy, vz):
    cx = uy * vz - uz * vy
    cy = uz * vx - ux * vz
    cz = ux * vy - uy * vx
    return math.atan2(math.sqrt(cx * cx + cy * cy + cz * cz), ux * vx + uy * vy + uz * vz)


@njit(cache=True, nogil=True)
def inside_angle(p, a, b, c):
    """Paper's angle test: p (3,) on the plane of triangle a, b, c (each (3,)). True on edges/vertices."""
    tol = 1e-7  # radians; atan2 keeps ~1e-16 relative accuracy, 1e-7 covers the point's own rounding
    for k in range(2):
        if k == 0:
            o, s, t = a, b, c
        else:
            o, s, t = b, c, a
        px = p[0] - o[0]
        py = p[1] - o[1]
        pz = p[2] - o[2]
        e1x = s[0] - o[0]
        e1y = s[1] - o[1]
        e1z = s[2] - o[2]
        e2x = t[0] - o[0]
        e2y = t[1] - o[1]
        e2z = t[2] - o[2]
        scale = e1x * e1x + e1y * e1y + e1z * e1z + e2x * e2x + e2y * e2y + e2z * e2z
        if px * px + py * py + pz * pz <= EPS * EPS * scale:
            return True  # p is this vertex
        total = _angle(e1x, e1y, e1z, e2x, e2y, e2z)
        a1 = _angle(px, py, pz, e1x, e1y, e1z)
        a2 = _angle(px, py, pz, e2x, e2y, e2z)
        if abs(a1 + a2 - total) > tol:
            return False
    return True


@njit(cache=True, nogil=True, inline="always")
def _area2(ax, ay, az, bx, by, bz):
    cx = ay * bz - az * by
    cy = az * bx - ax * bz
    cz = ax * by - ay * bx
    return math.sqrt(cx * cx + cy * cy + cz * cz)


@njit(cache=True, nogil=True)
def inside_area(p, a, b, c):
    """Area test: |PAB| + |PBC| + |PCA| == |ABC| within a relative tolerance. p on the plane of a, b, c."""
    pax = a[0] - p[0]
    pay = a[1] - p[1]
    paz = a[2] - p[2]
    pbx = b[0] - p[0]
    pby = b[1] - p[1]
    pbz = b[2] - p[2]
    pcx = c[0] - p[0]
    pcy = c[1] - p[1]
    pcz = c[2] - p[2]
    whole = _area2(b[0] - a[0], b[1] - a[1], b[2] - a[2], c[0] - a[0], c[1] - a[1], c[2] - a[2])
    parts = (_area2(pax, pay, paz, pbx, pby, pbz) + _area2(pbx, pby, pbz, pcx, pcy, pcz)
             + _area2(pcx, pcy, pcz, pax, pay, paz))
    return parts - whole <= 1e-7 * whole


@njit(cache=True, nogil=True)
def inside_barycentric(p, a, b, c):
    """Barycentric test (Moeller-Trumbore's u, v): u, v >= 0 and u + v <= 1 within EPS."""
    return inside_barycentric_xyz(p[0], p[1], p[2], a[0], a[1], a[2], b[0], b[1], b[2], c[0], c[1], c[2])


# The default test used by the collision response (fastest correct one, see the module docstring).
inside_triangle = inside_barycentric


@njit(cache=True, nogil=True)
def inside_barycentric_xyz(px, py, pz, ax, ay, az, bx, by, bz, cx, cy, cz):
    """The barycentric test (``inside_barycentric``) for a point and triangle given as coordinates, no
    array arguments (a call passing arrays into a function that branches and returns early pays two
    atomic reference-count updates per array; in the collision's ray casts they took a third of the
    time)."""
    e1x = bx - ax
    e1y = by - ay
    e1z = bz - az
    e2x = cx - ax
    e2y = cy - ay
    e2z = cz - az
    qx = px - ax
    qy = py - ay
    qz = pz - az
    d11 = e1x * e1x + e1y * e1y + e1z * e1z
    d12 = e1x * e2x + e1y * e2y + e1z * e2z
    d22 = e2x * e2x + e2y * e2y + e2z * e2z
    dq1 = qx * e1x + qy * e1y + qz * e1z
    dq2 = qx * e2x + qy * e2y + qz * e2z
    den = d11 * d22 - d12 * d12
    if den <= 0.0:
        return False
    u = (d22 * dq1 - d12 * dq2) / den
    v = (d11 * dq2 - d12 * dq1) / den
    return u >= -EPS and v >= -EPS and u + v <= 1.0 + EPS


# ``inside_triangle`` for a point and triangle given as coordinates (what the collision calls).
inside_triangle_xyz = inside_barycentric_xyz


@njit(cache=True, nogil=True)
def _count_angle(p, tri):
    n = 0
    for i in range(p.shape[0]):
        n += inside_angle(p[i], tri[i, 0], tri[i, 1], tri[i, 2])
    return n


@njit(cache=True, nogil=True)
def _count_area(p, tri):
    n = 0
    for i in range(p.shape[0]):
        n += inside_area(p[i], tri[i, 0], tri[i, 1], tri[i, 2])
    return n


@njit(cache=True, nogil=True)
def _count_barycentric(p, tri):
    n = 0
    for i in range(p.shape[0]):
        n += inside_barycentric(p[i], tri[i, 0], tri[i, 1], tri[i, 2])
    return n


COUNTERS = {"angle": _count_angle, "area": _count_area, "barycentric": _count_barycentric}


def random_hits(n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """``n`` random triangles (n, 3, 3) and, per triangle, the hit point (n, 3) of a random ray on its
    plane (barycentric (u, v) uniform in [-0.5, 1.5]^2, so 1/8 of them fall inside)."""
    rng = np.random.default_rng(seed)
    tri = rng.normal(size=(n, 3, 3))
    uv = rng.uniform(-0.5, 1.5, size=(n, 2))
    p = tri[:, 0] + uv[:, :1] * (tri[:, 1] - tri[:, 0]) + uv[:, 1:] * (tri[:, 2] - tri[:, 0])
    return p, tri


def benchmark(n: int = 2_000_000, seed: int = 0, repeats: int = 3) -> dict:
    """ns per test and inside count for each method on the same ``n`` random ray hits."""
    p, tri = random_hits(n, seed)
    out = {}
    for name, counter in COUNTERS.items():
        counter(p[:10], tri[:10])  # compile
        best = np.inf
        for _ in range(repeats):
            t0 = time.perf_counter()
            count = counter(p, tri)
            best = min(best, time.perf_counter() - t0)
        out[name] = {"ns_per_test": best / n * 1e9, "inside": int(count)}
    return out
