"""Small numba kernels of the body stage (serial: each is a single O(n) pass of a few microseconds)."""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def convex_hull_2d(points: np.ndarray) -> np.ndarray:
    """(m, 2) corners of the convex hull of (k, 2) points, counter-clockwise (Andrew's monotone chain);
    empty for fewer than 3 points."""
    k = points.shape[0]
    if k < 3:
        return np.empty((0, 2))
    by_y = np.argsort(points[:, 1], kind="mergesort")
    order = by_y[np.argsort(points[by_y, 0], kind="mergesort")]  # lexicographic (x, y)
    p = points[order]
    hull = np.empty((2 * k, 2))
    m = 0
    for i in range(k):  # lower chain
        while m >= 2 and ((hull[m - 1, 0] - hull[m - 2, 0]) * (p[i, 1] - hull[m - 2, 1])
                          - (hull[m - 1, 1] - hull[m - 2, 1]) * (p[i, 0] - hull[m - 2, 0])) <= 0.0:
            m -= 1
        hull[m] = p[i]
        m += 1
    lower = m + 1
    for i in range(k - 2, -1, -1):  # upper chain
        while m >= lower and ((hull[m - 1, 0] - hull[m - 2, 0]) * (p[i, 1] - hull[m - 2, 1])
                              - (hull[m - 1, 1] - hull[m - 2, 1]) * (p[i, 0] - hull[m - 2, 0])) <= 0.0:
            m -= 1
        hull[m] = p[i]
        m += 1
    return hull[:m - 1].copy()  # the chain ends where it began


@njit(cache=True)
def hull_perimeter_2d(points: np.ndarray) -> float:
    """Perimeter of the convex hull of (k, 2) points; 0 for fewer than 3."""
    hull = convex_hull_2d(points)
    m = hull.shape[0]
    total = 0.0
    for i in range(m):
        j = (i + 1) % m
        total += np.sqrt((hull[j, 0] - hull[i, 0]) ** 2 + (hull[j, 1] - hull[i, 1]) ** 2)
    return total


@njit(cache=True)
def section_points_2d(vertices: np.ndarray, edges: np.ndarray, point: np.ndarray, normal: np.ndarray,
                      basis: np.ndarray, eps: float) -> np.ndarray:
    """(k, 2) in-plane coordinates (along ``basis`` rows (2, 3)) of the points where the plane through
    ``point`` with unit ``normal`` cuts the mesh edges (e, 2): edge crossings, and edge ends within ``eps``
    of the plane. Points may repeat (harmless for a hull)."""
    n_e = edges.shape[0]
    out = np.empty((2 * n_e, 2))
    k = 0
    for e in range(n_e):
        i, j = edges[e, 0], edges[e, 1]
        di = 0.0
        dj = 0.0
        for c in range(3):
            di += (vertices[i, c] - point[c]) * normal[c]
            dj += (vertices[j, c] - point[c]) * normal[c]
        on_i = abs(di) <= eps
        on_j = abs(dj) <= eps
        if on_i or on_j:
            for v, on in ((i, on_i), (j, on_j)):
                if on:
                    for r in range(2):
                        s = 0.0
                        for c in range(3):
                            s += (vertices[v, c] - point[c]) * basis[r, c]
                        out[k, r] = s
                    k += 1
        elif di * dj < 0.0:
            t = di / (di - dj)
            for r in range(2):
                s = 0.0
                for c in range(3):
                    p = vertices[i, c] + t * (vertices[j, c] - vertices[i, c])
                    s += (p - point[c]) * basis[r, c]
                out[k, r] = s
            k += 1
    return out[:k]
