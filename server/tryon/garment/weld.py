"""Short coarse edges welded after the simplification (``simplify.collapse_with_parents``).

The paper's collapse takes faces in their order, not by size, so an edge far shorter than its neighbours can
outlive it. A mesh made on a fine grid had whole rows 0.1-0.5 mm apart (the first rings of a sleeve blending
out of its armhole); on a 49,260-vertex T-shirt at B = 0.3 (``tryon bench --only scaling``), 182 coarse
springs under 1 mm (the median spring: 12 mm). The simulation stretched them 10-16x at every step (their ends
follow neighbours tens of times farther apart), so the tear guard swept its full 100 times a step, a fifth of
the drape's time. A spring that short carries no shape: its two points are one.

So each coarse edge shorter than ``SHORT_EDGE`` x the median coarse edge is welded, shortest first: its
one end goes into the other (an opening's point is kept over an inner one; a vertex the collapse fixes is
never removed), every face that had both ends goes. A weld is skipped where it would pinch or fold the
surface: the two ends may share no neighbour but the faces' third corners (the link condition of an edge
collapse), a boundary point goes only along its opening, and no face may turn over.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from tryon.geometry import distance, triangle_normal

# Coarse edges shorter than this fraction of the median coarse edge are welded. At B = 0.3 the catalogue's
# shortest is 0.084 of its median (the T-shirt XL's), the nine real garments' tried (``../shared/garments-real``)
# 0.031 (a DiffCloth dress's): none is welded. The 49,260-vertex T-shirt's rows: 0.013 and up.
# At 0.05 as well as at 0.03 its drape to rest took ~20 % less time than without (3.7 / 3.9 s instead of 4.45 on
# one thread, 3.0 / 2.9 instead of 3.7 on two).
SHORT_EDGE = 0.03


def weld_short_edges(pos: np.ndarray, kept: np.ndarray, coarse_faces: np.ndarray, root: np.ndarray,
                     fixed: np.ndarray, on_boundary: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(kept (k',) int32, coarse_faces (g', 3) int32 indexing it, root (n,) int32) with the short edges welded;
    ``pos`` (n, 3) m the original vertices, ``kept`` (k,) their kept ids, ``coarse_faces`` (g, 3) indexing
    ``kept``, ``root`` (n,) the kept vertex each original went to, ``fixed`` (n,) bool never removed,
    ``on_boundary`` (n,) bool the kept vertices on an opening. Returns the inputs themselves when nothing is that
    short."""
    faces = kept[coarse_faces].astype(np.int64)
    a, b = faces.reshape(-1), faces[:, [1, 2, 0]].reshape(-1)
    length = np.linalg.norm(pos[a] - pos[b], axis=1)
    min_length = SHORT_EDGE * np.median(length)
    short = np.flatnonzero(length < min_length)
    if len(short) == 0:
        return kept, coarse_faces, root
    order = short[np.argsort(length[short], kind="stable")]
    alive, into = _weld_kernel(pos, faces, a[order], b[order], len(pos), fixed, on_boundary, min_length)
    went = np.where(into >= 0, into, np.arange(len(pos)))
    faces = went[faces[alive]]
    new_kept = np.unique(faces).astype(np.int32)
    remap = np.full(len(pos), -1, dtype=np.int64)
    remap[new_kept] = np.arange(len(new_kept))
    return new_kept, remap[faces].astype(np.int32), went[root].astype(np.int32)


@njit(cache=True)
def _weld_kernel(pos, faces, ea, eb, n, fixed, on_boundary, min_length):
    """Weld the edges (ea[q], eb[q]) in order where allowed (module doc), on ``faces`` (g, 3) int64 of original
    ids, in place, each only if its ends (or the points they were welded into) are still closer than
    ``min_length`` m. Returns (alive (g,) bool, into (n,) int64: the vertex each welded vertex ended in, -1 for
    the others). Serial: each weld changes the faces the next one tests."""
    g = faces.shape[0]
    alive = np.ones(g, dtype=np.bool_)
    into = np.full(n, -1, dtype=np.int64)
    mark = np.zeros(n, dtype=np.int64)
    stamp = 0
    for q in range(ea.shape[0]):
        a, b = _welded_to(into, ea[q]), _welded_to(into, eb[q])  # an end welded before: the point it went into
        if a == b or distance(pos, a, b) >= min_length:
            continue
        # b goes into a: keep an opening's point, never remove a fixed one
        if (on_boundary[b] and not on_boundary[a]) or (fixed[b] and not fixed[a]):
            a, b = b, a
        if fixed[b]:
            continue
        shared = 0
        for f in range(g):
            if alive[f] and _has(faces, f, a) and _has(faces, f, b):
                shared += 1
        if shared == 0:
            continue
        if on_boundary[a] and on_boundary[b] and shared != 1:
            continue  # two openings' points joined across the cloth: a pinch
        # link condition: a and b share exactly the third corners of their ``shared`` faces
        stamp += 1
        for f in range(g):
            if alive[f] and _has(faces, f, a):
                for r in range(3):
                    mark[faces[f, r]] = stamp
        common = 0
        stamp += 1
        for f in range(g):
            if alive[f] and _has(faces, f, b):
                for r in range(3):
                    v = faces[f, r]
                    if v != a and v != b and mark[v] == stamp - 1:
                        mark[v] = stamp  # count each neighbour once
                        common += 1
        if common != shared:
            continue
        if _turns_over(pos, faces, alive, a, b):
            continue
        for f in range(g):
            if alive[f] and _has(faces, f, b):
                if _has(faces, f, a):
                    alive[f] = False
                else:
                    for r in range(3):
                        if faces[f, r] == b:
                            faces[f, r] = a
        into[b] = a
    for v in range(n):  # a point welded into one welded later: where it ended
        if into[v] >= 0:
            into[v] = _welded_to(into, v)
    return alive, into


@njit(cache=True)
def _welded_to(into, v):
    while into[v] >= 0:
        v = into[v]
    return v


@njit(cache=True, inline="always")
def _has(faces, f, v):
    return faces[f, 0] == v or faces[f, 1] == v or faces[f, 2] == v


@njit(cache=True)
def _turns_over(pos, faces, alive, a, b):
    """Whether a face of b (not of a) would turn its normal by more than 90 degrees with b moved to a."""
    for f in range(faces.shape[0]):
        if not alive[f] or not _has(faces, f, b) or _has(faces, f, a):
            continue
        i, j, k = faces[f, 0], faces[f, 1], faces[f, 2]
        ox, oy, oz = triangle_normal(pos, i, j, k)
        nx, ny, nz = triangle_normal(pos, a if i == b else i, a if j == b else j, a if k == b else k)
        if ox * nx + oy * ny + oz * nz <= 0.0:
            return True
    return False
