"""The paper's triangle-collapse simplification with mark recovery (SPEC section 3, paper 2.2).

``collapse_faces(faces, n_vertices, B, vertices=None) -> (kept (k,) int32, coarse_faces (g, 3) int32)``:
repeatedly collapse an unmarked face onto its first vertex v0 (v1, v2 removed, every reference rewritten
to v0, faces that vanish removed, faces that changed shape marked and skipped for the rest of the pass);
when a pass has seen every face, the marks are cleared ("mark recovery", which spreads the kept vertices
evenly); stop as soon as kept / original <= B. Kept vertices are original vertices.

A file with several separate pieces (a MakeHuman outfit: a blouse and a skirt) is simplified piece by
piece: each connected piece stops at its own ``floor(B x its vertices)``. With one global count the pieces
first in face order took the collapses of the pieces the guards held back (the 395-vertex skirt of a
blouse-and-skirt outfit kept 49 vertices at B = 0.3, a coarse mesh too thin to hold its shape).

With ``vertices`` given, collapses that would spoil the garment are skipped (we go further than the
paper here), and the next vertex of the face is tried as v0:
- openings stay open: a boundary vertex is only removed into its neighbour along the same boundary
  loop, and a loop keeps at least ``sqrt(B)`` of its vertices (a 1-D loop thinned like the 2-D surface),
  with no coarse edge longer than ``1 / MIN_LOOP_SPANS`` of the loop's length (below);
  vertices on non-manifold edges or pinched boundaries are never removed;
- no flipped faces (a changed face's normal turns by less than ``MAX_TURN_DEG``), no slivers (quality
  above ``MIN_QUALITY`` unless it was already worse), no duplicate faces and no edge with more than two
  faces (the collapse must not fold or pinch the surface);
- then the coarse edges far shorter than the others are welded (``weld.py``).

``attach(vertices, parent, kept_faces) -> attach_face, attach_bary, attach_offset`` re-attaches every
original vertex to its nearest coarse face (unclamped barycentric coordinates of its projection on the
face's plane plus the signed distance along the unit normal, so that the rest mesh is reproduced).
"""

from __future__ import annotations

import math

import numpy as np
import scipy.sparse
import scipy.sparse.csgraph
from numba import njit

from tryon.garment.topology import vertex_pieces
from tryon.garment.weld import weld_short_edges
from tryon.geometry import distance, triangle_normal, vertex_normals

# A collapse may turn a changed face's normal by at most this much (degrees): beyond it the coarse
# surface folds (90 degrees would be a flip); 60 degrees keeps the sleeves and hem round.
MAX_TURN_DEG = 60.0
# A coarse face must face the same side as the original surface at its corners: cosine between its
# normal and the mean original vertex normal of its corners at least this (0: never flipped).
MIN_ORIGINAL_COS = 0.0
# Triangle quality 4 sqrt(3) area / sum of squared edges (1 equilateral, 0.87 a quad's half); a collapse
# may not create a face worse than this unless the face was already worse. When no collapse passes any
# more and B is not reached yet, the scan goes on with the looser ``MIN_QUALITY_FALLBACK``.
MIN_QUALITY = 0.3
MIN_QUALITY_FALLBACK = 0.12
# An opening's coarse edges are at most 1/this of its loop's length. Collapsed unevenly, the ten coarse points of
# the hem of a MakeHuman trouser leg (29 cm round, 18 points) were 1 to 8 cm apart, and a shin 7 cm across went
# through the 8 cm chord: the leg ended off the shin, the hem on its inner side (a 178.5 cm ANSUR body; the
# collision keeps points, not edges, out of the body). A limb through a chord needs the chord as wide as the limb,
# about the opening's perimeter / pi when it is tight; 1/8 of it leaves a margin. The catalogue's generated
# openings came out within it already (the longest, a long-sleeve L cuff's, 1/8.07 of its loop): of its 30 coarse
# meshes only the sleeveless dress S's and M's change, to another triangulation of the same points (an armhole's
# chord went past the limit at an intermediate collapse).
MIN_LOOP_SPANS = 8.0
# Neighbourhood scratch size (faces around the three vertices of a collapse); a collapse touching more
# is skipped (never happens on garment meshes, whose vertex valence is < 20).
SCRATCH_FACES = 4096
# A piece keeps at least this many vertices whatever B asks: a closed piece (which no opening guards)
# would otherwise collapse to a point and leave no face to simulate.
MIN_PIECE_VERTICES = 8


