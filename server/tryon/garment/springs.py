"""Structural, shear and bending springs of a triangle mesh (SPEC section 3, paper section 2.1).

``spring_model(vertices, faces) -> (springs (s, 2) int32, rest (s,) float64 m, kind (s,) int8)``.

The paper's rules for 3DMAX-style meshes (each quad split into triangles v0 v1 v2 with near right-angle
edges v0v1, v1v2 and the near hypotenuse v2v0):
1. near right-angle edges are structural springs, near hypotenuses shear springs;
2. the two vertices opposite a shared hypotenuse get another shear spring (the quad's other diagonal);
3. bending: a vertex's two "vertical" neighbours are joined, and its two "horizontal" ones. We find
   those as pairs of structural neighbours that lie on a straight line through the vertex (angle at the
   vertex >= ``STRAIGHT_DEG``), which is exactly rule 3 on a quad grid and means the same on any mesh.

For meshes not built that way (fewer than ``GRID_FACE_FRACTION`` of the faces are halves of a split
quad: two near-right triangles sharing their near hypotenuse), the fallback: every edge structural; the
two vertices opposite each interior edge a shear spring (the other diagonal of the two triangles, as rule
2 does for quads); bending as in rule 3 over all edges. In a 3DMAX-style mesh, the few faces that are
not halves of quads get the fallback's shear springs across their shared edges.
"""

from __future__ import annotations

import numpy as np
from numba import njit

# Spring kinds, as stored in a model's ``kind`` (s,) int8, and their names in reports.
STRUCTURAL, SHEAR, BENDING = 0, 1, 2
SPRING_KINDS = ("structural", "shear", "bending")

# An angle within 90 +- 15 degrees is "near right" (3DMAX quads are rectangles up to mesh distortion).
RIGHT_ANGLE_TOLERANCE_DEG = 15.0
# At least this fraction of the faces being halves of split quads makes a mesh "3DMAX-style".
GRID_FACE_FRACTION = 0.8
# Two neighbours of a vertex are "opposite" (same grid line) when the angle between them at the vertex
# is at least this: 150 degrees allows the curvature of a 2 cm grid on a 10 cm-radius sleeve and more.
STRAIGHT_DEG = 150.0


def edge_keys(a: np.ndarray, b: np.ndarray, n: int) -> np.ndarray:
    """int64 key of the undirected edge (a, b) for n vertices."""
    lo, hi = np.minimum(a, b).astype(np.int64), np.maximum(a, b).astype(np.int64)
    return lo * n + hi


