"""The separate pieces of a garment file and the kind each is aligned as (issue 5).

A file may hold several garments at once (a MakeHuman outfit: a shirt and trousers, a blouse and a
skirt, as separate connected components). Aligned as one rigid "top", the trousers go wherever the shirt
puts them (the outfit was modelled on another body, with another distance from shoulders to waist), so
their legs miss the body's legs. Each piece is therefore aligned by its own kind:

- a piece whose top hangs below the middle of the highest piece (its top is at a waist) is a bottom:
  its waistband goes to the body's waist, its legs over the body's legs;
- every other piece (the one over the shoulders, and anything beside it, such as a collar or a belt
  modelled with it) is aligned with the highest piece, by the garment's category.

Beside a bottom, each other piece is a top or a dress by its length (``piece_kinds``): a top's hem hangs a
little below the bottom's waistband (a shirt over trousers), a dress reaches down over the legs. A garment
catalogued as a bottom is one bottom, whatever its pieces. Pieces are the connected components
of the coarse mesh (simplification never joins two components), found when needed: a few hundred
microseconds on a 700-vertex coarse mesh, cheaper than a new cached model format.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from tryon.garment.topology import vertex_pieces

# A piece is a bottom when its highest point is below this fraction of the highest piece's height (from
# the highest piece's lowest point). 0.5: a waistband hangs at most at the middle of a shirt; the
# MakeHuman trousers and skirt tops are at 0.05-0.25 of their shirt's or blouse's height, and a collar,
# belt or sleeve piece modelled beside a top reaches far higher.
BOTTOM_TOP_FRACTION = 0.5
# A piece of a section counts as a leg when it crosses at least this share of the section's crossed edges (a
# trouser leg below the crotch: about half; the DiffCloth skirt's section meets small flaps, 4-6 edges of 95,
# on either side of the centre line, and it was taken for shorts and lowered from the waist).
LEG_SHARE = 0.25
# A piece beside a bottom is a top when its hem hangs below the bottom's waist (the bottom's highest point) by at
# most this fraction of how far the piece reaches above that waist (its neck), else a dress: a top ends about the
# hips, a dress reaches down the legs. The MakeHuman T-shirt, blouse and shirt hang 0.09, 0.17 and 0.23 of it
# below their trousers' or skirt's waist, the generator's long T-shirt and long-sleeve top (to the crotch) 0.73
# and 0.80; its dress 1.29 (a hand over the knee), a hem at mid-thigh about 1. The highest piece over a bottom
# always ends above it (the bottom's waist is under its middle, ``BOTTOM_TOP_FRACTION``): a dress worn over
# trousers is one garment, a dress, since its trousers' waist is above its middle.
TOP_HEM_FRACTION = 1.0
# m: how far from its waist opening a bottom's waistband reaches (a sewn band is 3-4 cm tall).
BAND_DEPTH = 0.03


def piece_labels(faces: np.ndarray, n_vertices: int) -> np.ndarray:
    """(n_vertices,) int64 connected-component label of each vertex over the triangles ``faces`` (f, 3);
    a vertex in no face is a piece of its own."""
    return vertex_pieces(faces, n_vertices)[1]


def piece_tops(x: np.ndarray, piece: np.ndarray) -> np.ndarray:
    """(p,) m: the height of the highest of the points x (k, 3) of each piece (``piece`` (k,) labels 0..p-1)."""
    top = np.full(int(piece.max()) + 1 if len(piece) else 0, -np.inf)
    np.maximum.at(top, piece, x[:, 1])
    return top


def hanging_pieces(label: np.ndarray, held: np.ndarray) -> np.ndarray:
    """(k,) bool: which points are in a piece (``label`` (k,) int64, ``piece_labels``) of which some point
    is ``held`` (k,) bool (touching the body, or pinned): cloth that can hang. A piece held by nothing
    is falling (it slid off the body)."""
    held_piece = np.zeros(int(label.max()) + 1 if len(label) else 0, dtype=np.bool_)
    held_piece[label[held]] = True
    return held_piece[label]


def bottom_mask(points: np.ndarray, faces: np.ndarray, category: str,
                label: np.ndarray | None = None) -> np.ndarray:
    """(k,) bool: which of the garment's points (k, 3), metres, y up, belong to a piece aligned as a bottom
    (see the module doc). ``faces`` (f, 3) index ``points``; ``category`` is top | bottom | dress; ``label``
    (k,) their ``piece_labels`` if the caller has them."""
    k = len(points)
    if category == "bottom":
        return np.ones(k, dtype=np.bool_)
    if label is None:
        label = piece_labels(faces, k)
    count = int(label.max()) + 1 if k else 0
    if count < 2:
        return np.zeros(k, dtype=np.bool_)
    top_y = piece_tops(points, label)
    low_y = np.full(count, np.inf)
    np.minimum.at(low_y, label, points[:, 1])
    highest = int(np.argmax(top_y))
    cut = low_y[highest] + BOTTOM_TOP_FRACTION * (top_y[highest] - low_y[highest])
    return (top_y < cut)[label]


def piece_kinds(points: np.ndarray, faces: np.ndarray, category: str,
                label: np.ndarray | None = None) -> list[str] | None:
    """For a garment of separate pieces with a bottom among them (a shirt and trousers in one file), each
    piece's kind in label order: ``bottom`` for a piece hanging from a waist (``bottom_mask``); beside it, a
    ``top`` if its hem ends above the legs (``TOP_HEM_FRACTION``), else a ``dress``. None for a garment of one
    piece, of pieces none or all of which are a bottom, or catalogued as a bottom (one bottom, whatever its
    pieces). ``points`` (k, 3) m, y up; ``faces`` (f, 3); ``category`` top | bottom | dress; ``label`` (k,)
    their ``piece_labels`` if the caller has them."""
    k = len(points)
    if category == "bottom":
        return None
    if label is None:
        label = piece_labels(faces, k)
    count = int(label.max()) + 1 if k else 0
    if count < 2:
        return None
    bottom = bottom_mask(points, faces, category, label)
    if not bottom.any() or bottom.all():
        return None
    top_y = piece_tops(points, label)
    low_y = np.full(count, np.inf)
    np.minimum.at(low_y, label, points[:, 1])
    is_bottom = np.zeros(count, dtype=np.bool_)
    is_bottom[label[bottom]] = True
    waist = top_y[is_bottom].max()
    return ["bottom" if is_bottom[p] else
            "top" if waist - low_y[p] <= TOP_HEM_FRACTION * max(top_y[p] - waist, 0.0) else "dress"
            for p in range(count)]


def waistband_mask(points: np.ndarray, faces: np.ndarray, category: str, loops: list[np.ndarray],
                   piece: np.ndarray, depth: float = BAND_DEPTH) -> np.ndarray:
    """(k,) bool: which of the garment's points (k, 3), metres, y up, are in the waistband of a piece
    aligned as a bottom (``bottom_mask``): within ``depth`` m of its waist opening, the highest of its
    boundary loops (``loops``: int64 point ids each), if that reaches within ``depth`` of the piece's top.
    ``faces`` (f, 3) index ``points``; ``piece`` (k,) their ``piece_labels``."""
    band = np.zeros(len(points), dtype=np.bool_)
    bottom = bottom_mask(points, faces, category, piece)
    if not bottom.any():
        return band
    top = piece_tops(points, piece)
    waist = {}  # piece -> its highest opening
    for loop in loops:  # a garment has a handful of openings
        own = int(piece[loop[0]])
        if bottom[loop[0]] and (own not in waist or points[loop, 1].max() > points[waist[own], 1].max()):
            waist[own] = loop
    for own, loop in waist.items():
        if points[loop, 1].max() < top[own] - depth:
            continue
        mine = np.flatnonzero(piece == own)
        gap = points[mine, None, :] - points[None, loop, :]
        band[mine[np.einsum("ijk,ijk->ij", gap, gap).min(axis=1) <= depth * depth]] = True
    return band


@njit(cache=True, nogil=True)
def union_root(parent, e):
    """The root of element ``e`` in the union-find forest ``parent`` (n,) int64, halving its path."""
    while parent[e] != e:
        parent[e] = parent[parent[e]]  # path halving
        e = parent[e]
    return e


@njit(cache=True, nogil=True)
def section_sides(x, faces, face_edges, edges, y, cx, min_edges):
    """(left, right): whether the horizontal section at height ``y`` (m) of the mesh (points x (k, 3),
    faces (f, 3), their edges from ``topology.face_edge_ids``) has a piece whose mean x is below ``cx``
    (m), and one whose mean x is above it. A piece is a connected run of the section (the crossed edges of
    adjacent faces) crossing ``min_edges`` edges or more, and ``LEG_SHARE`` of the section's. A pair of
    trousers has one piece above its crotch (the seat, about the centre line) and two below (the legs),
    however close the legs hang."""
    n_e = edges.shape[0]
    parent = np.arange(n_e)
    crossed = np.empty(n_e, np.bool_)
    for e in range(n_e):
        crossed[e] = (x[edges[e, 0], 1] > y) != (x[edges[e, 1], 1] > y)
    for f in range(faces.shape[0]):
        first = -1
        for c in range(3):
            e = face_edges[f, c]
            if crossed[e]:
                if first < 0:
                    first = e
                else:  # a face crossed by the plane joins its two crossed edges
                    parent[union_root(parent, e)] = union_root(parent, first)
    count = np.zeros(n_e)
    sum_x = np.zeros(n_e)
    total = 0.0
    for e in range(n_e):
        if crossed[e]:
            r = union_root(parent, e)
            count[r] += 1.0
            total += 1.0
            sum_x[r] += 0.5 * (x[edges[e, 0], 0] + x[edges[e, 1], 0])
    left = False
    right = False
    for r in range(n_e):
        if count[r] >= max(min_edges, LEG_SHARE * total):
            mean = sum_x[r] / count[r]
            left = left or mean < cx
            right = right or mean > cx
    return left, right
