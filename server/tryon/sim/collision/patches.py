"""The broad phase of a mesh's contact with itself by patches and their normal cones (issue 53 item 1): the mesh's
triangles are grown once into patches of about ``PATCH_FACES`` triangles, and every list of the pairs near enough
to touch (``SelfContact.build``) looks only between patches whose swept boxes come within the reach, and within a
patch (or two a few patches apart, ``RINGS``) only where it is not flat: a piece of surface whose normals all lie
within ``FLAT_ANGLE`` of one direction is a height field over the plane across it and cannot fold onto itself
(Volino and Magnenat-Thalmann 1994, the curvature criterion; Provot 1997). Cloth lying smoothly on a body, most of
a garment, lists nothing; the near neighbours along the surface (most of the pairs a grid of boxes finds) are not
looked at there.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from tryon.geometry import face_normals
from tryon.sim.collision.ccd import far_from_edge, far_from_triangle

# triangles a patch grows to: on the coarse meshes' ~3 cm triangles a patch is about 4 cm across. Patches of
# 4, 6 or 8 triangles (with ``RINGS`` 2 or 3) cost about the same
PATCH_FACES = 4
# rad: the largest angle between the normals of patches flat together (at the step's start and end) and their
# mean. Under 90 degrees a smooth piece is a height field over the plane across the mean, but the coarse meshes'
# creases are not smooth: at 60 degrees 20 of the small body's trousers M's 34 steps ended with crossings the
# step did not begin with (239 in all; none at 45 or 30 degrees, or with nothing left out)
FLAT_ANGLE = math.radians(45.0)
# patches this many steps apart in the patch graph (sharing a point: one) are looked at as one piece of cloth,
# left out where flat together: on a mesh of 3 cm triangles the boxes of patches two and three steps apart
# still overlap, and their pairs are the cloth's neighbours along its surface. A piece between them folded
# back into a Z is looked at against each of them.
RINGS = 3


@dataclass(frozen=True)
class Patches:
    """A mesh's triangles in patches: ``face_start`` (c + 1,) and ``face_ids`` (f,) int64 list each patch's
    triangles, ``point_start``/``point_ids`` the points it owns (each point one patch, one of its triangles'),
    ``edge_start``/``edge_ids`` the edges it owns (each edge the patch of its first triangle); ``near`` (c, c)
    bool: the patches at most ``RINGS`` steps apart (a step: sharing a point)."""

    face_start: np.ndarray
    face_ids: np.ndarray
    point_start: np.ndarray
    point_ids: np.ndarray
    edge_start: np.ndarray
    edge_ids: np.ndarray
    near: np.ndarray


@njit(cache=True, nogil=True)
def _grow(face_nbrs, size):
    """(f,) int64: each triangle's patch, grown breadth-first over shared edges (``face_nbrs`` (f, 3) int64, -1 at
    a border) from the lowest triangle not yet in one, until it has ``size`` triangles or no neighbour left."""
    n = face_nbrs.shape[0]
    patch = np.full(n, -1, dtype=np.int64)
    queue = np.empty(n, dtype=np.int64)
    count = 0
    for seed in range(n):
        if patch[seed] >= 0:
            continue
        patch[seed] = count
        queue[0] = seed
        head, tail = 0, 1
        while head < tail and tail < size:
            f = queue[head]
            head += 1
            for k in range(3):
                g = face_nbrs[f, k]
                if g >= 0 and patch[g] < 0 and tail < size:
                    patch[g] = count
                    queue[tail] = g
                    tail += 1
        count += 1
    return patch


@njit(cache=True, nogil=True)
def _adjacent(faces, patch, n_patches, n_points):
    """(c, c) bool: patches with a point in common."""
    out = np.zeros((n_patches, n_patches), dtype=np.bool_)
    star_start = np.zeros(n_points + 1, dtype=np.int64)
    for f in range(faces.shape[0]):
        for k in range(3):
            star_start[faces[f, k] + 1] += 1
    for v in range(n_points):
        star_start[v + 1] += star_start[v]
    fill = star_start[:-1].copy()
    star = np.empty(star_start[-1], dtype=np.int64)
    for f in range(faces.shape[0]):
        for k in range(3):
            v = faces[f, k]
            star[fill[v]] = patch[f]
            fill[v] += 1
    for v in range(n_points):
        for s in range(star_start[v], star_start[v + 1]):
            for t in range(star_start[v], star_start[v + 1]):
                out[star[s], star[t]] = True  # the patches round point v, pairwise
    return out


@njit(cache=True, nogil=True)
def _ring_further(near, step):
    """(c, c) bool: the patches ``near`` (c, c) bool marks, and those one ``step`` (c, c) bool from one of them
    (through each patch's list of its step-neighbours: the cost follows the neighbours, not c^3)."""
    n = near.shape[0]
    start = np.zeros(n + 1, dtype=np.int64)
    for r in range(n):
        start[r + 1] = start[r] + np.count_nonzero(step[r])
    ids = np.empty(start[n], dtype=np.int64)
    for r in range(n):
        ids[start[r]:start[r + 1]] = np.flatnonzero(step[r])
    out = near.copy()
    for p in range(n):
        for r in range(n):
            if near[p, r]:
                for k in range(start[r], start[r + 1]):
                    out[p, ids[k]] = True
    return out


def _ranges(owner: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """(start (n + 1,), ids) int64: the items of each owner 0..n-1 (``owner`` (m,) int64), in index order."""
    ids = np.argsort(owner, kind="stable").astype(np.int64)
    start = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(np.bincount(owner, minlength=n), out=start[1:])
    return start, ids


def make_patches(faces: np.ndarray, n_points: int, edge_tris: np.ndarray, face_edges: np.ndarray,
                 size: int = PATCH_FACES) -> Patches:
    """The ``Patches`` of the mesh ``faces`` (f, 3) int64 of ``n_points`` points, with its edges' triangles
    ``edge_tris`` (e, 2) int64 (-1: none) and the triangles' edges ``face_edges`` (f, 3) int64."""
    other = np.where(edge_tris[face_edges, 0] == np.arange(len(faces))[:, None], edge_tris[face_edges, 1],
                     edge_tris[face_edges, 0])
    patch = _grow(np.ascontiguousarray(other, dtype=np.int64), int(size))
    n = int(patch.max()) + 1 if len(patch) else 0
    first = np.full(n_points, len(faces), dtype=np.int64)  # each point's first triangle (none: len(faces))
    np.minimum.at(first, faces.ravel(), np.repeat(np.arange(len(faces), dtype=np.int64), 3))
    used = first < len(faces)
    point_start, point_ids = _ranges(np.where(used, patch[np.minimum(first, len(faces) - 1)], n), n + 1)
    face_start, face_ids = _ranges(patch, n)
    edge_start, edge_ids = _ranges(patch[edge_tris[:, 0]], n)
    step = _adjacent(faces, patch, n, n_points)
    near = step
    for _ in range(RINGS - 1):
        near = _ring_further(near, step)
    return Patches(face_start, face_ids, point_start[:-1].copy(), point_ids, edge_start, edge_ids, near)


@njit(cache=True, nogil=True)
def _face_normals(x, faces):
    """(f, 3): each triangle's winding unit normal at x (n, 3) m (zero for a degenerate one)."""
    out = np.empty((faces.shape[0], 3))
    face_normals(x, faces, out)
    return out


@njit(cache=True, nogil=True)
def _flat(p, q, face_start, face_ids, n1, n0, cos_flat):
    """Whether patches p and q (p == q: one) are flat together: every triangle's normal at the end (n1 (f, 3)) and at
    the start (n0) of the step within acos(cos_flat) of their mean; a degenerate triangle is not."""
    mx, my, mz = 0.0, 0.0, 0.0
    for r in (p, q):
        for k in range(face_start[r], face_start[r + 1]):
            f = face_ids[k]
            mx += n1[f, 0] + n0[f, 0]
            my += n1[f, 1] + n0[f, 1]
            mz += n1[f, 2] + n0[f, 2]
        if p == q:
            break
    ln = math.sqrt(mx * mx + my * my + mz * mz)
    if ln < 1e-12:
        return False
    mx, my, mz = mx / ln, my / ln, mz / ln
    for r in (p, q):
        for k in range(face_start[r], face_start[r + 1]):
            f = face_ids[k]
            if n1[f, 0] * mx + n1[f, 1] * my + n1[f, 2] * mz < cos_flat or \
                    n0[f, 0] * mx + n0[f, 1] * my + n0[f, 2] * mz < cos_flat:
                return False
    return True


@njit(cache=True, nogil=True)
def path_boxes(x, x0, ids):
    """(m, 6) m: the box (lo x, lo y, lo z, hi x, hi y, hi z) of each row of points ``ids`` (m, k) int64 over their
    paths from x0 to x."""
    out = np.empty((ids.shape[0], 6))
    for r in range(ids.shape[0]):
        for ax in range(3):
            lo = np.inf
            hi = -np.inf
            for k in range(ids.shape[1]):
                v = ids[r, k]
                lo = min(lo, min(x[v, ax], x0[v, ax]))
                hi = max(hi, max(x[v, ax], x0[v, ax]))
            out[r, ax] = lo
            out[r, 3 + ax] = hi
    return out


@njit(cache=True, nogil=True)
def boxes_apart(box_a, a, box_b, b, pad):
    """Whether box a of ``box_a`` and box b of ``box_b`` (``path_boxes``) lie more than ``pad`` m apart on an axis."""
    for ax in range(3):
        if box_a[a, ax] > box_b[b, 3 + ax] + pad or box_b[b, ax] > box_a[a, 3 + ax] + pad:
            return True
    return False


@njit(cache=True, nogil=True)
def _within(ids, lo, hi, box, patch_box, patch, reach, out):
    """How many of ``ids[lo:hi]`` have a ``box`` row within ``reach`` m of row ``patch`` of ``patch_box``: written
    to ``out``."""
    n = 0
    for s in range(lo, hi):
        r = ids[s]
        if not boxes_apart(box, r, patch_box, patch, reach):
            out[n] = r
            n += 1
    return n


@njit(cache=True, nogil=True)
def _point_face(x, x0, faces, i, f, reach, point_box, face_box, points, count):
    """Append (i, f) to ``points`` (as far as it holds; returns the new count) if point i is no corner of triangle
    f and their paths come within ``reach`` m (boxes, then ``far_from_triangle``)."""
    if i == faces[f, 0] or i == faces[f, 1] or i == faces[f, 2] or boxes_apart(point_box, i, face_box, f, reach) or \
            far_from_triangle(i, f, x, x0, faces, reach):
        return count
    if count < points.shape[0]:
        points[count, 0] = i
        points[count, 1] = f
    return count + 1


@njit(cache=True, nogil=True)
def _edge_edge(x, x0, edges, e, k, reach, edge_box, pairs, count):
    """Append (min, max) of edges e and k to ``pairs`` (as far as it holds; returns the new count) if they share
    no end and their paths come within ``reach`` m (boxes, then ``far_from_edge``)."""
    p1, p2, q1, q2 = edges[e, 0], edges[e, 1], edges[k, 0], edges[k, 1]
    if q1 == p1 or q1 == p2 or q2 == p1 or q2 == p2 or boxes_apart(edge_box, e, edge_box, k, reach) or \
            far_from_edge(p1, p2, q1, q2, x, x0, reach):
        return count
    if count < pairs.shape[0]:
        pairs[count, 0] = min(e, k)
        pairs[count, 1] = max(e, k)
    return count + 1


@njit(cache=True, nogil=True)
def near_pairs(x, x0, faces, edges, face_start, face_ids, point_start, point_ids, edge_start, edge_ids, near,
               reach, cos_flat, points, pairs, flats):
    """The (point, triangle) and (edge, edge) pairs whose paths from x0 to x (n, 3) m come within ``reach`` m, in
    every pair of patches (``Patches``' arrays) whose boxes do and that are not flat together (``_flat``: one
    patch, or two ``near`` each other), into ``points`` (p, 2) and ``pairs`` (q, 2) int64 as far as they hold,
    and the pairs of patches left out as flat together into ``flats`` (r, 2) int64; returns how many of each
    there are. Each pair once: a point and an edge belong to one patch."""
    n_patches = face_start.shape[0] - 1
    n1, n0 = _face_normals(x, faces), _face_normals(x0, faces)
    point_box = path_boxes(x, x0, np.arange(x.shape[0]).reshape(-1, 1))
    face_box = path_boxes(x, x0, faces)
    edge_box = path_boxes(x, x0, edges)
    patch_box = np.empty((n_patches, 6))  # each patch's: its triangles' boxes together
    for p in range(n_patches):
        patch_box[p, :3], patch_box[p, 3:] = np.inf, -np.inf
        for k in range(face_start[p], face_start[p + 1]):
            for ax in range(3):
                patch_box[p, ax] = min(patch_box[p, ax], face_box[face_ids[k], ax])
                patch_box[p, 3 + ax] = max(patch_box[p, 3 + ax], face_box[face_ids[k], 3 + ax])
    near_a = np.empty(max(x.shape[0], max(faces.shape[0], edges.shape[0])), dtype=np.int64)
    near_b = np.empty_like(near_a)
    n_points, n_pairs, n_flats = 0, 0, 0
    order = np.argsort(patch_box[:, 1])  # sweep and prune along y: the patches whose heights overlap
    for u in range(n_patches):
        p = order[u]
        for w in range(u, n_patches):
            q = order[w]
            if patch_box[q, 1] > patch_box[p, 4] + reach:
                break
            if boxes_apart(patch_box, p, patch_box, q, reach):
                continue
            if (p == q or near[p, q]) and _flat(p, q, face_start, face_ids, n1, n0, cos_flat):
                if n_flats < flats.shape[0]:
                    flats[n_flats, 0], flats[n_flats, 1] = p, q
                n_flats += 1
                continue
            for a, b in ((p, q), (q, p)):  # a's points near b's box against b's triangles near a's box
                m = _within(point_ids, point_start[a], point_start[a + 1], point_box, patch_box, b, reach, near_a)
                k = _within(face_ids, face_start[b], face_start[b + 1], face_box, patch_box, a, reach, near_b)
                for s in range(m):
                    for t in range(k):
                        n_points = _point_face(x, x0, faces, near_a[s], near_b[t], reach, point_box, face_box,
                                               points, n_points)
                if p == q:
                    break
            m = _within(edge_ids, edge_start[p], edge_start[p + 1], edge_box, patch_box, q, reach, near_a)
            k = _within(edge_ids, edge_start[q], edge_start[q + 1], edge_box, patch_box, p, reach, near_b)
            for s in range(m):
                for t in range(s + 1 if p == q else 0, k):
                    n_pairs = _edge_edge(x, x0, edges, near_a[s], near_b[t], reach, edge_box, pairs, n_pairs)
    return n_points, n_pairs, n_flats


@njit(cache=True, nogil=True)
def still_flat(x, x0, faces, face_start, face_ids, flats, cos_flat):
    """Whether every pair of patches ``flats`` (r, 2) int64 is still flat together (``_flat``) for the paths x0 ->
    x (n, 3) m: a list that left their pairs out may be kept only while they are."""
    if flats.shape[0] == 0:
        return True
    n1, n0 = _face_normals(x, faces), _face_normals(x0, faces)
    for k in range(flats.shape[0]):
        if not _flat(flats[k, 0], flats[k, 1], face_start, face_ids, n1, n0, cos_flat):
            return False
    return True


def listed_pairs(x: np.ndarray, x0: np.ndarray, faces: np.ndarray, edges: np.ndarray, patches: Patches,
                 reach: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(points (p, 2), edge pairs (q, 2), flat patch pairs (r, 2)) int64: ``near_pairs`` of the mesh ``faces``
    (f, 3), ``edges`` (e, 2) in its ``patches``, for the paths x0 -> x (n, 3) m, however many."""
    args = (x, x0, faces, edges, patches.face_start, patches.face_ids, patches.point_start, patches.point_ids,
            patches.edge_start, patches.edge_ids, patches.near, float(reach), math.cos(FLAT_ANGLE))
    # room for as many flat pairs as there are near pairs of patches (each is met once): no second search
    sizes = (4 * len(faces), 4 * len(edges), int(np.count_nonzero(patches.near)))
    while True:
        out = tuple(np.empty((n, 2), dtype=np.int64) for n in sizes)
        counts = near_pairs(*args, *out)
        if all(c <= n for c, n in zip(counts, sizes)):
            break
        sizes = counts
    points, pairs, flats = (a[:c] for a, c in zip(out, counts))
    # in the order of their points (Gauss-Seidel passes go through them so; the patches' order is the growth's)
    return points[np.lexsort((points[:, 1], points[:, 0]))], pairs[np.lexsort((pairs[:, 1], pairs[:, 0]))], flats


def kept_flat(x: np.ndarray, x0: np.ndarray, faces: np.ndarray, patches: Patches, flats: np.ndarray) -> bool:
    """``still_flat`` for the pairs of ``patches`` a list left out (``listed_pairs``' third)."""
    return bool(still_flat(x, x0, faces, patches.face_start, patches.face_ids, flats, math.cos(FLAT_ANGLE)))
