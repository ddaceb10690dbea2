"""Connectivity of a triangle mesh: which separate piece each vertex belongs to, its openings, and
distances over its edges."""

from __future__ import annotations

import numpy as np
import scipy.sparse
import scipy.sparse.csgraph

from tryon.body.measure import mesh_edges


def vertex_pieces(faces: np.ndarray, n_vertices: int) -> tuple[int, np.ndarray]:
    """Connected pieces over shared vertices of the triangles ``faces`` (f, 3): (count, (n_vertices,) int64
    label of each vertex). A vertex in no face is a piece of its own."""
    f = np.asarray(faces, dtype=np.int64)
    rows = np.concatenate([f[:, 0], f[:, 1]])
    cols = np.concatenate([f[:, 1], f[:, 2]])
    graph = scipy.sparse.coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(n_vertices, n_vertices))
    count, label = scipy.sparse.csgraph.connected_components(graph, directed=False)
    return int(count), label.astype(np.int64)


def boundary_loops(faces: np.ndarray, n_vertices: int) -> list[np.ndarray]:
    """The openings of the mesh ``faces`` (f, 3): one int64 array of vertex ids per boundary loop."""
    f = np.asarray(faces, dtype=np.int64)
    edges = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
    key, count = np.unique(edges[:, 0] * n_vertices + edges[:, 1], return_counts=True)
    b = key[count == 1]
    if len(b) == 0:
        return []
    a, c = b // n_vertices, b % n_vertices
    graph = scipy.sparse.coo_matrix((np.ones(len(b)), (a, c)), shape=(n_vertices, n_vertices))
    label = scipy.sparse.csgraph.connected_components(graph, directed=False)[1]
    on = np.unique(np.concatenate([a, c]))
    return [on[label[on] == k] for k in np.unique(label[on])]


def cloth_distance(x: np.ndarray, faces: np.ndarray, sources: np.ndarray) -> np.ndarray:
    """(k,) m: the shortest path over the mesh's edges (points x (k, 3), faces (f, 3)) from the nearest of
    the points ``sources`` (q,) int; inf for points of other pieces."""
    f = np.asarray(faces, dtype=np.int64)
    # each edge once: coo_matrix sums repeated entries (an edge listed the same way round by two faces of a
    # mesh whose faces are not consistently oriented)
    e = mesh_edges(f)
    w = np.linalg.norm(x[e[:, 0]] - x[e[:, 1]], axis=1)
    graph = scipy.sparse.coo_matrix((w, (e[:, 0], e[:, 1])), shape=(len(x), len(x))).tocsr()
    return scipy.sparse.csgraph.dijkstra(graph, directed=False, indices=np.asarray(sources), min_only=True)


def face_edge_ids(faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(edges (e, 2) int64, ids (f, 3) int64): the unique undirected edges of the triangles ``faces``
    (f, 3), and which one each face's edge from corner c to corner c + 1 is."""
    ends = np.sort(np.stack([faces, np.roll(faces, -1, axis=1)], axis=2).reshape(-1, 2), axis=1)
    edges, ids = np.unique(ends.astype(np.int64), axis=0, return_inverse=True)
    return edges, ids.reshape(-1, 3)


def edge_faces(faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(edges (e, 2) int64, adjacent (e, 2) int64): the unique undirected edges of the triangles ``faces``
    (f, 3) and the (at most two) triangles on each, -1 where an edge has one (an opening's rim); where three
    triangles meet on an edge (a seam), the first two."""
    edges, ids = face_edge_ids(np.asarray(faces, dtype=np.int64))
    return edges, faces_on_edges(ids, len(edges))


def faces_on_edges(ids: np.ndarray, n_edges: int) -> np.ndarray:
    """(e, 2) int64: the (at most two) triangles on each of ``n_edges`` edges, from each face's edge ids (f, 3)
    (``face_edge_ids``), -1 where an edge has fewer (``edge_faces``)."""
    adjacent = np.full((n_edges, 2), -1, dtype=np.int64)
    flat = ids.ravel()
    owner = np.repeat(np.arange(len(ids)), 3)
    order = np.argsort(flat, kind="stable")
    flat, owner = flat[order], owner[order]
    first = np.r_[True, flat[1:] != flat[:-1]]
    adjacent[flat[first], 0] = owner[first]
    second = np.r_[False, (flat[1:] == flat[:-1]) & first[:-1]]
    adjacent[flat[second], 1] = owner[second]
    return adjacent