def face_angles(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(f, 3) interior angles in degrees; column c is the angle at ``faces[:, c]``."""
    tri = vertices[faces]
    angles = np.empty((len(faces), 3))
    for c in range(3):  # three corners, vectorised over faces
        u = tri[:, (c + 1) % 3] - tri[:, c]
        w = tri[:, (c + 2) % 3] - tri[:, c]
        cos = np.einsum("ij,ij->i", u, w) / np.maximum(np.linalg.norm(u, axis=1) * np.linalg.norm(w, axis=1), 1e-300)
        angles[:, c] = np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))
    return angles


def spring_model(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Springs of the mesh: (s, 2) int32 vertex pairs (i < j, unique), rest lengths (s,) m, kind (s,) int8."""
    vertices = np.asarray(vertices, dtype=np.float64)
    faces = np.asarray(faces, dtype=np.int64)
    n, f = len(vertices), len(faces)
    # Half-edges: corner c of face t owns the edge opposite it, (faces[t, c+1], faces[t, c+2]).
    opp = faces.reshape(-1)  # (3f,) the vertex opposite each half-edge
    ea = faces[:, [1, 2, 0]].reshape(-1)
    eb = faces[:, [2, 0, 1]].reshape(-1)
    keys = edge_keys(ea, eb, n)
    uniq, edge_of = np.unique(keys, return_inverse=True)  # edge id per half-edge
    n_edges = len(uniq)
    faces_per_edge = np.bincount(edge_of, minlength=n_edges)

    angles = face_angles(vertices, faces)
    off = np.abs(angles - 90.0)
    best = np.argmin(off, axis=1)
    has_right = off[np.arange(f), best] <= RIGHT_ANGLE_TOLERANCE_DEG
    hyp_half = np.zeros((f, 3), dtype=bool)
    hyp_half[np.arange(f)[has_right], best[has_right]] = True
    hyp_half = hyp_half.reshape(-1)
    # An edge is a near hypotenuse when it is one in every face that has it; a face is half of a split
    # quad ("paired") when its hypotenuse is shared, as one, with the face across it.
    is_hyp = np.bincount(edge_of, weights=hyp_half, minlength=n_edges) == faces_per_edge
    quad_diagonal = is_hyp & (faces_per_edge == 2)
    face_of_half = np.arange(3 * f) // 3
    face_paired = np.zeros(f, dtype=bool)
    face_paired[face_of_half[hyp_half & quad_diagonal[edge_of]]] = True
    grid_like = f > 0 and face_paired.mean() >= GRID_FACE_FRACTION
    if not grid_like:  # the fallback: no near hypotenuses at all
        is_hyp[:] = False
        face_paired[:] = False

    lo, hi = uniq // n, uniq % n
    edge_kind = np.where(is_hyp, SHEAR, STRUCTURAL)

    # Opposite-vertex pairs across edges with two faces: across each quad diagonal (rule 2), and across
    # every edge between faces that are not halves of quads (the fallback, there or everywhere).
    order = np.argsort(edge_of, kind="stable")
    starts = np.concatenate([[0], np.cumsum(faces_per_edge)])[:-1]
    e2 = np.flatnonzero(faces_per_edge == 2)
    h1, h2 = order[starts[e2]], order[starts[e2] + 1]
    loose = ~face_paired[face_of_half[h1]] & ~face_paired[face_of_half[h2]]
    pick = is_hyp[e2] | loose
    across = np.column_stack([opp[h1[pick]], opp[h2[pick]]])

    # Bending (rule 3): straight-through pairs of structural neighbours.
    bend_mask = edge_kind == STRUCTURAL
    bend = _straight_pairs(vertices, lo[bend_mask], hi[bend_mask], n, np.cos(np.radians(STRAIGHT_DEG)))

    pairs = np.concatenate([np.column_stack([lo, hi]), across, bend]).astype(np.int64)
    kinds = np.concatenate([edge_kind, np.full(len(across), SHEAR), np.full(len(bend), BENDING)]).astype(np.int8)
    return _unique_springs(vertices, pairs, kinds, n)


def _unique_springs(vertices, pairs, kinds, n):
    """Drop self-springs and repeats (a pair keeps its lowest kind: structural < shear < bending)."""
    pairs = np.sort(pairs, axis=1)
    ok = pairs[:, 0] != pairs[:, 1]
    pairs, kinds = pairs[ok], kinds[ok]
    key = pairs[:, 0] * n + pairs[:, 1]
    order = np.lexsort((kinds, key))
    key, pairs, kinds = key[order], pairs[order], kinds[order]
    first = np.ones(len(key), dtype=bool)
    first[1:] = key[1:] != key[:-1]
    pairs, kinds = pairs[first], kinds[first]
    rest = np.linalg.norm(vertices[pairs[:, 0]] - vertices[pairs[:, 1]], axis=1)
    return pairs.astype(np.int32), rest, kinds.astype(np.int8)


def _straight_pairs(vertices, lo, hi, n, cos_limit):
    """(m, 2) pairs (a, b) of neighbours of some vertex v (over the given edges) with angle a-v-b
    beyond ``STRAIGHT_DEG``, each a's most opposite partner (so a grid gives one pair per line)."""
    a = np.concatenate([lo, hi])
    b = np.concatenate([hi, lo])
    order = np.argsort(a, kind="stable")
    nbr = b[order].astype(np.int64)
    start = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(np.bincount(a, minlength=n), out=start[1:])
    return _straight_pairs_kernel(vertices, start, nbr, cos_limit)


@njit(cache=True, nogil=True)  # nogil: an upload prepared in a worker thread does not stall the server
def _straight_pairs_kernel(vertices, start, nbr, cos_limit):
    """For each vertex v and neighbour a: the neighbour b minimising cos(a-v-b), kept if below
    ``cos_limit``. Sequential (one output list); cost sum of degree^2."""
    n = len(start) - 1
    out = np.empty((len(nbr), 2), dtype=np.int64)
    m = 0
    for v in range(n):
        s, e = start[v], start[v + 1]
        for i in range(s, e):
            a = nbr[i]
            ax = vertices[a, 0] - vertices[v, 0]
            ay = vertices[a, 1] - vertices[v, 1]
            az = vertices[a, 2] - vertices[v, 2]
            la = np.sqrt(ax * ax + ay * ay + az * az)
            best_cos = cos_limit
            best = -1
            for j in range(s, e):
                b = nbr[j]
                if b == a:
                    continue
                bx = vertices[b, 0] - vertices[v, 0]
                by = vertices[b, 1] - vertices[v, 1]
                bz = vertices[b, 2] - vertices[v, 2]
                lb = np.sqrt(bx * bx + by * by + bz * bz)
                if la == 0.0 or lb == 0.0:
                    continue
                c = (ax * bx + ay * by + az * bz) / (la * lb)
                if c < best_cos:
                    best_cos = c
                    best = b
            if best >= 0:
                out[m, 0] = a
                out[m, 1] = best
                m += 1
    return out[:m]
