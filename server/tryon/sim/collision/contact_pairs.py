"""The pairs of a mesh near enough to touch itself within a step (issue 53 item 1's broad phase): ``SelfContact``
lists the (point, triangle) and (edge, edge) pairs whose paths come within a reach of each other, between the
patches of the mesh that are not flat together (``patches.listed_pairs``), and keeps them while no point has moved
far enough to bring a pair not on the list within a thickness.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from tryon.garment.topology import faces_on_edges
from tryon.sim.collision.ccd import far_from_edge, far_from_triangle, paths_apart
from tryon.sim.collision.crossings import crosses
from tryon.sim.collision.patches import boxes_apart, kept_flat, listed_pairs, make_patches, path_boxes


@njit(cache=True, nogil=True)
def _append(rows, count, a, b):
    """(count + 1, rows): (a, b) written to row ``count`` of ``rows`` (r, 2) int64, grown twice as long if full."""
    if count == rows.shape[0]:
        grown = np.empty((2 * count, 2), dtype=np.int64)
        grown[:count] = rows
        rows = grown
    rows[count, 0] = a
    rows[count, 1] = b
    return count + 1, rows


@njit(cache=True, nogil=True)
def _add_point_pair(x, x0, faces, reach, i, f, points, count):
    """(count, points): (i, f) appended to the first ``count`` rows of ``points`` (``_append``) if point i is no
    corner of triangle f and their paths come within ``reach`` m of each other (``far_from_triangle``)."""
    if i == faces[f, 0] or i == faces[f, 1] or i == faces[f, 2] or far_from_triangle(i, f, x, x0, faces, reach):
        return count, points
    return _append(points, count, i, f)


@njit(cache=True, nogil=True)
def _pairs_of_moved(x, x0, faces, edges, moved, reach):
    """(points (p, 2), edge pairs (q, 2)) int64: every (point, triangle) and (edge, edge) pair with a point of
    ``moved`` (n,) bool, whose paths from x0 to x come within ``reach`` m of each other (``_point_pairs``,
    ``_edge_pairs``), each pair of edges once as (lower, higher). Every point and edge is tested against the moved
    ones (no grid): for the few points a list kept at rest needs again (a hem still swinging), that is cheaper
    than the grid of every triangle."""
    n_f, n_e = faces.shape[0], edges.shape[0]
    point_box = path_boxes(x, x0, np.arange(x.shape[0]).reshape(-1, 1))
    tri_box = path_boxes(x, x0, faces)
    edge_box = path_boxes(x, x0, edges)
    tri_moved = np.zeros(n_f, dtype=np.bool_)
    for f in range(n_f):
        tri_moved[f] = moved[faces[f, 0]] or moved[faces[f, 1]] or moved[faces[f, 2]]
    points = np.empty((64, 2), dtype=np.int64)
    count = 0
    for i in np.flatnonzero(moved):  # a moved point against every triangle
        for f in range(n_f):
            if not boxes_apart(point_box, i, tri_box, f, reach):
                count, points = _add_point_pair(x, x0, faces, reach, i, f, points, count)
    for f in np.flatnonzero(tri_moved):  # a triangle with a moved corner against every point that did not move
        for i in range(x.shape[0]):
            if not moved[i] and not boxes_apart(point_box, i, tri_box, f, reach):
                count, points = _add_point_pair(x, x0, faces, reach, i, f, points, count)
    edge_moved = np.zeros(n_e, dtype=np.bool_)
    for e in range(n_e):
        edge_moved[e] = moved[edges[e, 0]] or moved[edges[e, 1]]
    pairs = np.empty((64, 2), dtype=np.int64)
    n_pairs = 0
    for e in range(n_e):
        if not edge_moved[e]:
            continue
        p1, p2 = edges[e, 0], edges[e, 1]
        for k in range(n_e):
            if k == e or (edge_moved[k] and k < e):
                continue  # two moved edges once, from the lower
            q1, q2 = edges[k, 0], edges[k, 1]
            if q1 == p1 or q1 == p2 or q2 == p1 or q2 == p2 or boxes_apart(edge_box, e, edge_box, k, reach) or \
                    far_from_edge(p1, p2, q1, q2, x, x0, reach):
                continue
            n_pairs, pairs = _append(pairs, n_pairs, min(e, k), max(e, k))
    return points[:count], pairs[:n_pairs]


@njit(cache=True, nogil=True)
def _crossed_in_pairs(x, edges, faces, edge_pairs, edge_tris, tangled):
    """Mark in ``tangled`` (n,) bool the ends of every edge of an edge pair (``edge_pairs`` (q, 2) int64) that
    crosses a triangle on the other edge (``edge_tris`` (e, 2) int64, -1 for none) at x (n, 3) m, sharing no corner
    with it (``crossings.crosses``), and that triangle's corners; returns how many crossings it met (one may be
    met more than once)."""
    count = 0
    for k in range(edge_pairs.shape[0]):
        for side in range(2):
            i, j = edges[edge_pairs[k, side], 0], edges[edge_pairs[k, side], 1]
            for s in range(2):
                f = edge_tris[edge_pairs[k, 1 - side], s]
                if f < 0:
                    continue
                a, b, c = faces[f, 0], faces[f, 1], faces[f, 2]
                if i == a or i == b or i == c or j == a or j == b or j == c:
                    continue
                if crosses((x[i, 0], x[i, 1], x[i, 2], x[j, 0], x[j, 1], x[j, 2], x[a, 0], x[a, 1], x[a, 2],
                            x[b, 0], x[b, 1], x[b, 2], x[c, 0], x[c, 1], x[c, 2])):
                    tangled[i] = tangled[j] = tangled[a] = tangled[b] = tangled[c] = True
                    count += 1
    return count


# Share of a mesh's points past their allowance up to which only their pairs are listed again (``_pairs_of_moved``,
# every element against them); past it the whole list is made again by patches. A re-list of 1-4 points (a T-shirt
# M's swinging hem at rest) costs ~0.1 ms this way, a whole list 1-2 ms.
PARTIAL_SHARE = 0.02


class SelfContact:
    """The pairs of a garment's simulated mesh near enough to touch within a step: every (point, triangle) and
    (edge, edge) pair whose paths came within ``margin`` m of each other as listed (``update``; ``positions``: where
    each point was when its pairs were listed), but those within a piece of the mesh flat when listed
    (``patches``: a flat piece cannot fold onto itself; the list is kept only while those pieces are still flat,
    ``flats``). A pair not on it was at least ``margin`` apart, so its points may move up to allow = (margin -
    thickness) / 2 from there, in the passes' pushes and the steps after, before their pairs must be listed again.
    While the whole list was made at once, that is counted once the mesh's mean move is taken away (a pair's
    distance does not change as the cloth moves as a whole); when a few points have strayed, only their pairs are
    listed again, within margin + allow (a point not listed again may stray 2 allow from where it is then: margin
    + allow - 3 allow = thickness), and from then on each point's own move counts.

    faces (f, 3) int64, edges (e, 2) int64 and face_edges (f, 3) int64 (``topology.face_edge_ids``): the mesh,
    kept with the drape; thickness, margin m."""

    def __init__(self, faces: np.ndarray, edges: np.ndarray, face_edges: np.ndarray, thickness: float,
                 margin: float):
        self.faces, self.edges, self.face_edges = faces, edges, face_edges
        self.thickness, self.margin = float(thickness), float(margin)
        self.allow = 0.5 * (self.margin - self.thickness)
        self.positions = None
        self.whole = False  # the list was made at once, every point's position taken together
        self.tangled = np.zeros(0, dtype=np.bool_)
        self.edge_tris = faces_on_edges(face_edges, len(edges))  # the (at most two) triangles on each edge, -1: none
        self.patches = make_patches(faces, int(faces.max()) + 1, self.edge_tris, face_edges)
        self.points = np.zeros((0, 2), dtype=np.int64)
        self.edge_pairs = np.zeros((0, 2), dtype=np.int64)
        self.flats = np.zeros((0, 2), dtype=np.int64)  # the pairs of patches the list left out as flat together

    def update(self, x: np.ndarray, x0: np.ndarray, from_start: bool = True) -> bool:
        """Keep the list right for the paths x0 -> x (n, 3) m (the straight path of a point stays within the larger
        of its two ends' distances from where it was listed; ``from_start`` False: x0 was checked already, only x
        has moved since): nothing if no point strayed, the strayed points' pairs (and those of the points crossed
        through the mesh) if few did, else the whole list. Returns whether the list changed."""
        if self.positions is None:
            self.build(x, x0)
            return True
        if not kept_flat(x, x0, self.faces, self.patches, self.flats):
            self.build(x, x0)  # a piece of cloth left out as flat has bent: its pairs are needed
            return True
        if self.whole:
            far = _largest_spread(x, self.positions)
            if from_start:
                far = max(far, _largest_spread(x0, self.positions))
            if far <= self.allow:
                return False
        moved = self.tangled.copy()
        _strayed(x, self.positions, self.allow, moved)
        if from_start:
            _strayed(x0, self.positions, self.allow, moved)
        if not moved.any():
            return False
        if moved.mean() > PARTIAL_SHARE:
            self.build(x, x0)
            return True
        kept_points, kept_edges = self._without(self.points, self.edge_pairs, moved)
        points, edge_pairs = _pairs_of_moved(x, x0, self.faces, self.edges, moved, self.margin + self.allow)
        self.tangled = np.zeros(len(x), dtype=np.bool_)
        _crossed_in_pairs(x0, self.edges, self.faces, edge_pairs, self.edge_tris, self.tangled)
        self._keep(np.concatenate([kept_points, points]), np.concatenate([kept_edges, edge_pairs]))
        self.positions[moved] = x[moved]
        self.whole = False
        return True

    def build(self, x: np.ndarray, x0: np.ndarray) -> None:
        """The whole list from the paths x0 -> x (n, 3) m."""
        points, edge_pairs, self.flats = listed_pairs(x, x0, self.faces, self.edges, self.patches, self.margin)
        self.tangled = np.zeros(len(x), dtype=np.bool_)
        _crossed_in_pairs(x0, self.edges, self.faces, edge_pairs, self.edge_tris, self.tangled)
        self._keep(points, edge_pairs)
        self.positions = x.copy()
        self.whole = True

    def _keep(self, points: np.ndarray, edge_pairs: np.ndarray) -> None:
        """List ``points`` (p, 2) and ``edge_pairs`` (q, 2) int64, but none with a point in ``tangled``: where the mesh
        is crossed through itself where the step began no side is right, its pairs are left to the untangling (held
        to the sides they happen to be on, a garment aligned with its legs through each other fought to the step
        limit). An edge through a triangle passes within the triangle's inradius (1 cm on a mesh of 3 cm edges) of
        one of its edges, so the crossings are looked for among the listed edge pairs only (``_crossed_in_pairs``)."""
        if self.tangled.any():
            points, edge_pairs = self._without(points, edge_pairs, self.tangled)
        self.points, self.edge_pairs = points, edge_pairs

    def _without(self, points: np.ndarray, edge_pairs: np.ndarray, marked: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``points`` (p, 2) and ``edge_pairs`` (q, 2) int64 without the pairs that have a point ``marked`` (n,) bool
        (the point, a corner of its triangle, an end of either edge)."""
        points = points[~(marked[points[:, 0]] | marked[self.faces[points[:, 1]]].any(axis=1))]
        return points, edge_pairs[~marked[self.edges[edge_pairs]].reshape(-1, 4).any(axis=1)]


@njit(cache=True, nogil=True)
def _largest_spread(x, positions):
    """m: the largest distance of one of the moves x - positions ((n, 3) m each) from their mean."""
    n = x.shape[0]
    mx, my, mz = 0.0, 0.0, 0.0
    for i in range(n):
        mx += x[i, 0] - positions[i, 0]
        my += x[i, 1] - positions[i, 1]
        mz += x[i, 2] - positions[i, 2]
    mx, my, mz = mx / n, my / n, mz / n
    far = 0.0
    for i in range(n):
        dx, dy, dz = x[i, 0] - positions[i, 0] - mx, x[i, 1] - positions[i, 1] - my, x[i, 2] - positions[i, 2] - mz
        far = max(far, dx * dx + dy * dy + dz * dz)
    return math.sqrt(far)


@njit(cache=True, nogil=True)
def _strayed(x, positions, allow, out):
    """Mark in ``out`` (n,) bool the points of x (n, 3) m further than ``allow`` m from ``positions``."""
    for i in range(x.shape[0]):
        dx, dy, dz = x[i, 0] - positions[i, 0], x[i, 1] - positions[i, 1], x[i, 2] - positions[i, 2]
        if dx * dx + dy * dy + dz * dz > allow * allow:
            out[i] = True