def collapse_faces(faces: np.ndarray, n_vertices: int, B: float, vertices: np.ndarray | None = None
                   ) -> tuple[np.ndarray, np.ndarray]:
    """Kept original vertex ids (k,) int32 (sorted) and coarse faces (g, 3) int32 indexing ``kept``."""
    kept, coarse, _ = collapse_with_parents(faces, n_vertices, B, vertices)
    return kept, coarse


def collapse_with_parents(faces: np.ndarray, n_vertices: int, B: float, vertices: np.ndarray | None = None
                          ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """As ``collapse_faces``, plus ``root (n,) int32``: the kept vertex each original vertex went to."""
    if not 0.0 < B <= 1.0:
        raise ValueError(f"simplification degree B must be in (0, 1], got {B}")
    faces = np.ascontiguousarray(faces, dtype=np.int64)
    guard = vertices is not None
    pos = np.ascontiguousarray(vertices, dtype=np.float64) if guard else np.zeros((n_vertices, 3))
    vf_start, vf_list = _vertex_faces(faces, n_vertices)
    fixed, bnext, bprev, loop_id, loop_count, loop_min = _boundary(faces, n_vertices, B, guard)
    loop_max_edge = _loop_lengths(pos, bnext, loop_id, len(loop_count)) / MIN_LOOP_SPANS
    piece, piece_kept = _pieces(faces, n_vertices)
    piece_target = np.maximum(np.floor(B * piece_kept), np.minimum(piece_kept, MIN_PIECE_VERTICES)).astype(np.int64)
    vnorm = vertex_normals(pos, faces) if guard else pos
    fv, alive, parent = _collapse_kernel(
        faces, n_vertices, piece, piece_kept, piece_target, pos, vnorm, guard, vf_start, vf_list, fixed,
        bnext, bprev, loop_id, loop_count, loop_min, loop_max_edge, math.cos(math.radians(MAX_TURN_DEG)),
        MIN_ORIGINAL_COS, MIN_QUALITY, MIN_QUALITY_FALLBACK, SCRATCH_FACES,
    )
    coarse_orig = fv[alive]
    kept = np.unique(coarse_orig).astype(np.int32)
    remap = np.full(n_vertices, -1, dtype=np.int64)
    remap[kept] = np.arange(len(kept))
    root = _roots(parent).astype(np.int32)
    coarse = remap[coarse_orig].astype(np.int32)
    if guard:
        return weld_short_edges(pos, kept, coarse, root, fixed, bnext >= 0)
    return kept, coarse, root


def _pieces(faces: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Connected piece of each vertex ``(n,) int64`` (-1 for a vertex in no face) and the number of
    vertices of each piece ``(p,) int64``."""
    _, label = vertex_pieces(faces, n)
    used = np.zeros(n, dtype=np.bool_)
    used[faces.reshape(-1)] = True
    piece = np.full(n, -1, dtype=np.int64)
    _, piece[used] = np.unique(label[used], return_inverse=True)
    return piece, np.bincount(piece[used]).astype(np.int64)


def _vertex_faces(faces: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """CSR vertex -> incident faces."""
    flat = faces.reshape(-1)
    order = np.argsort(flat, kind="stable")
    start = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(np.bincount(flat, minlength=n), out=start[1:])
    return start, (order // 3).astype(np.int64)


def _boundary(faces: np.ndarray, n: int, B: float, guard: bool):
    """Boundary loops as linked lists (bnext/bprev, -1 elsewhere), loop ids and sizes, fixed vertices."""
    fixed = np.zeros(n, dtype=np.bool_)
    bnext = np.full(n, -1, dtype=np.int64)
    bprev = np.full(n, -1, dtype=np.int64)
    loop_id = np.full(n, -1, dtype=np.int64)
    if not guard:
        return fixed, bnext, bprev, loop_id, np.zeros(1, np.int64), np.zeros(1, np.int64)
    ea = faces[:, [0, 1, 2]].reshape(-1)
    eb = faces[:, [1, 2, 0]].reshape(-1)
    key = np.minimum(ea, eb) * n + np.maximum(ea, eb)
    _, inv, count = np.unique(key, return_inverse=True, return_counts=True)
    per_half = count[inv]
    nonmanifold = per_half > 2
    fixed[ea[nonmanifold]] = True
    fixed[eb[nonmanifold]] = True
    bnd = per_half == 1
    a, b = ea[bnd], eb[bnd]
    out_deg = np.bincount(a, minlength=n)
    in_deg = np.bincount(b, minlength=n)
    pinched = (out_deg + in_deg > 0) & ((out_deg != 1) | (in_deg != 1))
    fixed |= pinched
    ok = ~pinched[a] & ~pinched[b]
    bnext[a[ok]] = b[ok]
    bprev[b[ok]] = a[ok]
    if len(a):
        g = scipy.sparse.coo_matrix((np.ones(len(a)), (a, b)), shape=(n, n))
        _, label = scipy.sparse.csgraph.connected_components(g, directed=False)
        on = np.zeros(n, dtype=bool)
        on[a] = True
        on[b] = True
        _, loop_of = np.unique(label[on], return_inverse=True)
        loop_id[on] = loop_of
        loop_count = np.bincount(loop_of).astype(np.int64)
    else:
        loop_count = np.zeros(1, np.int64)
    loop_min = np.maximum(3, np.ceil(np.sqrt(B) * loop_count)).astype(np.int64)
    return fixed, bnext, bprev, loop_id, loop_count, loop_min


def _loop_lengths(pos: np.ndarray, bnext: np.ndarray, loop_id: np.ndarray, n_loops: int) -> np.ndarray:
    """(n_loops,) m: the length of each boundary loop (``_boundary``) on the vertices ``pos`` (n, 3)."""
    on = np.flatnonzero(bnext >= 0)
    lengths = np.zeros(n_loops)
    np.add.at(lengths, loop_id[on], np.linalg.norm(pos[bnext[on]] - pos[on], axis=1))
    return lengths


def _roots(parent: np.ndarray) -> np.ndarray:
    root = parent.copy()
    while True:
        nxt = root[root]
        if np.array_equal(nxt, root):
            return root
        root = nxt


@njit(cache=True)
def _quality(p, a, b, c, nx, ny, nz):
    area2 = math.sqrt(nx * nx + ny * ny + nz * nz)  # twice the area
    s = 0.0
    for i, j in ((a, b), (b, c), (c, a)):
        dx = p[i, 0] - p[j, 0]
        dy = p[i, 1] - p[j, 1]
        dz = p[i, 2] - p[j, 2]
        s += dx * dx + dy * dy + dz * dz
    if s == 0.0:
        return 0.0
    return 2.0 * math.sqrt(3.0) * area2 / s


@njit(cache=True)
def _boundary_ok(a, b, c, fixed, bnext, bprev, loop_id, loop_count, loop_min, loop_max_edge, pos, guard):
    """May b and c (removed) go into a without closing or pinching an opening, or leaving it an edge longer than
    ``loop_max_edge`` of its loop (m)?"""
    if not guard:
        return True
    if fixed[b] or fixed[c]:
        return False
    nb = 0
    for r in (b, c):
        if loop_id[r] >= 0:
            nb += 1
    if nb == 0:
        return True
    if loop_id[a] < 0:
        return False
    # Simulate the removals in order: each removed boundary vertex must be a's loop neighbour then.
    an, ap = bnext[a], bprev[a]
    removed = 0
    lengthened_next = False
    lengthened_prev = False
    for r in (b, c):
        if loop_id[r] < 0:
            continue
        if loop_id[r] != loop_id[a] or bnext[r] < 0 or bprev[r] < 0:
            return False
        if an == r:
            an = bnext[r]
            lengthened_next = True
        elif ap == r:
            ap = bprev[r]
            lengthened_prev = True
        else:
            return False
        removed += 1
        if an == a or ap == a:
            return False
    longest = loop_max_edge[loop_id[a]]
    if lengthened_next and distance(pos, a, an) > longest:
        return False
    if lengthened_prev and distance(pos, a, ap) > longest:
        return False
    return loop_count[loop_id[a]] - removed >= loop_min[loop_id[a]]


@njit(cache=True, nogil=True)  # nogil: an upload prepared in a worker thread does not stall the server
def _collapse_kernel(faces, n, piece, piece_kept, piece_target, pos, vnorm, guard, vf_start, vf_list, fixed,
                     bnext, bprev, loop_id, loop_count, loop_min, loop_max_edge, cos_turn, cos_original, min_quality,
                     min_quality_fallback, scratch):
    """Sequential collapse (each collapse depends on the previous ones: no parallelism) until every piece
    p has ``piece_kept[p] <= piece_target[p]`` (``piece_kept`` is updated in place)."""
    nf = faces.shape[0]
    fv = faces.copy()
    alive = np.ones(nf, dtype=np.bool_)
    mark = np.zeros(nf, dtype=np.int64)
    parent = np.arange(n)
    head = np.arange(n)  # member chains: head[root] .. nxt[] .. tail[root]
    tail = np.arange(n)
    nxt = np.full(n, -1, dtype=np.int64)
    seen = np.zeros(nf, dtype=np.int64)
    stamp = 0
    buf = np.empty(scratch, dtype=np.int64)
    new_f = np.empty((scratch, 3), dtype=np.int64)
    other = np.empty(2 * scratch, dtype=np.int64)
    # pieces still above their target (vertices in no face belong to none: removed already)
    busy = 0
    for p in range(piece_kept.shape[0]):
        if piece_kept[p] > piece_target[p]:
            busy += 1
    pass_id = 1
    while busy > 0:
        collapsed = 0
        for f in range(nf):
            if busy == 0:
                break
            if not alive[f] or mark[f] == pass_id:
                continue
            pf = piece[fv[f, 0]]
            if piece_kept[pf] <= piece_target[pf]:
                continue
            for rot in range(3):
                a = fv[f, rot]
                b = fv[f, (rot + 1) % 3]
                c = fv[f, (rot + 2) % 3]
                if not _boundary_ok(a, b, c, fixed, bnext, bprev, loop_id, loop_count, loop_min, loop_max_edge, pos,
                                    guard):
                    continue
                # Gather the alive faces around a, b, c (over every original vertex merged into them).
                stamp += 1
                m = 0
                overflow = False
                for r in (a, b, c):
                    u = head[r]
                    while u >= 0 and not overflow:
                        for t in range(vf_start[u], vf_start[u + 1]):
                            g = vf_list[t]
                            if alive[g] and seen[g] != stamp:
                                seen[g] = stamp
                                if m >= scratch:
                                    overflow = True
                                    break
                                buf[m] = g
                                m += 1
                        u = nxt[u]
                if overflow:
                    continue
                ok = True
                n_other = 0
                for i in range(m):
                    g = buf[i]
                    for k in range(3):
                        x = fv[g, k]
                        new_f[i, k] = a if (x == b or x == c) else x
                    p0, p1, p2 = new_f[i, 0], new_f[i, 1], new_f[i, 2]
                    if p0 == p1 or p1 == p2 or p0 == p2:
                        new_f[i, 0] = -1  # vanishes
                        continue
                    if guard:
                        ox, oy, oz = triangle_normal(pos, fv[g, 0], fv[g, 1], fv[g, 2])
                        nx_, ny_, nz_ = triangle_normal(pos, p0, p1, p2)
                        lo = math.sqrt(ox * ox + oy * oy + oz * oz)
                        ln = math.sqrt(nx_ * nx_ + ny_ * ny_ + nz_ * nz_)
                        if ln == 0.0 or ox * nx_ + oy * ny_ + oz * nz_ < cos_turn * lo * ln:
                            ok = False
                            break
                        mx = vnorm[p0, 0] + vnorm[p1, 0] + vnorm[p2, 0]
                        my = vnorm[p0, 1] + vnorm[p1, 1] + vnorm[p2, 1]
                        mz = vnorm[p0, 2] + vnorm[p1, 2] + vnorm[p2, 2]
                        lm = math.sqrt(mx * mx + my * my + mz * mz)
                        if mx * nx_ + my * ny_ + mz * nz_ < cos_original * lm * ln:
                            ok = False
                            break
                        qn = _quality(pos, p0, p1, p2, nx_, ny_, nz_)
                        if qn < min_quality and qn < _quality(pos, fv[g, 0], fv[g, 1], fv[g, 2], ox, oy, oz):
                            ok = False
                            break
                        # the two other vertices in cyclic order after a: directed edges a->x, y->a
                        k0 = 0 if p0 == a else (1 if p1 == a else 2)
                        other[n_other] = new_f[i, (k0 + 1) % 3]
                        other[n_other + 1] = new_f[i, (k0 + 2) % 3]
                        n_other += 2
                if not ok:
                    continue
                if guard:
                    # Manifold and consistently oriented around a: each edge a-x at most once as a->x
                    # (even slot) and once as x->a (odd slot); no two faces on the same vertex pair.
                    for i in range(n_other):
                        for j in range(i + 1, n_other):
                            if other[i] == other[j] and (i % 2) == (j % 2):
                                ok = False
                                break
                        if not ok:
                            break
                    if ok:
                        for i in range(0, n_other, 2):
                            for j in range(i + 2, n_other, 2):
                                if other[i] == other[j + 1] and other[i + 1] == other[j]:
                                    ok = False  # duplicate face (a, x, y) and (a, y, x)
                                    break
                            if not ok:
                                break
                if not ok:
                    continue
                # Commit: b, c -> a.
                for r in (b, c):
                    parent[r] = a
                    nxt[tail[a]] = head[r]
                    tail[a] = tail[r]
                    if guard and loop_id[r] >= 0:
                        p_, q_ = bprev[r], bnext[r]
                        bnext[p_] = q_
                        bprev[q_] = p_
                        loop_count[loop_id[r]] -= 1
                        bnext[r] = -1
                        bprev[r] = -1
                for i in range(m):
                    g = buf[i]
                    if new_f[i, 0] < 0:
                        alive[g] = False
                    else:
                        fv[g, 0] = new_f[i, 0]
                        fv[g, 1] = new_f[i, 1]
                        fv[g, 2] = new_f[i, 2]
                        mark[g] = pass_id
                piece_kept[pf] -= 2
                if piece_kept[pf] <= piece_target[pf]:
                    busy -= 1
                collapsed += 1
                break
        if collapsed == 0:
            if min_quality > min_quality_fallback:
                min_quality = min_quality_fallback
                continue
            break  # every remaining collapse would spoil the mesh: B cannot be reached
        pass_id += 1  # mark recovery: clear every mark and scan again
    return fv, alive, parent


# --- re-attachment --------------------------------------------------------------------------------


def attach(vertices: np.ndarray, root: np.ndarray, kept: np.ndarray, coarse_faces: np.ndarray
           ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each original vertex as a point of a coarse face: ``attach_face (n,) int32``,
    ``attach_bary (n, 3)``, ``attach_offset (n,)`` (m along the face's unit normal)."""
    vertices = np.ascontiguousarray(vertices, dtype=np.float64)
    faces_orig = np.ascontiguousarray(kept[coarse_faces], dtype=np.int64)  # coarse faces in original ids
    start, flist = _vertex_faces(faces_orig, len(vertices))
    face, bary, offset = _attach_kernel(vertices, np.ascontiguousarray(root, dtype=np.int64), faces_orig, start, flist)
    return face.astype(np.int32), bary, offset


@njit(cache=True, fastmath=True)
def _closest_sq(V, v, i, j, k):
    """Squared distance from vertex v to triangle (i, j, k) of V (Ericson, Real-Time Collision
    Detection 5.1.5), in scalars (no temporaries). The same point as ``geometry.closest_on_triangle``, but
    with fastmath and its own rounding: the re-attachment's nearest face is part of every prepared model,
    and the other rounding picks another face at near-ties (all catalogue drapes then differ slightly)."""
    px, py, pz = V[v, 0], V[v, 1], V[v, 2]
    ax, ay, az = V[i, 0], V[i, 1], V[i, 2]
    abx, aby, abz = V[j, 0] - ax, V[j, 1] - ay, V[j, 2] - az
    acx, acy, acz = V[k, 0] - ax, V[k, 1] - ay, V[k, 2] - az
    apx, apy, apz = px - ax, py - ay, pz - az
    d1 = abx * apx + aby * apy + abz * apz
    d2 = acx * apx + acy * apy + acz * apz
    if d1 <= 0.0 and d2 <= 0.0:
        s, t = 0.0, 0.0
    else:
        bpx, bpy, bpz = apx - abx, apy - aby, apz - abz
        d3 = abx * bpx + aby * bpy + abz * bpz
        d4 = acx * bpx + acy * bpy + acz * bpz
        if d3 >= 0.0 and d4 <= d3:
            s, t = 1.0, 0.0
        else:
            vc = d1 * d4 - d3 * d2
            if vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
                s, t = d1 / (d1 - d3), 0.0
            else:
                cpx, cpy, cpz = apx - acx, apy - acy, apz - acz
                d5 = abx * cpx + aby * cpy + abz * cpz
                d6 = acx * cpx + acy * cpy + acz * cpz
                if d6 >= 0.0 and d5 <= d6:
                    s, t = 0.0, 1.0
                else:
                    vb = d5 * d2 - d1 * d6
                    if vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
                        s, t = 0.0, d2 / (d2 - d6)
                    else:
                        va = d3 * d6 - d5 * d4
                        if va <= 0.0 and (d4 - d3) >= 0.0 and (d5 - d6) >= 0.0:
                            w = (d4 - d3) / ((d4 - d3) + (d5 - d6))
                            s, t = 1.0 - w, w
                        else:
                            den = 1.0 / (va + vb + vc)
                            s, t = vb * den, vc * den
    dx = apx - s * abx - t * acx
    dy = apy - s * aby - t * acy
    dz = apz - s * abz - t * acz
    return dx * dx + dy * dy + dz * dz


@njit(cache=True, nogil=True)  # nogil: an upload prepared in a worker thread does not stall the server
def _attach_kernel(vertices, root, faces, start, flist):
    """Nearest coarse face among those around the vertex's root and its neighbours (2 rings); a vertex
    whose root lost every face searches all faces. Independent per vertex."""
    n = vertices.shape[0]
    g = faces.shape[0]
    face_out = np.empty(n, dtype=np.int64)
    bary = np.zeros((n, 3))
    offset = np.zeros(n)
    for v in range(n):
        p = vertices[v]
        r = root[v]
        best = -1
        best_d = np.inf
        if start[v + 1] > start[v]:  # a kept vertex: exactly on one of its faces
            best = flist[start[v]]
            best_d = 0.0
        elif start[r + 1] > start[r]:
            for t in range(start[r], start[r + 1]):
                f0 = flist[t]
                for k in range(3):
                    u = faces[f0, k]
                    for s in range(start[u], start[u + 1]):
                        f = flist[s]
                        d = _closest_sq(vertices, v, faces[f, 0], faces[f, 1], faces[f, 2])
                        if d < best_d:
                            best_d = d
                            best = f
        else:
            for f in range(g):
                d = _closest_sq(vertices, v, faces[f, 0], faces[f, 1], faces[f, 2])
                if d < best_d:
                    best_d = d
                    best = f
        face_out[v] = best
        a = vertices[faces[best, 0]]
        e1 = vertices[faces[best, 1]] - a
        e2 = vertices[faces[best, 2]] - a
        nrm = np.cross(e1, e2)
        ln = math.sqrt(nrm @ nrm)
        if start[v + 1] > start[v]:
            for k in range(3):
                if faces[best, k] == v:
                    bary[v, k] = 1.0
            continue
        nrm = nrm / ln
        w = p - a
        h = w @ nrm
        w = w - h * nrm
        # solve w = s e1 + t e2 in the plane
        d11 = e1 @ e1
        d12 = e1 @ e2
        d22 = e2 @ e2
        dw1 = w @ e1
        dw2 = w @ e2
        den = d11 * d22 - d12 * d12
        s = (d22 * dw1 - d12 * dw2) / den
        t = (d11 * dw2 - d12 * dw1) / den
        bary[v, 0] = 1.0 - s - t
        bary[v, 1] = s
        bary[v, 2] = t
        offset[v] = h
    return face_out, bary, offset
