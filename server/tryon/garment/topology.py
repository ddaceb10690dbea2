"""Connectivity of a triangle mesh: which separate piece each vertex belongs to."""

from __future__ import annotations

import numpy as np
import scipy.sparse
import scipy.sparse.csgraph


def vertex_pieces(faces: np.ndarray, n_vertices: int) -> tuple[int, np.ndarray]:
    """Connected pieces over shared vertices of the triangles ``faces`` (f, 3): (count, (n_vertices,) int64
    label of each vertex). A vertex in no face is a piece of its own."""
    f = np.asarray(faces, dtype=np.int64)
    rows = np.concatenate([f[:, 0], f[:, 1]])
    cols = np.concatenate([f[:, 1], f[:, 2]])
    graph = scipy.sparse.coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(n_vertices, n_vertices))
    count, label = scipy.sparse.csgraph.connected_components(graph, directed=False)
    return int(count), label.astype(np.int64)
