"""Geometry that the body, the garment and the simulation share: normals, the closest point of a triangle,
rotations. Metres and radians; arrays float64 unless said otherwise."""

from __future__ import annotations

import math

import numpy as np
from numba import njit





@njit(cache=True, nogil=True)
def triangle_normal(p, a, b, c):
    """(nx, ny, nz): the cross product (p[b] - p[a]) x (p[c] - p[a]) of the triangle of rows a, b, c of ``p``
    (n, 3) m: its normal, twice its area long."""
    ux = p[b, 0] - p[a, 0]
    uy = p[b, 1] - p[a, 1]
    uz = p[b, 2] - p[a, 2]
    wx = p[c, 0] - p[a, 0]
    wy = p[c, 1] - p[a, 1]
    wz = p[c, 2] - p[a, 2]
    return uy * wz - uz * wy, uz * wx - ux * wz, ux * wy - uy * wx


@njit(cache=True, nogil=True, inline="always")
def distance(p, i, j):
    """m: the distance between rows i and j of ``p`` (n, 3) m."""
    return math.sqrt((p[i, 0] - p[j, 0]) ** 2 + (p[i, 1] - p[j, 1]) ** 2 + (p[i, 2] - p[j, 2]) ** 2)


@njit(cache=True)
def face_vertex_normals(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit face normals (f, 3) and area-weighted unit vertex normals (n, 3) of a triangle mesh
    (vertices (n, 3) float64, faces (f, 3) int32, counter-clockwise from outside). Serial scatter."""
    n = vertices.shape[0]
    f = faces.shape[0]
    fn = np.empty((f, 3))
    vn = np.zeros((n, 3))
    for k in range(f):
        a, b, c = faces[k, 0], faces[k, 1], faces[k, 2]
        nx, ny, nz = triangle_normal(vertices, a, b, c)
        for v in (a, b, c):
            vn[v, 0] += nx
            vn[v, 1] += ny
            vn[v, 2] += nz
        length = np.sqrt(nx * nx + ny * ny + nz * nz)
        if length > 0.0:
            nx /= length
            ny /= length
            nz /= length
        fn[k, 0] = nx
        fn[k, 1] = ny
        fn[k, 2] = nz
    for v in range(n):
        length = np.sqrt(vn[v, 0] ** 2 + vn[v, 1] ** 2 + vn[v, 2] ** 2)
        if length > 0.0:
            vn[v, 0] /= length
            vn[v, 1] /= length
            vn[v, 2] /= length
    return fn, vn


def vertex_normals(pos: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(n, 3) area-weighted unit vertex normals of the mesh ``pos`` (n, 3), ``faces`` (f, 3) (zero where
    undefined)."""
    tri = pos[faces]
    fn = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])  # length = 2 area: area weighting
    vn = np.zeros_like(pos)
    for c in range(3):
        np.add.at(vn, faces[:, c], fn)
    length = np.linalg.norm(vn, axis=1, keepdims=True)
    return np.ascontiguousarray(vn / np.where(length > 0, length, 1.0))


@njit(cache=True, nogil=True)
def face_normals(vertices, faces, out):
    """Unit face normals (f, 3) of a triangle mesh into ``out``."""
    for f in range(faces.shape[0]):
        nx, ny, nz = triangle_normal(vertices, faces[f, 0], faces[f, 1], faces[f, 2])
        ln = math.sqrt(nx * nx + ny * ny + nz * nz)
        if ln > 0.0:
            ln = 1.0 / ln
        out[f, 0] = nx * ln
        out[f, 1] = ny * ln
        out[f, 2] = nz * ln


@njit(cache=True, nogil=True)
def closest_uv_on_triangle(px, py, pz, ax, ay, az, bx, by, bz, cx, cy, cz):
    """Where on triangle a, b, c the point closest to p lies (Ericson, Real-Time Collision Detection 5.1.5):
    (u, v) with closest = a + u (b - a) + v (c - a), u, v >= 0, u + v <= 1. Coordinates, not arrays: passing
    arrays into a function that branches and returns early pays two atomic reference-count updates per
    array, and this runs for every face of up to 9 cells."""
    abx = bx - ax
    aby = by - ay
    abz = bz - az
    acx = cx - ax
    acy = cy - ay
    acz = cz - az
    apx = px - ax
    apy = py - ay
    apz = pz - az
    d1 = abx * apx + aby * apy + abz * apz
    d2 = acx * apx + acy * apy + acz * apz
    u = 0.0
    v = 0.0
    if d1 <= 0.0 and d2 <= 0.0:
        u = 0.0
        v = 0.0
    else:
        bpx = px - bx
        bpy = py - by
        bpz = pz - bz
        d3 = abx * bpx + aby * bpy + abz * bpz
        d4 = acx * bpx + acy * bpy + acz * bpz
        cpx = px - cx
        cpy = py - cy
        cpz = pz - cz
        d5 = abx * cpx + aby * cpy + abz * cpz
        d6 = acx * cpx + acy * cpy + acz * cpz
        vc = d1 * d4 - d3 * d2
        vb = d5 * d2 - d1 * d6
        va = d3 * d6 - d5 * d4
        if d3 >= 0.0 and d4 <= d3:
            u = 1.0
            v = 0.0
        elif d6 >= 0.0 and d5 <= d6:
            u = 0.0
            v = 1.0
        elif vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
            u = d1 / (d1 - d3)
            v = 0.0
        elif vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
            u = 0.0
            v = d2 / (d2 - d6)
        elif va <= 0.0 and (d4 - d3) >= 0.0 and (d5 - d6) >= 0.0:
            w = (d4 - d3) / ((d4 - d3) + (d5 - d6))
            u = 1.0 - w
            v = w
        else:
            den = 1.0 / (va + vb + vc)
            u = vb * den
            v = vc * den
    return u, v


@njit(cache=True, nogil=True)
def closest_on_triangle(px, py, pz, ax, ay, az, bx, by, bz, cx, cy, cz):
    """Closest point of triangle a, b, c to p (``closest_uv_on_triangle``): (squared distance, x, y, z)."""
    u, v = closest_uv_on_triangle(px, py, pz, ax, ay, az, bx, by, bz, cx, cy, cz)
    qx = ax + u * (bx - ax) + v * (cx - ax)
    qy = ay + u * (by - ay) + v * (cy - ay)
    qz = az + u * (bz - az) + v * (cz - az)
    dd = 0.0
    dd += (px - qx) ** 2
    dd += (py - qy) ** 2
    dd += (pz - qz) ** 2
    return dd, qx, qy, qz


def rotation(axis: np.ndarray, angle: float) -> np.ndarray:
    """3x3 rotation matrix about unit ``axis`` by ``angle`` radians (Rodrigues)."""
    axis = axis / np.linalg.norm(axis)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * (k @ k)


def stack_meshes(meshes: list[tuple[np.ndarray, np.ndarray]]) -> tuple[np.ndarray, np.ndarray]:
    """Several meshes ``(vertices (n_i, 3), faces (f_i, 3))`` as one: the vertices one after the other and the
    faces (int64) offset to index them."""
    starts = np.cumsum([0] + [len(v) for v, _ in meshes[:-1]])
    return (np.concatenate([np.asarray(v) for v, _ in meshes]),
            np.concatenate([np.asarray(f, dtype=np.int64) + s for (_, f), s in zip(meshes, starts)]))
