"""Tape-measure girths of a mesh: perimeter of the convex hull of a plane section (SPEC section 2)."""

from __future__ import annotations

import numpy as np

from tryon.body.kernels import hull_perimeter_2d, section_points_2d


def mesh_edges(faces: np.ndarray) -> np.ndarray:
    """(e, 2) int unique undirected edges of the triangles ``faces`` (f, 3)."""
    e = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    return np.unique(np.sort(e, axis=1), axis=0)


def plane_basis(normal: np.ndarray) -> np.ndarray:
    """(2, 3) orthonormal in-plane axes of the plane with unit ``normal``; the first is world x made
    perpendicular to the normal (exactly x for a horizontal plane)."""
    helper = np.array([1.0, 0.0, 0.0]) if abs(normal[0]) < 0.9 else np.array([0.0, 0.0, 1.0])
    e1 = helper - (helper @ normal) * normal
    e1 /= np.linalg.norm(e1)
    e2 = np.array([normal[1] * e1[2] - normal[2] * e1[1], normal[2] * e1[0] - normal[0] * e1[2],
                   normal[0] * e1[1] - normal[1] * e1[0]])
    return np.stack([e1, e2])


def hull_perimeter(points_2d: np.ndarray) -> float:
    """Perimeter (same unit as the points) of the convex hull of (k, 2) points; 0 if fewer than 3."""
    return float(hull_perimeter_2d(np.ascontiguousarray(points_2d, dtype=np.float64)))


SECTION_EPS = 1e-10  # m: a vertex this close to the cutting plane counts as on it


def section_2d(vertices: np.ndarray, edges: np.ndarray, point: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """(k, 2) plane-section points of the mesh ``edges`` (e, 2) in the plane's ``plane_basis`` coordinates."""
    return section_points_2d(vertices, np.ascontiguousarray(edges), np.asarray(point, float),
                             np.asarray(normal, float), plane_basis(normal), SECTION_EPS)


def section_girth(vertices: np.ndarray, edges: np.ndarray, point: np.ndarray, normal: np.ndarray) -> float:
    """Tape-measure girth (metres) of the mesh with ``edges`` (e, 2) (``mesh_edges``) at the plane
    (point, unit normal): the perimeter of the convex hull of the section."""
    return hull_perimeter(section_2d(vertices, edges, point, normal))


def horizontal_girth(vertices: np.ndarray, edges: np.ndarray, y: float) -> float:
    """Girth (metres) of the horizontal section of the mesh ``edges`` at height ``y`` (metres)."""
    return section_girth(vertices, edges, np.array([0.0, y, 0.0]), np.array([0.0, 1.0, 0.0]))


def horizontal_breadth(vertices: np.ndarray, edges: np.ndarray, y: float) -> float:
    """Extent in x (metres) of the horizontal section of the mesh ``edges`` at height ``y``."""
    pts = section_2d(vertices, edges, np.array([0.0, y, 0.0]), np.array([0.0, 1.0, 0.0]))
    return float(pts[:, 0].max() - pts[:, 0].min()) if len(pts) else 0.0
