"""Tape-measure girths of a mesh: perimeter of the convex hull of a plane section (SPEC section 2)."""

from __future__ import annotations

import numpy as np

from tryon.body.kernels import hull_perimeter_2d


def mesh_edges(faces: np.ndarray) -> np.ndarray:
    """(e, 2) int unique undirected edges of the triangles ``faces`` (f, 3)."""
    e = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    return np.unique(np.sort(e, axis=1), axis=0)


def plane_section_points(vertices: np.ndarray, edges: np.ndarray, point: np.ndarray,
                         normal: np.ndarray, eps: float = 1e-10) -> np.ndarray:
    """(k, 3) points where the plane through ``point`` (3,) with unit ``normal`` (3,) cuts the mesh edges
    ``edges`` (e, 2) of ``vertices`` (n, 3): the crossings of the edges, plus the edge ends lying on the
    plane (within ``eps`` metres). Points may repeat; that does not matter for a hull."""
    d = (vertices - point) @ normal
    di, dj = d[edges[:, 0]], d[edges[:, 1]]
    on_i = np.abs(di) <= eps
    on_j = np.abs(dj) <= eps
    cross = (di * dj < 0.0) & ~on_i & ~on_j
    i, j, di, dj = edges[cross, 0], edges[cross, 1], di[cross], dj[cross]
    t = (di / (di - dj))[:, None]
    hits = vertices[i] + t * (vertices[j] - vertices[i])
    return np.concatenate([vertices[edges[on_i, 0]], vertices[edges[on_j, 1]], hits])


def plane_basis(normal: np.ndarray) -> np.ndarray:
    """(2, 3) orthonormal in-plane axes of the plane with unit ``normal``."""
    helper = np.array([1.0, 0.0, 0.0]) if abs(normal[0]) < 0.9 else np.array([0.0, 0.0, 1.0])
    e1 = helper - (helper @ normal) * normal
    e1 /= np.linalg.norm(e1)
    return np.stack([e1, np.cross(normal, e1)])


def hull_perimeter(points_2d: np.ndarray) -> float:
    """Perimeter (same unit as the points) of the convex hull of (k, 2) points; 0 if fewer than 3."""
    return float(hull_perimeter_2d(np.ascontiguousarray(points_2d, dtype=np.float64)))


def section_girth(vertices: np.ndarray, edges: np.ndarray, point: np.ndarray, normal: np.ndarray) -> float:
    """Tape-measure girth (metres) of the mesh with ``edges`` (e, 2) (``mesh_edges``) at the plane
    (point, unit normal): the perimeter of the convex hull of the section."""
    pts = plane_section_points(vertices, edges, point, normal)
    return hull_perimeter((pts - point) @ plane_basis(normal).T)


def horizontal_girth(vertices: np.ndarray, edges: np.ndarray, y: float) -> float:
    """Girth (metres) of the horizontal section of the mesh ``edges`` at height ``y`` (metres)."""
    return section_girth(vertices, edges, np.array([0.0, y, 0.0]), np.array([0.0, 1.0, 0.0]))


def horizontal_breadth(vertices: np.ndarray, edges: np.ndarray, y: float) -> float:
    """Extent in x (metres) of the horizontal section of the mesh ``edges`` at height ``y``."""
    pts = plane_section_points(vertices, edges, np.array([0.0, y, 0.0]), np.array([0.0, 1.0, 0.0]))
    return float(pts[:, 0].max() - pts[:, 0].min()) if len(pts) else 0.0
