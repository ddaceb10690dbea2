"""Small synthetic scenes: a body of capped cylinders and square or tube cloths with simple springs.

They exercise the simulation without the NURBS body or a prepared catalogue garment (tests, the stress
test's quick mode, benchmarks). Same contracts as the real stages: a ``Body`` and a ``GarmentModel``.
"""

from __future__ import annotations

import numpy as np

from tryon.body.maps import build_part_maps
from tryon.body.types import PART_NAMES, Body
from tryon.garment.model import GarmentMeta, GarmentModel
from tryon.garment.springs import BENDING, SHEAR, STRUCTURAL
from tryon.geometry import face_normals, vertex_normals

# Default collision margin of the synthetic bodies' maps, metres (matches SimSettings' default order).
MAP_MARGIN = 0.01


def capped_cylinder(a, b, radius: float, n_around: int = 24, n_along: int = 8):
    """A closed tube from ``a`` to ``b`` (metres) with flat-fan caps. Returns (vertices (n,3), faces (f,3)),
    counter-clockwise seen from outside."""
    a = np.asarray(a, float)
    b = np.asarray(b, float)
    axis = b - a
    length = np.linalg.norm(axis)
    z = axis / length
    ref = np.array([0.0, 0.0, 1.0]) if abs(z[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    x = ref - (ref @ z) * z
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    t = np.linspace(0.0, 1.0, n_along + 1)
    ang = np.linspace(0.0, 2 * np.pi, n_around, endpoint=False)
    ring = radius * (np.cos(ang)[:, None] * x + np.sin(ang)[:, None] * y)  # (m, 3)
    verts = (a + t[:, None, None] * axis + ring[None]).reshape(-1, 3)
    faces = []
    for i in range(n_along):
        for j in range(n_around):
            p = i * n_around + j
            q = i * n_around + (j + 1) % n_around
            faces.append((p, q, q + n_around))
            faces.append((p, q + n_around, p + n_around))
    base = len(verts)
    verts = np.vstack([verts, a, b])
    top = n_along * n_around
    for j in range(n_around):
        jn = (j + 1) % n_around
        faces.append((base, jn, j))  # bottom cap, normal -z
        faces.append((base + 1, top + j, top + jn))  # top cap, normal +z
    return verts, np.asarray(faces, dtype=np.int32)


def body_from_parts(segments, radii, n_around: int = 24, cell_along: float = 0.03, margin: float = MAP_MARGIN) -> Body:
    """A ``Body`` of capped cylinders: ``segments`` (P, 2, 3) axis segments, ``radii`` (P,) metres."""
    vs, fs, fp = [], [], []
    base = 0
    for k, (seg, r) in enumerate(zip(segments, radii)):
        n_along = max(2, int(np.ceil(np.linalg.norm(seg[1] - seg[0]) / cell_along)))
        v, f = capped_cylinder(seg[0], seg[1], r, n_around, n_along)
        vs.append(v)
        fs.append(f + base)
        fp.append(np.full(len(f), k, dtype=np.int16))
        base += len(v)
    vertices = np.vstack(vs)
    faces = np.vstack(fs).astype(np.int32)
    face_part = np.concatenate(fp)
    vn = vertex_normals(vertices, faces)
    fn = np.empty((len(faces), 3))
    face_normals(vertices, np.asarray(faces, dtype=np.int64), fn)
    axes = np.asarray(segments, float)
    return Body(
        vertices=vertices, faces=faces, vertex_normals=vn, face_normals=fn, face_part=face_part,
        parts=PART_NAMES[: len(axes)] if len(axes) <= len(PART_NAMES) else tuple(f"p{k}" for k in range(len(axes))),
        part_axes=axes, maps=build_part_maps(vertices, faces, face_part, axes, margin),
        requested={}, achieved={}, levels={},
    )


def stick_body(scale: float = 1.0, arm_angle_deg: float = 40.0, n_around: int = 24) -> Body:
    """A 1.75 m (x ``scale``) body of ten capped cylinders in the PART_NAMES order, arms abducted by
    ``arm_angle_deg`` from the torso side, facing +z, feet on y = 0."""
    s = scale
    hip_y, neck_y = 0.95 * s, 1.45 * s
    sh_x, sh_y = 0.19 * s, 1.40 * s
    a = np.radians(arm_angle_deg)
    down = np.array([np.sin(a), -np.cos(a), 0.0])
    up_l = 0.30 * s
    lo_l = 0.27 * s
    sh_l = np.array([sh_x, sh_y, 0.0])
    el_l = sh_l + up_l * down
    wr_l = el_l + lo_l * down
    mirror = np.array([-1.0, 1.0, 1.0])
    hip_l = np.array([0.09 * s, hip_y, 0.0])
    knee_l = np.array([0.10 * s, 0.50 * s, 0.0])
    ankle_l = np.array([0.10 * s, 0.06 * s, 0.0])
    segments = np.array([
        [[0, neck_y, 0], [0, 1.75 * s, 0]],
        [[0, hip_y - 0.08 * s, 0], [0, neck_y, 0]],
        [sh_l, el_l], [sh_l * mirror, el_l * mirror],
        [el_l, wr_l], [el_l * mirror, wr_l * mirror],
        [hip_l + [0, 0.05 * s, 0], knee_l], [(hip_l + [0, 0.05 * s, 0]) * mirror, knee_l * mirror],
        [knee_l, ankle_l], [knee_l * mirror, ankle_l * mirror],
    ], dtype=float)
    radii = np.array([0.09, 0.15, 0.05, 0.05, 0.04, 0.04, 0.08, 0.08, 0.055, 0.055]) * s
    return body_from_parts(segments, radii, n_around=n_around)


def _springs_from_grid(index: np.ndarray, closed_u: bool):
    """Structural, shear and bending springs of a grid of vertex ids ``index`` (nv, nu)."""
    nv, nu = index.shape
    springs, kinds = [], []

    def add(a, b, kind):
        springs.append(np.stack([a.ravel(), b.ravel()], axis=1))
        kinds.append(np.full(a.size, kind, dtype=np.int8))

    roll = (lambda arr, s: np.roll(arr, -s, axis=1)) if closed_u else None
    if closed_u:
        add(index, roll(index, 1), STRUCTURAL)
        add(index[:-1], index[1:], STRUCTURAL)
        add(index[:-1], roll(index, 1)[1:], SHEAR)
        add(roll(index, 1)[:-1], index[1:], SHEAR)
        add(index, roll(index, 2), BENDING)
        add(index[:-2], index[2:], BENDING)
    else:
        add(index[:, :-1], index[:, 1:], STRUCTURAL)
        add(index[:-1], index[1:], STRUCTURAL)
        add(index[:-1, :-1], index[1:, 1:], SHEAR)
        add(index[:-1, 1:], index[1:, :-1], SHEAR)
        add(index[:, :-2], index[:, 2:], BENDING)
        add(index[:-2], index[2:], BENDING)
    return np.vstack(springs).astype(np.int32), np.concatenate(kinds)


def _grid_faces(index: np.ndarray, closed_u: bool):
    nv, nu = index.shape
    cols = nu if closed_u else nu - 1
    faces = []
    for i in range(nv - 1):
        for j in range(cols):
            jn = (j + 1) % nu
            a, b, c, d = index[i, j], index[i, jn], index[i + 1, jn], index[i + 1, j]
            faces.append((a, b, c))
            faces.append((a, c, d))
    return np.asarray(faces, dtype=np.int32)


def model_from_grid(vertices, index, closed_u, category="top", density=0.15, name="synthetic") -> GarmentModel:
    """A ``GarmentModel`` whose coarse mesh is the full mesh (B = 1) built on a vertex grid."""
    vertices = np.asarray(vertices, float)
    faces = _grid_faces(index, closed_u)
    springs, kind = _springs_from_grid(index, closed_u)
    rest = np.linalg.norm(vertices[springs[:, 0]] - vertices[springs[:, 1]], axis=1)
    area = 0.5 * np.linalg.norm(
        np.cross(vertices[faces[:, 1]] - vertices[faces[:, 0]], vertices[faces[:, 2]] - vertices[faces[:, 0]]), axis=1
    )
    mass = np.zeros(len(vertices))
    for c in range(3):
        np.add.at(mass, faces[:, c], density * area / 3.0)
    n = len(vertices)
    # Each vertex re-attached to the first face that uses it, at its own corner.
    attach_face = np.zeros(n, dtype=np.int32)
    attach_bary = np.zeros((n, 3))
    for c in (2, 1, 0):
        attach_face[faces[:, c]] = np.arange(len(faces), dtype=np.int32)
    for c in range(3):
        mine = faces[attach_face, c] == np.arange(n)
        attach_bary[mine, c] = 1.0
    counts = {"structural": int((kind == 0).sum()), "shear": int((kind == 1).sum()), "bending": int((kind == 2).sum())}
    meta = GarmentMeta(
        id=name, name=name, category=category, size=None, units="m", units_guessed=False, simplification=1.0,
        source_sha256="", source_name=name, vertices=n, faces=len(faces), coarse_vertices=n,
        coarse_faces=len(faces), springs=counts, notes=[],
    )
    return GarmentModel(
        meta=meta, vertices=vertices, faces=faces, coarse_index=np.arange(n, dtype=np.int32), coarse_faces=faces,
        springs=springs, rest=rest, kind=kind, mass=mass, attach_face=attach_face, attach_bary=attach_bary,
        attach_offset=np.zeros(n),
    )


def cloth_square(size: float = 1.0, n: int = 21, height: float = 1.0, center=(0.0, 0.0)) -> GarmentModel:
    """A horizontal square cloth ``size`` metres wide, n x n vertices, at y = ``height``."""
    u = np.linspace(-size / 2, size / 2, n)
    xx, zz = np.meshgrid(u + center[0], u + center[1])
    vertices = np.stack([xx.ravel(), np.full(n * n, height), zz.ravel()], axis=1)
    return model_from_grid(vertices, np.arange(n * n).reshape(n, n), closed_u=False, name="square")


def cloth_tube(radius: float, y_top: float, y_bottom: float, n_around: int = 32, n_along: int = 20,
               category: str = "bottom") -> GarmentModel:
    """A vertical open tube (a skirt), axis the world y axis."""
    ang = np.linspace(0, 2 * np.pi, n_around, endpoint=False)
    ys = np.linspace(y_top, y_bottom, n_along)
    vertices = np.stack([
        np.tile(radius * np.sin(ang), n_along), np.repeat(ys, n_around), np.tile(radius * np.cos(ang), n_along)
    ], axis=1)
    return model_from_grid(vertices, np.arange(n_along * n_around).reshape(n_along, n_around), closed_u=True,
                           category=category, name="tube")
