"""Collision of garment points with the body (paper sections 3.3-3.4).

The body is offset outward along its vertex normals by the collision margin (``offset_body``), so only
point-triangle contacts matter. For a garment point p and each body part whose OBB contains it (only the
parts the garment comes near are tested at all, ``relevant_parts``):

1. local cylinder coordinates (r, theta, z) of p; its cell of the part's cylinder map;
2. the ray from p's projection on the part axis through p (perpendicular to the axis, so it keeps theta
   and z and can only hit that cell's triangles) is intersected with the cell's offset triangles, a hit
   counting when it lies inside its triangle (``inside_triangle``);
3. p is inside the part iff the ray crosses the surface an odd number of times beyond p (for a convex
   cross-section: iff p is closer to the axis than the hit, the paper's test; the count also gets the
   hollows of the surface right);
4. response: p moves to the first hit beyond it + lambda * n (eq. 4), n the hit triangle's unit normal.

Where the construction has no good answer we fall back to the nearest point of the part's offset
surface among the faces of the 3 x 3 neighbouring cells:
- the ray hits its triangle at a grazing angle (n . ray < 0.7, e.g. under the top of the shoulders): the
  radial push would be long and sideways, the nearest surface point is the short way out;
- the ray misses every triangle of its cell (the part's open end at the armpit or crotch, overlaps): p
  is inside iff it is behind the nearest face (signed distance along that face's normal < 0), judged
  only within ``FALLBACK_DEPTH`` of the surface so the open ends of a tube never capture far points.
Overlapping parts (a point in the torso and in the upper arm's box) are handled by repeating the part
loop (up to ``ROUNDS`` times) until no part reports the point inside, so it leaves the union of parts.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from tryon.sim.collision.contacts import coulomb_cut
from tryon.geometry import closest_on_triangle, face_normals
from tryon.sim.collision.inside import inside_triangle_xyz

# Below this cosine between the ray and the hit triangle's normal, the radial push is replaced by the
# nearest-surface push (45 degrees: the radial path is then more than 1.4x the shortest one).
GRAZING_COS = 0.7
# m: how deep behind its nearest face a point whose ray missed everything may be and still be pushed
# out. Garment points penetrate at most a few mm per step; 3 cm also covers the growth phase.
FALLBACK_DEPTH = 0.03
# m: radial depths up to (this step's motion + TRUST_SLACK) are taken as the paper's answer directly; the
# slack covers rounding and the last push's lambda.
TRUST_SLACK = 0.002
# m: radial depths below this are used as they are (any way out is then within 0.5 mm of the best).
SMALL_DEPTH = 0.0005
# Most ray hits kept per query (a cell's ray crosses a part's surface a handful of times at most).
MAX_HITS = 32
# Part-loop repetitions per point: enough for a point in the overlap of two parts (shoulder, hip).
ROUNDS = 3
# A point pinched between two parts pressed into each other (``collide_points``' hold_depth: a re-posed drape, and
# the shown mesh as it is built, ``full_mesh.PINCHED_LEAST_DEEP``) may also go along the sum of the two pushes'
# normals, in steps of CREASE_STEP m, up to CREASE_STEPS of them (3 cm, the collision's reach), to where it is
# outside both: the crease where their surfaces meet. Cloth squeezed between an arm lowered against the torso was
# held 1 cm inside one of them (the motion stress's long-sleeve S, sequence 11: 11.0 mm, now 3.5); over eight
# sequences of the long-sleeves that missed 10 mm, 11 settles over it -> 3, each where the garment is too small
# for the pose. In the shown meshes, cloth between the large body's thighs goes to the crease too (the trousers M
# there: shown strain 2.14 -> 1.80, self-crossings 158 -> 252).
CREASE_STEP = 0.002
CREASE_STEPS = 15


class BodySurface(NamedTuple):
    """What the collision kernels read of one body surface (the offset one, or the real one for depths),
    passed as one argument. The map arrays are ``tryon.body.maps.PartMaps``' (P parts, C cells), possibly
    moved with a posed arm (``collider.BodyCollider``):
    obb_normals (P, 6, 3), obb_offsets (P, 6): part k's box is ``obb_normals[k] @ p <= obb_offsets[k]``;
    cyl_origin (P, 3), cyl_axes (P, 3, 3) rows local x, y, z; cyl_zrange (P, 2); cyl_shape (P, 2) int64
    (n_theta, n_z); cell_base (P,) int64; cell_start (C + 1,) int64 and cell_faces (K,) int64, the CSR face
    lists of the cells; cell_rmax (C,) m, each cell's largest face radius (``cell_max_radius``);
    vertices (n, 3) m and faces (f, 3) int64 of the surface, face_normals (f, 3) unit outward;
    boxes (f, 4) per-face (theta, z) boxes (``face_boxes``); cover: m, how far beyond its cell a cell's face
    list reaches around this surface (the maps' margin minus the offset, >= 0)."""

    obb_normals: np.ndarray
    obb_offsets: np.ndarray
    cyl_origin: np.ndarray
    cyl_axes: np.ndarray
    cyl_zrange: np.ndarray
    cyl_shape: np.ndarray
    cell_base: np.ndarray
    cell_start: np.ndarray
    cell_faces: np.ndarray
    cell_rmax: np.ndarray
    vertices: np.ndarray
    faces: np.ndarray
    face_normals: np.ndarray
    boxes: np.ndarray
    cover: float


@njit(cache=True, nogil=True)
def vertex_parts(faces, face_part, n_vertices):
    """Part index of every body vertex (the part of the last face using it), (n,) int64."""
    out = np.zeros(n_vertices, dtype=np.int64)
    for f in range(faces.shape[0]):
        for c in range(3):
            out[faces[f, c]] = face_part[f]
    return out


@njit(cache=True, nogil=True)
def offset_body(vertices, vertex_normals, faces, margin, out_vertices, out_normals):
    """Offset vertices (n, 3) = vertices + margin * vertex_normals, and their unit face normals (f, 3),
    written into ``out_vertices`` / ``out_normals``."""
    for i in range(vertices.shape[0]):
        for a in range(3):
            out_vertices[i, a] = vertices[i, a] + margin * vertex_normals[i, a]
    face_normals(out_vertices, faces, out_normals)


@njit(cache=True, nogil=True)
def grow_vertices(vertices, vertex_part, origin, axes, part_scale, out):
    """Body vertices with each part k's distance to its axis scaled by ``part_scale[k]`` (the growth phase;
    ``part_scale`` (P,)).

    The cylinder maps stay valid: theta and z of every vertex are unchanged, only r shrinks.
    """
    for i in range(vertices.shape[0]):
        k = vertex_part[i]
        scale = part_scale[k]
        dx = vertices[i, 0] - origin[k, 0]
        dy = vertices[i, 1] - origin[k, 1]
        dz = vertices[i, 2] - origin[k, 2]
        z = dx * axes[k, 2, 0] + dy * axes[k, 2, 1] + dz * axes[k, 2, 2]
        for a in range(3):
            on_axis = origin[k, a] + z * axes[k, 2, a]
            out[i, a] = on_axis + scale * (vertices[i, a] - on_axis)


@njit(cache=True, nogil=True)
def cell_max_radius(cyl_origin, cyl_axes, cyl_shape, cell_base, cell_start, cell_faces, faces, bv, out):
    """Largest distance to the part axis of any vertex of each cell's faces, (C,) m, into ``out``.

    A point farther from the axis than its cell's radius is outside that part without casting a ray:
    most garment points are outside, so most tests stop there. Each vertex's distance is taken once per
    part (a face is listed in ~8 cells, each vertex in ~6 faces).
    """
    r2 = np.empty(bv.shape[0])
    stamp = np.full(bv.shape[0], -1, dtype=np.int64)
    for k in range(cyl_shape.shape[0]):
        _part_max_radius(k, cyl_origin, cyl_axes, cyl_shape, cell_base, cell_start, cell_faces, faces, bv, out, r2,
                         stamp)


@njit(cache=True, nogil=True)
def part_max_radius(parts, cyl_origin, cyl_axes, cyl_shape, cell_base, cell_start, cell_faces, faces, bv, out):
    """``cell_max_radius`` of the cells of the parts ``parts`` (q,) int64 only (a reshaped limb); the other
    cells of ``out`` are left as they are."""
    r2 = np.empty(bv.shape[0])
    stamp = np.full(bv.shape[0], -1, dtype=np.int64)
    for i in range(parts.shape[0]):
        _part_max_radius(parts[i], cyl_origin, cyl_axes, cyl_shape, cell_base, cell_start, cell_faces, faces, bv,
                         out, r2, stamp)


@njit(cache=True, nogil=True, inline="always")
def _part_max_radius(k, cyl_origin, cyl_axes, cyl_shape, cell_base, cell_start, cell_faces, faces, bv, out, r2,
                     stamp):
    """Part k's cells into ``out``; r2 (n,) holds each vertex's squared radius about part k's axis where
    stamp (n,) is k (taken at its first use)."""
    for c in range(cell_base[k], cell_base[k] + cyl_shape[k, 0] * cyl_shape[k, 1]):
        r_max = 0.0
        for m in range(cell_start[c], cell_start[c + 1]):
            f = cell_faces[m]
            for j in range(3):
                v = faces[f, j]
                if stamp[v] != k:
                    lx, ly, lz = _to_local(bv[v, 0], bv[v, 1], bv[v, 2], cyl_origin, cyl_axes, k)
                    r2[v] = lx * lx + ly * ly
                    stamp[v] = k
                r = r2[v]
                if r > r_max:
                    r_max = r
        out[c] = math.sqrt(r_max)


@njit(cache=True, nogil=True)
def face_boxes(bv, faces, face_part, vertex_part, cyl_origin, cyl_axes, corners, out):
    """Each face's extent in its part's cylinder coordinates, (f, 4): z min, z max, theta min, theta max
    (radians, theta max may exceed pi for a face across the theta = +-pi seam; -inf, inf for a face around
    the axis, such as an end cap), into ``out``.

    The ray of a query keeps its point's (theta, z), and a flat triangle that does not surround the axis
    spans no more than its corners' theta and z, so a face whose box does not contain the ray's (theta, z)
    cannot be hit: most of a cell's ~50 faces (its list is grown by the maps' margin) are skipped with
    two comparisons instead of a plane intersection and an inside-triangle test.

    Each vertex's (z, theta, squared radius) in the frame of its part ``vertex_part`` (n,) is computed
    once into ``corners`` (n, 3) and shared by its ~6 faces (a corner of a face of another part is
    computed again in that part's frame; the built bodies' parts share no vertex): a sixth of the
    arctangents, the same boxes, ~1.25 -> ~0.4 ms on a 10,172-vertex body (the growth phase and the arm
    turns recompute the boxes every step).
    """
    for v in range(bv.shape[0]):
        lx, ly, lz = _to_local(bv[v, 0], bv[v, 1], bv[v, 2], cyl_origin, cyl_axes, vertex_part[v])
        corners[v, 0] = lz
        corners[v, 1] = math.atan2(ly, lx)
        corners[v, 2] = lx * lx + ly * ly
    for f in range(faces.shape[0]):
        k = face_part[f]
        zmin = np.inf
        zmax = -np.inf
        t0 = 0.0
        t1 = 0.0
        t2 = 0.0
        around = False
        for c in range(3):
            v = faces[f, c]
            if vertex_part[v] == k:
                lz = corners[v, 0]
                t = corners[v, 1]
                r2 = corners[v, 2]
            else:
                lx, ly, lz = _to_local(bv[v, 0], bv[v, 1], bv[v, 2], cyl_origin, cyl_axes, k)
                t = math.atan2(ly, lx)
                r2 = lx * lx + ly * ly
            zmin = min(zmin, lz)
            zmax = max(zmax, lz)
            if r2 < 1e-12:
                around = True
            if c == 0:
                t0 = t
            elif c == 1:
                t1 = t
            else:
                t2 = t
        lo = min(t0, min(t1, t2))
        hi = max(t0, max(t1, t2))
        if hi - lo > math.pi:
            # across the seam: shift the negative angles by a full turn
            if t0 < 0.0:
                t0 += 2.0 * math.pi
            if t1 < 0.0:
                t1 += 2.0 * math.pi
            if t2 < 0.0:
                t2 += 2.0 * math.pi
            lo = min(t0, min(t1, t2))
            hi = max(t0, max(t1, t2))
            if hi - lo > math.pi:
                around = True
        eps = 1e-7
        out[f, 0] = zmin - eps
        out[f, 1] = zmax + eps
        if around:
            out[f, 2] = -np.inf
            out[f, 3] = np.inf
        else:
            out[f, 2] = lo - eps
            out[f, 3] = hi + eps


@njit(cache=True, nogil=True, inline="always")
def _to_local(px, py, pz, cyl_origin, cyl_axes, k):
    """A point in part k's cylinder frame: (x, y, z) local, m (z along the part's axis)."""
    dx = px - cyl_origin[k, 0]
    dy = py - cyl_origin[k, 1]
    dz = pz - cyl_origin[k, 2]
    return (dx * cyl_axes[k, 0, 0] + dy * cyl_axes[k, 0, 1] + dz * cyl_axes[k, 0, 2],
            dx * cyl_axes[k, 1, 0] + dy * cyl_axes[k, 1, 1] + dz * cyl_axes[k, 1, 2],
            dx * cyl_axes[k, 2, 0] + dy * cyl_axes[k, 2, 1] + dz * cyl_axes[k, 2, 2])


@njit(cache=True, nogil=True, inline="always")
def _in_obb(px, py, pz, normals, offsets, k):
    for j in range(6):
        if normals[k, j, 0] * px + normals[k, j, 1] * py + normals[k, j, 2] * pz > offsets[k, j]:
            return False
    return True


@njit(cache=True, nogil=True, _nrt=False)
def _nearest_face(p, k, it, iz, n_theta, n_z, cell_base, cell_start, cell_faces, bv, faces, q_out, reach=1):
    """Nearest face of part k's offset surface to p among the cells around (it, iz): the
    (2 reach + 1)^2 block (reach 0: the cell itself). Returns (face id or -1, squared distance); the
    closest point goes into ``q_out``."""
    best = np.inf
    best_f = -1
    for dt in range(-reach, reach + 1):
        jt = (it + dt) % n_theta
        for dz in range(-reach, reach + 1):
            jz = iz + dz
            if jz < 0 or jz >= n_z:
                continue
            c = cell_base[k] + jt * n_z + jz
            for m in range(cell_start[c], cell_start[c + 1]):
                f = cell_faces[m]
                a = faces[f, 0]
                b = faces[f, 1]
                c3 = faces[f, 2]
                d, qx, qy, qz = closest_on_triangle(p[0], p[1], p[2], bv[a, 0], bv[a, 1], bv[a, 2], bv[b, 0],
                                                     bv[b, 1], bv[b, 2], bv[c3, 0], bv[c3, 1], bv[c3, 2])
                if d < best:
                    best = d
                    best_f = f
                    q_out[0] = qx
                    q_out[1] = qy
                    q_out[2] = qz
    return best_f, best


@njit(cache=True, nogil=True, inline="always")
def _axial_inside(p, k, lz, it, iz, n_z, z0, z1, cyl_axes, cell_base, cell_start, cell_faces, bv, faces, fn):
    """Whether p is inside part k by the parity of a ray from p along the part's axis, towards the nearer end of
    its map: every face that ray can cross is listed in p's column of cells (moving along the axis keeps the
    angle), a crossing counted in the cell its height falls in (a face is listed in several). For points whose
    radial ray from the axis misses the part (beyond a turned hand's fingertips, where the axis leaves the
    forearm): the nearest face's side, taken before, called points 5-14 mm outside inside."""
    up = lz >= 0.5 * (z0 + z1)
    sign = 1.0 if up else -1.0
    dx = sign * cyl_axes[k, 2, 0]
    dy = sign * cyl_axes[k, 2, 1]
    dz = sign * cyl_axes[k, 2, 2]
    cell_h = (z1 - z0) / n_z
    count = 0
    jz = iz
    while 0 <= jz < n_z:
        c = cell_base[k] + it * n_z + jz
        lo = z0 + jz * cell_h
        hi = lo + cell_h
        for m in range(cell_start[c], cell_start[c + 1]):
            f = cell_faces[m]
            a = faces[f, 0]
            den = fn[f, 0] * dx + fn[f, 1] * dy + fn[f, 2] * dz
            if abs(den) < 1e-12:
                continue
            t = (fn[f, 0] * (bv[a, 0] - p[0]) + fn[f, 1] * (bv[a, 1] - p[1]) + fn[f, 2] * (bv[a, 2] - p[2])) / den
            if t <= 0.0:
                continue
            hz = lz + sign * t  # the crossing's height along the axis
            if hz < lo or hz >= hi:
                continue  # counted in the cell it falls in
            b = faces[f, 1]
            c3 = faces[f, 2]
            if inside_triangle_xyz(p[0] + t * dx, p[1] + t * dy, p[2] + t * dz, bv[a, 0], bv[a, 1], bv[a, 2],
                                   bv[b, 0], bv[b, 1], bv[b, 2], bv[c3, 0], bv[c3, 1], bv[c3, 2]):
                count += 1
        jz += 1 if up else -1
    return count % 2 == 1


# The collision's per-query functions are compiled without the numba runtime (``_nrt=False``): they
# allocate nothing, and with it every call began by taking an atomic reference on each of its ~20 array
# arguments and dropped them on every return (numba keeps those pairs where a function has many exits;
# inlined, the same happened per query). Those atomics were a third of the collision's time (perf
# sampling); without them a collision of the perf T-shirt's 2,202 points costs 1.0-1.4 instead of
# 1.4-1.7 ms, same results. (Inlined, as before, the call with ~25 array arguments is saved but not the
# atomics.) Its steps below (``_locate`` to ``_missed_ray``) are inlined into it (``inline="always"``), so
# they run without the runtime too and cost no call.
@njit(cache=True, nogil=True, _nrt=False)
def part_query(p, k, surface, target, normal, hit, q, trust, near, tbuf, fbuf):
    """Is p (inside part k's OBB: the callers test that first) inside part k of the (offset) body
    ``surface`` (a ``BodySurface``)?

    Returns the depth (m, > 0 inside, 0 outside); when inside, ``target`` gets the surface point p must
    move to (before adding lambda * normal) and ``normal`` the outward unit normal there.
    hit, q: (3,) float64, tbuf (h,) float64, fbuf (h,) int64: work space (no allocation per query).
    trust: m, the deepest radial answer taken without a second opinion. A point cannot have gone deeper
    in one step than it moved, so a deeper radial depth means it came in through another surface (the
    end of a part, the top of a shoulder, where the ray runs along the surface): then the nearest face
    of the cell (or of the 3 x 3 block) gives the way out if it is shorter.
    near: m; a point outside but closer than this to the surface along its ray gets a negative depth
    (minus its distance) and the surface point and normal, for a contact plane. Faces whose box
    (``surface.boxes``) misses the ray are not intersected.

    Steps: the point's cell (``_locate``), the radial ray through it (``_radial_ray``), the ray's hits
    among the cell's faces (``_ray_hits``), their parity (``_crossings``); then the answer: outside, maybe
    near (``_near_plane``), inside (``_way_out``), or, when the ray hit nothing, the fallback (``_missed_ray``).
    """
    lz, r, theta, it, iz, c = _locate(p, k, surface, near)
    if c < 0:
        return 0.0
    ray = _radial_ray(p, k, lz, r, surface.cyl_origin, surface.cyl_axes)
    nh = _ray_hits(c, lz, theta, ray, surface, hit, tbuf, fbuf)
    if nh == 0:
        return _missed_ray(p, k, lz, it, iz, surface, target, normal, q)
    count, best_t, best_f, below_t, below_f = _crossings(tbuf, fbuf, nh, r)
    if count % 2 == 0:
        return _near_plane(r, below_t, below_f, ray, surface.face_normals, near, target, normal)
    return _way_out(p, k, it, iz, r, best_t, best_f, ray, surface, target, normal, q, trust)


@njit(cache=True, nogil=True, inline="always")
def _locate(p, k, surface, near):
    """Where p (3,) m falls in part k's cylinder map: (lz m along the axis, r m from it, theta in [-pi, pi]
    radians (0 on the axis: the ray then goes along local x), it and iz its cell's theta and z indices, c the
    cell's global id). c is -1 where p is outside the part without a ray: beyond the map's ends, or farther
    from the axis than every face of its cell by more than ``near`` m (most garment points stop there)."""
    cyl_shape, cyl_zrange = surface.cyl_shape, surface.cyl_zrange
    lx, ly, lz = _to_local(p[0], p[1], p[2], surface.cyl_origin, surface.cyl_axes, k)
    n_theta = cyl_shape[k, 0]
    n_z = cyl_shape[k, 1]
    z0 = cyl_zrange[k, 0]
    z1 = cyl_zrange[k, 1]
    if lz < z0 or lz > z1:
        return lz, 0.0, 0.0, 0, 0, -1
    iz = min(int((lz - z0) / (z1 - z0) * n_z), n_z - 1)
    r = math.sqrt(lx * lx + ly * ly)
    theta = math.atan2(ly, lx) if r > 1e-9 else 0.0  # on the axis: cast along local x (theta = 0)
    it = min(int((theta + math.pi) / (2.0 * math.pi) * n_theta), n_theta - 1)
    c = surface.cell_base[k] + it * n_z + iz
    if r > surface.cell_rmax[c] + near:
        return lz, r, theta, it, iz, -1  # beyond every face of the cell: outside this part
    return lz, r, theta, it, iz, c


@njit(cache=True, nogil=True, inline="always")
def _radial_ray(p, k, lz, r, cyl_origin, cyl_axes):
    """The ray of p's query, (ox, oy, oz, rx, ry, rz): its origin o, m, p's projection on part k's axis (lz m
    along it), and its unit direction from o through p (r m away; on the axis, the part's local x). It
    keeps p's theta and z, so it can only hit the triangles of p's cell."""
    ox = cyl_origin[k, 0] + lz * cyl_axes[k, 2, 0]
    oy = cyl_origin[k, 1] + lz * cyl_axes[k, 2, 1]
    oz = cyl_origin[k, 2] + lz * cyl_axes[k, 2, 2]
    if r > 1e-9:
        rx = (p[0] - ox) / r
        ry = (p[1] - oy) / r
        rz = (p[2] - oz) / r
    else:
        rx = cyl_axes[k, 0, 0]
        ry = cyl_axes[k, 0, 1]
        rz = cyl_axes[k, 0, 2]
    return ox, oy, oz, rx, ry, rz


@njit(cache=True, nogil=True, inline="always")
def _ray_hits(c, lz, theta, ray, surface, hit, tbuf, fbuf):
    """The ray ``ray`` (``_radial_ray``) against the faces of cell c: plane hit, then the inside-triangle test.
    Returns nh, the number of hits kept (at most len(tbuf)): tbuf[:nh] their distances from the ray's origin, m,
    fbuf[:nh] their faces. A face whose (theta, z) box misses the ray's (theta, lz) is skipped (two
    comparisons). hit (3,): work space."""
    ox, oy, oz, rx, ry, rz = ray
    cell_start, cell_faces = surface.cell_start, surface.cell_faces
    bv, faces, fn, fbox = surface.vertices, surface.faces, surface.face_normals, surface.boxes
    nh = 0
    theta_up = theta + 2.0 * math.pi
    for m in range(cell_start[c], cell_start[c + 1]):
        f = cell_faces[m]
        if lz < fbox[f, 0] or lz > fbox[f, 1]:
            continue
        if not ((theta >= fbox[f, 2] and theta <= fbox[f, 3]) or (theta_up >= fbox[f, 2] and theta_up <= fbox[f, 3])):
            continue
        a = faces[f, 0]
        den = fn[f, 0] * rx + fn[f, 1] * ry + fn[f, 2] * rz
        if abs(den) < 1e-12:
            continue
        t = (fn[f, 0] * (bv[a, 0] - ox) + fn[f, 1] * (bv[a, 1] - oy) + fn[f, 2] * (bv[a, 2] - oz)) / den
        if t <= 0.0 or nh >= tbuf.shape[0]:
            continue
        hit[0] = ox + t * rx
        hit[1] = oy + t * ry
        hit[2] = oz + t * rz
        b = faces[f, 1]
        c3 = faces[f, 2]
        if inside_triangle_xyz(hit[0], hit[1], hit[2], bv[a, 0], bv[a, 1], bv[a, 2], bv[b, 0], bv[b, 1], bv[b, 2],
                               bv[c3, 0], bv[c3, 1], bv[c3, 2]):
            tbuf[nh] = t
            fbuf[nh] = f
            nh += 1
    return nh


@njit(cache=True, nogil=True, inline="always")
def _crossings(tbuf, fbuf, nh, r):
    """The hits tbuf[:nh] (m from the axis, faces fbuf[:nh]) of a point r m from the axis, counted: (count, best_t,
    best_f, below_t, below_f). count: the crossings beyond the point, the point inside iff it is odd; best_t,
    best_f: the first of them (the way out; inf, -1 if none); below_t, below_f: the last hit short of the point
    (-inf, -1 if none). Hits through a shared edge or vertex, found in two or more triangles at the same t,
    count once. (Taking simply the farthest hit would call a point in a hollow of the surface, such as the
    small of the back, inside.)"""
    count = 0
    best_t = np.inf
    best_f = -1
    below_t = -np.inf
    below_f = -1
    for h in range(nh):
        t = tbuf[h]
        dup = False
        for g in range(h):
            if abs(tbuf[g] - t) <= 1e-9 + 1e-9 * t:
                dup = True
                break
        if dup:
            continue
        if t > r:
            count += 1
            if t < best_t:
                best_t = t
                best_f = fbuf[h]
        elif t > below_t:
            below_t = t
            below_f = fbuf[h]
    return count, best_t, best_f, below_t, below_f


@njit(cache=True, nogil=True, inline="always")
def _near_plane(r, below_t, below_f, ray, fn, near, target, normal):
    """A point outside (r m from the axis, the last hit short of it at below_t m, face below_f): if it is within
    ``near`` m of that surface, the surface point into ``target`` (3,) and its face's normal (``fn`` (f, 3)) into
    ``normal`` (3,), for a contact plane, and minus its distance (m); else 0."""
    if below_f >= 0 and r - below_t < near:
        ox, oy, oz, rx, ry, rz = ray
        target[0] = ox + below_t * rx
        target[1] = oy + below_t * ry
        target[2] = oz + below_t * rz
        for ax in range(3):
            normal[ax] = fn[below_f, ax]
        return below_t - r
    return 0.0


@njit(cache=True, nogil=True, inline="always")
def _way_out(p, k, it, iz, r, best_t, best_f, ray, surface, target, normal, q, trust):
    """A point inside part k (r m from the axis, in cell (it, iz)), its ray leaving the surface at best_t m
    through face best_f: its depth, m, the point to move it to into ``target`` (3,) and the outward normal
    there into ``normal`` (3,). The paper's answer (the ray's exit) where it is shallow (``SMALL_DEPTH``), or
    not grazing (``GRAZING_COS``) and within ``trust`` m; else the nearest face if that is nearer: near the
    end of a part (a shoulder top, the rim of a cap) the radial way out is long and sideways while the real
    one is short. The cell's own faces cover everything within ``surface.cover`` of it; only when the nearest
    of them is farther than that are the 3 x 3 neighbouring cells searched. q (3,): work space."""
    ox, oy, oz, rx, ry, rz = ray
    fn = surface.face_normals
    ray_depth = best_t - r
    target[0] = ox + best_t * rx
    target[1] = oy + best_t * ry
    target[2] = oz + best_t * rz
    for ax in range(3):
        normal[ax] = fn[best_f, ax]
    cos = fn[best_f, 0] * rx + fn[best_f, 1] * ry + fn[best_f, 2] * rz
    if ray_depth <= SMALL_DEPTH or (cos >= GRAZING_COS and ray_depth <= trust):
        return ray_depth  # the paper's answer
    n_theta, n_z, cover = surface.cyl_shape[k, 0], surface.cyl_shape[k, 1], surface.cover
    f, d2 = _nearest_face(p, k, it, iz, n_theta, n_z, surface.cell_base, surface.cell_start, surface.cell_faces,
                          surface.vertices, surface.faces, q, 0)
    if f < 0 or d2 > cover * cover:
        f, d2 = _nearest_face(p, k, it, iz, n_theta, n_z, surface.cell_base, surface.cell_start, surface.cell_faces,
                              surface.vertices, surface.faces, q, 1)
    depth = math.sqrt(d2)
    if f >= 0 and depth < ray_depth:
        for ax in range(3):
            target[ax] = q[ax]
            normal[ax] = fn[f, ax]
        return depth
    return ray_depth


@njit(cache=True, nogil=True, inline="always")
def _missed_ray(p, k, lz, it, iz, surface, target, normal, q):
    """A point whose ray missed every face of its cell (it, iz) of part k (the part's open end at the armpit or
    crotch, overlaps): inside iff its nearest face of the 3 x 3 cells is within ``FALLBACK_DEPTH`` and a ray
    along the axis says so (``_axial_inside``); then that face's closest point into ``target`` (3,), its normal
    into ``normal`` (3,), and its distance, m; else 0. lz: m along the axis; q (3,): work space."""
    n_theta, n_z = surface.cyl_shape[k, 0], surface.cyl_shape[k, 1]
    cell_base, cell_start, cell_faces = surface.cell_base, surface.cell_start, surface.cell_faces
    bv, faces, fn = surface.vertices, surface.faces, surface.face_normals
    f, d2 = _nearest_face(p, k, it, iz, n_theta, n_z, cell_base, cell_start, cell_faces, bv, faces, q)
    if f < 0 or d2 > FALLBACK_DEPTH * FALLBACK_DEPTH:
        return 0.0
    if not _axial_inside(p, k, lz, it, iz, n_z, surface.cyl_zrange[k, 0], surface.cyl_zrange[k, 1],
                         surface.cyl_axes, cell_base, cell_start, cell_faces, bv, faces, fn):
        return 0.0
    for ax in range(3):
        target[ax] = q[ax]
        normal[ax] = fn[f, ax]
    return math.sqrt(d2)


@njit(cache=True, nogil=True)
def _depth_at(p, parts, surface, scratch, tbuf, fbuf):
    """Depth (m) of the point p (3,) in the deepest of ``parts`` (q,) of the body ``surface`` (``part_query``
    with the nearest-face second opinion), 0 outside every one. scratch (4, 3): work space."""
    worst = 0.0
    for kk in range(parts.shape[0]):
        k = parts[kk]
        if _in_obb(p[0], p[1], p[2], surface.obb_normals, surface.obb_offsets, k):
            worst = max(worst, part_query(p, k, surface, scratch[0], scratch[1], scratch[2], scratch[3], 0.0, 0.0,
                                          tbuf, fbuf))
    return worst


@njit(cache=True, nogil=True)
def collide_points(x, x_prev, inv_mass, active, parts, surface, lam, mu_static, mu_kinetic, contact, near, has_plane,
                   plane_point, plane_normal, hold_pinched=False, held=None, hold_depth=1e9):
    """Push garment points out of the offset body, in place (paper 3.4, eq. 4 plus the fallbacks above).

    x, x_prev (k, 3) m (x_prev: positions at the start of the step; both updated in place); inv_mass (k,)
    (0 = pinned, skipped); active (k,) bool: points to test (the caller skips points at rest); parts (q,)
    int64 part ids to test; surface: the offset body (``BodySurface``);
    lam m (eq. 4's lambda); mu_static, mu_kinetic: Coulomb friction coefficients (position-based,
    ``_friction``); the normal velocity is removed (inelastic contact).
    contact (k,) bool out: whether each point was moved. Returns the number of points moved.
    near: m; has_plane (k,) bool, plane_point (k, 3), plane_normal (k, 3) out: the contact plane of each
    tested point that was pushed or lies within ``near`` of the surface (its last surface point plus
    lambda, and normal), for ``constraints.solve_constraints``; untested points keep theirs (and their
    contact flag).
    hold_pinched: a point pushed out of one part into another in every round (``ROUNDS``) stays where it
    was at the start of the step (only while the body does not move: a growing body would grow into it);
    held (k,) bool out, if given: which tested points were held so (the step loop tests them again at its
    next step, the relaxation keeps them still). hold_depth: m, given (under 1e8) a pinched point ends where the
    rounds' pushes left it least deep instead (``_least_deep``).

    Each point: pushed out of the parts round after round (``_push_out``); if still inside, put where it is
    least deep (``_least_deep``) or held (``_hold``); else, if pushed, its motion's friction (``_friction``).
    One point at a time, each writing only its own row: safe to split the loop across threads.
    """
    # work space: part_query's (target, normal, hit, q, tbuf, fbuf), the point before its pushes (x0), where
    # each push of its rounds left it and the push's normal (cand, cand_n), _least_deep's (best: the place
    # found and its normal; mid, crease, scratch)
    n_cand = ROUNDS * parts.shape[0]
    work = (np.empty(3), np.empty(3), np.empty(3), np.empty(3), np.empty(MAX_HITS), np.empty(MAX_HITS, dtype=np.int64),
            np.empty(3), np.empty((n_cand, 3)), np.empty((n_cand, 3)), np.empty((2, 3)), np.empty(3), np.empty(3),
            np.empty((4, 3)))
    return _collide_each(x, x_prev, inv_mass, active, parts, surface, lam, mu_static, mu_kinetic, contact, near,
                         has_plane, plane_point, plane_normal, hold_pinched, held, hold_depth, work)


# collide_points' loop is compiled without the numba runtime, as part_query is (see the note above it): its
# steps are inlined into it at no cost. Inlined into collide_points itself, which allocates and so runs with the
# runtime, each step's ~20 array arguments took and dropped an atomic reference for every point (the perf
# T-shirt's shown mesh, 7,342 points, one thread, best of 10: 3.6 -> 18.8 ms a collision); called instead of
# inlined (without the runtime), the steps' calls made it 5.5 ms.
@njit(cache=True, nogil=True, _nrt=False)
def _collide_each(x, x_prev, inv_mass, active, parts, surface, lam, mu_static, mu_kinetic, contact, near, has_plane,
                  plane_point, plane_normal, hold_pinched, held, hold_depth, work):
    """``collide_points``' loop over the points (the same arguments; ``work``: its work space, a tuple of
    arrays). Returns the number of points moved."""
    target, normal, hit, q, tbuf, fbuf, x0, cand, cand_n, best, mid, crease, scratch = work
    moved = 0
    for i in range(x.shape[0]):
        if inv_mass[i] == 0.0 or not active[i]:
            continue
        contact[i] = False
        has_plane[i] = False
        if held is not None:
            held[i] = False
        p = x[i]
        x0[0] = p[0]
        x0[1] = p[1]
        x0[2] = p[2]
        any_inside, n_cand = _push_out(i, p, x_prev, parts, surface, lam, near, contact, has_plane, plane_point,
                                       plane_normal, cand, cand_n, target, normal, hit, q, tbuf, fbuf)
        if any_inside and hold_depth < 1e8 and n_cand > 0 and _least_deep(
                i, x_prev, parts, surface, cand, cand_n, n_cand, hold_pinched, hold_depth, best, mid, crease, scratch,
                tbuf, fbuf):
            for ax in range(3):
                p[ax] = best[0, ax]
                x_prev[i, ax] = p[ax]  # no velocity from the move
                plane_point[i, ax] = p[ax]
                plane_normal[i, ax] = best[1, ax]
            has_plane[i] = True
            moved += 1
            continue
        if any_inside and hold_pinched:
            _hold(i, p, x_prev, has_plane)
            if held is not None:
                held[i] = True
            moved += 1
            continue
        if contact[i]:
            moved += 1
            _friction(i, p, x0, x_prev, normal, mu_static, mu_kinetic)
    return moved


@njit(cache=True, nogil=True, inline="always")
def _push_out(i, p, x_prev, parts, surface, lam, near, contact, has_plane, plane_point, plane_normal, cand, cand_n,
              target, normal, hit, q, tbuf, fbuf):
    """Point i at p (3,) m (a row of x, moved in place) pushed out of every part of ``parts`` (q,) whose box it
    is in, to the surface point plus ``lam`` m along its normal (eq. 4), repeated (up to ``ROUNDS``) while a
    round pushed it: it leaves the union of overlapping parts. Each push is also point i's contact plane
    (``plane_point``, ``plane_normal`` (k, 3), ``has_plane`` (k,)) and ``contact[i]`` is set; without a push,
    the first surface within ``near`` m gives the plane. Returns (whether the last round still pushed it, the
    number of pushes): cand, cand_n (ROUNDS * q, 3) get where each push left the point and its normal.
    x_prev (k, 3) m: the start of the step (each query trusts a radial depth up to the move since then plus
    ``TRUST_SLACK``); target, normal, hit, q (3,), tbuf, fbuf: ``part_query``'s work space (``normal`` keeps
    the last normal found, which ``_friction`` reads)."""
    n_cand = 0
    any_inside = False
    for _ in range(ROUNDS):
        any_inside = False
        for kk in range(parts.shape[0]):
            k = parts[kk]
            # the box test inline: a call with ~20 array arguments costs more than the test itself
            if not _in_obb(p[0], p[1], p[2], surface.obb_normals, surface.obb_offsets, k):
                continue
            mx = p[0] - x_prev[i, 0]
            my = p[1] - x_prev[i, 1]
            mz = p[2] - x_prev[i, 2]
            trust = math.sqrt(mx * mx + my * my + mz * mz) + TRUST_SLACK
            depth = part_query(p, k, surface, target, normal, hit, q, trust, near, tbuf, fbuf)
            if depth < 0.0:
                if not has_plane[i]:
                    has_plane[i] = True
                    for ax in range(3):
                        plane_point[i, ax] = target[ax] + lam * normal[ax]
                        plane_normal[i, ax] = normal[ax]
                continue
            if depth > 0.0:
                any_inside = True
                contact[i] = True
                has_plane[i] = True
                for ax in range(3):
                    p[ax] = target[ax] + lam * normal[ax]
                    plane_point[i, ax] = p[ax]
                    plane_normal[i, ax] = normal[ax]
                    cand[n_cand, ax] = p[ax]
                    cand_n[n_cand, ax] = normal[ax]
                n_cand += 1
        if not any_inside:
            break
    return any_inside, n_cand


@njit(cache=True, nogil=True, inline="always")
def _least_deep(i, x_prev, parts, surface, cand, cand_n, n_cand, hold_pinched, hold_depth, best, mid, crease,
                scratch, tbuf, fbuf):
    """Where point i, still inside after its rounds (``_push_out``), is least deep in the body ``surface`` over
    ``parts`` (q,): best (2, 3) gets that point, m, and the normal of its push; returns whether one was found
    (else it is held or left as the caller decides). Held (``hold_pinched``), it is found only if where it was
    at the start of the step (x_prev (k, 3) m) is deeper than ``hold_depth`` m, and must be less deep than that.

    The places: each push (cand, cand_n (n_cand, 3): where it left the point, its normal), the middle of two
    pushes in a row, and, for two pushes in a row out of two different parts, the crease (``_crease``). Where
    the last push leaves it is inside the other part, and a re-posed body's cloth squeezed between a forearm
    and the torso where they press into each other was left 1-2 cm inside one of them. Between two parts
    pressed together the middle is as deep in each, where either push leaves it as deep in the other as the
    overlap and the offset together (``full_mesh.PINCHED_LEAST_DEEP``: the shown mesh of a long sleeve on a
    forearm resting on the belly ended 3.2 mm inside the torso, now 0); where two parts overlap, every push
    and middle stays as deep as half the overlap, and the way out is along the crease.
    mid, crease (3,), scratch (4, 3), tbuf, fbuf: work space."""
    found, best_depth = False, _depth_at(x_prev[i], parts, surface, scratch, tbuf, fbuf) if hold_pinched \
        else np.inf
    if not best_depth > hold_depth:
        return False
    for c in range(2 * n_cand - 1):
        a, b = c // 2, (c + 1) // 2  # a push (a == b), or the middle of two in a row
        for ax in range(3):
            mid[ax] = 0.5 * (cand[a, ax] + cand[b, ax])
        depth = _depth_at(mid, parts, surface, scratch, tbuf, fbuf)
        if depth < best_depth:
            found, best_depth = True, depth
            for ax in range(3):
                best[0, ax] = mid[ax]
                best[1, ax] = cand_n[b, ax]
        if a != b and depth > 0.0:
            cdepth, sn = _crease(mid, cand_n, a, b, parts, surface, crease, scratch, tbuf, fbuf)
            if sn > 1e-6 and cdepth < best_depth:
                found, best_depth = True, cdepth
                for ax in range(3):
                    best[0, ax] = crease[ax]
                    best[1, ax] = (cand_n[a, ax] + cand_n[b, ax]) / sn
    return found


@njit(cache=True, nogil=True, inline="always")
def _crease(mid, cand_n, a, b, parts, surface, crease, scratch, tbuf, fbuf):
    """Two parts pressed into each other (an arm lowered against the torso): their pushes a and b (normals
    cand_n[a], cand_n[b]) go opposite ways, and the sum of their normals points along the overlap to the nearer
    crease where the two surfaces meet, outside both. From mid (3,) m along that sum, in steps of
    ``CREASE_STEP`` m up to ``CREASE_STEPS``, to the first point outside both (or the last step) into
    ``crease`` (3,): (its depth, m, in the body ``surface`` over ``parts``; the sum's length, its depth not
    looked for where that is under 1e-6)."""
    sx = cand_n[a, 0] + cand_n[b, 0]
    sy = cand_n[a, 1] + cand_n[b, 1]
    sz = cand_n[a, 2] + cand_n[b, 2]
    sn = math.sqrt(sx * sx + sy * sy + sz * sz)
    cdepth = 0.0
    if sn > 1e-6:
        for m in range(1, CREASE_STEPS + 1):
            t = m * CREASE_STEP / sn
            crease[0] = mid[0] + t * sx
            crease[1] = mid[1] + t * sy
            crease[2] = mid[2] + t * sz
            cdepth = _depth_at(crease, parts, surface, scratch, tbuf, fbuf)
            if cdepth == 0.0:
                break
    return cdepth, sn


@njit(cache=True, nogil=True, inline="always")
def _hold(i, p, x_prev, has_plane):
    """Point i pinched: pushed out of one part into another in every round (cloth between touching thighs, in
    the crotch), no way out nearby. Pushed on, it flips between the parts every step (2-3 cm on a heavy-thighed
    body) and never comes to rest. It keeps its place at the start of the step instead, at rest (cloth squeezed
    between two parts is held there): outside the body if it was about to enter the pinch, where it was if it
    started in it. p (3,) m: its row of x, set to x_prev[i] ((k, 3) m); has_plane (k,) bool: its plane dropped."""
    for ax in range(3):
        p[ax] = x_prev[i, ax]
    has_plane[i] = False


@njit(cache=True, nogil=True, inline="always")
def _friction(i, p, x0, x_prev, normal, mu_static, mu_kinetic):
    """The response of point i's motion to its push from x0 (3,) m to p (3,) m (a row of x, in place), x_prev
    (k, 3) m its place at the start of the step (row i updated): the push itself must not become velocity
    (pushing along a ray that is not the surface normal would otherwise feed the cloth tangential speed every
    step). Coulomb friction on positions (Macklin et al. 2014, "Unified particle physics"): the tangential part
    of this step's motion before the push (x0 - x_prev) is undone if shorter than mu_static x the push
    (sticking), else shortened by mu_kinetic x the push (sliding), along the last normal (3,) found; the next
    step starts with what is left of it and no normal velocity (inelastic)."""
    px = p[0] - x0[0]
    py = p[1] - x0[1]
    pz = p[2] - x0[2]
    press = math.sqrt(px * px + py * py + pz * pz)
    cut, tx, ty, tz = coulomb_cut(x0[0] - x_prev[i, 0], x0[1] - x_prev[i, 1], x0[2] - x_prev[i, 2],
                                  normal[0], normal[1], normal[2], press, mu_static, mu_kinetic)
    p[0] -= cut * tx
    p[1] -= cut * ty
    p[2] -= cut * tz
    keep = 1.0 - cut
    x_prev[i, 0] = p[0] - keep * tx
    x_prev[i, 1] = p[1] - keep * ty
    x_prev[i, 2] = p[2] - keep * tz


@njit(cache=True, nogil=True)
def penetration_depth(points, parts, surface):
    """Depth (m) of each point (n, 3) inside the body ``surface`` (a ``BodySurface``; 0 outside), (n,)
    float64: the largest depth over the parts ``parts`` (q,) int64 (the same inside test as the collision,
    with the nearest-surface distance)."""
    obb_normals, obb_offsets, cyl_origin, cyl_axes = surface.obb_normals, surface.obb_offsets, \
        surface.cyl_origin, surface.cyl_axes
    cyl_zrange, cyl_shape, cell_base, cell_start, cell_faces = surface.cyl_zrange, surface.cyl_shape, \
        surface.cell_base, surface.cell_start, surface.cell_faces
    bv, faces = surface.vertices, surface.faces
    out = np.zeros(points.shape[0])
    target = np.empty(3)
    normal = np.empty(3)
    q = np.empty(3)
    hit = np.empty(3)
    query_q = np.empty(3)
    tbuf = np.empty(MAX_HITS)
    fbuf = np.empty(MAX_HITS, dtype=np.int64)
    for i in range(points.shape[0]):
        p = points[i]
        for kk in range(parts.shape[0]):
            k = parts[kk]
            if not _in_obb(p[0], p[1], p[2], obb_normals, obb_offsets, k):
                continue
            d = part_query(p, k, surface, target, normal, hit, query_q, 0.0, 0.0, tbuf, fbuf)
            if d > 0.0:
                # the true depth is the distance to the nearest surface point, never more than the
                # distance to the response point
                n_theta = cyl_shape[k, 0]
                n_z = cyl_shape[k, 1]
                lx, ly, lz = _to_local(p[0], p[1], p[2], cyl_origin, cyl_axes, k)
                z0 = cyl_zrange[k, 0]
                z1 = cyl_zrange[k, 1]
                iz = min(int((lz - z0) / (z1 - z0) * n_z), n_z - 1)
                it = min(int((math.atan2(ly, lx) + math.pi) / (2.0 * math.pi) * n_theta), n_theta - 1)
                f, d2 = _nearest_face(p, k, it, iz, n_theta, n_z, cell_base, cell_start, cell_faces, bv, faces,
                                      q)
                if f >= 0:
                    d = min(d, math.sqrt(d2))
                out[i] = max(out[i], d)
    return out
