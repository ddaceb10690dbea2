"""The catalogue's own garment meshes, built the way 3DMAX-style garment models are (SPEC section 3).

Every garment is a set of quad grids, each quad split into two triangles (v0 v1 v2 with right angles at
v1, so v0v1 and v1v2 are the near right-angle edges and v2v0 the near hypotenuse), glued into one closed
tube topology: a body tube of rings around the torso, sleeve tubes whose first ring is the armhole, leg
tubes that share the crotch point. Openings: neck, hem, cuffs, waist, leg hems.

Placement: as worn by a standing person 1.70 m tall, feet at y = 0, facing +z, left arm towards +x,
arms in an A-pose (``ARM_ANGLE_DEG`` from the torso side). Metres.

Sizes S, M, L, XL, XXL from a standard unisex size chart (body girths, cm) plus each garment's ease; each
kind is a style, and ``catalogue.json`` gives each size's chart row (``chart_row``).

Run ``python3 -m tryon.garment.generate garments/`` to write the OBJ files and ``catalogue.json``.
"""

from __future__ import annotations

import argparse
import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import trimesh

from tryon.garment.fabric import DEFAULT_FABRIC

# Body girths in cm (standard unisex chart: chest, waist, hips, upper arm, wrist, thigh, knee, neck).
SIZE_CHART = {
    "S": dict(chest=88, waist=74, hips=94, upper_arm=28, wrist=16, thigh=54, knee=36, neck=36),
    "M": dict(chest=96, waist=82, hips=100, upper_arm=30, wrist=17, thigh=57, knee=38, neck=38),
    "L": dict(chest=104, waist=90, hips=106, upper_arm=32, wrist=18, thigh=60, knee=40, neck=40),
    "XL": dict(chest=112, waist=98, hips=112, upper_arm=34, wrist=19, thigh=63, knee=42, neck=42),
    "XXL": dict(chest=120, waist=106, hips=118, upper_arm=36, wrist=20, thigh=66, knee=44, neck=44),
}
# Shoulder half-width (acromion to the body's mid-plane), m, per size.
SHOULDER_HALF = {"S": 0.185, "M": 0.195, "L": 0.205, "XL": 0.215, "XXL": 0.225}

# Landmark heights (m) of a 1.70 m standing person (anthropometric ratios of stature: shoulder 0.82,
# armpit 0.72, chest 0.73, waist 0.62, hips 0.53, crotch 0.46, knee 0.28).
Y_NECK_BASE = 1.465  # where the shoulder seam meets the neckline (1.5 cm over the body's 1.45)
Y_SHOULDER = 1.415  # the shoulder point (1.5 cm over the body's acromion)
Y_ARMPIT = 1.21
Y_WAIST = 1.05
Y_HIP = 0.90
Y_CROTCH = 0.78
Y_KNEE = 0.47
Y_ANKLE = 0.08
# Shoulder joint centre (m): where the arm's axis starts (|x|, y), and its depth z.
SHOULDER_JOINT = (0.16, 1.39)
ARM_Z = -0.055
# A sleeve started outside the armpit rejoins the arm's axis within this length along the arm, m.
SLEEVE_RETURN = 0.2
# ... and no steeper than this (m across per m along): a shift of 6.9 cm (the tops' XXL) taken back within 20 cm
# turned the sleeve's first rows into the body tube at the armpit, the cloth through itself
SLEEVE_SLOPE = 0.24
# The body's mid-plane is not z = 0 at every height: the neck and shoulders sit behind the chest, the
# buttocks behind the belly. (y, z of the torso's section centre), m, measured on the service's
# parametric body (tryon.body) of a 1.70 m person; the legs are centred on z = 0.
BODY_CENTRE_Z = ((0.0, 0.0), (0.75, 0.0), (0.80, -0.005), (0.85, -0.025), (0.90, -0.026), (0.95, -0.02),
                 (1.00, -0.012), (1.05, -0.008), (1.10, -0.015), (1.20, -0.021), (1.25, -0.024),
                 (1.30, -0.033), (1.35, -0.049), (1.40, -0.052), (1.47, -0.05))
# The A-pose: arms this many degrees out from the torso's side.
ARM_ANGLE_DEG = 27.0
# Depth / width of the torso's cross-section (a chest is about 0.7 as deep as wide), and the exponent of
# its superellipse |x/a|^p + |z/b|^p = 1: 2.5 is squarer than an ellipse, like a torso's section.
DEPTH_RATIO = 0.72
SECTION_EXPONENT = 2.5
# Target grid spacing, m: about 1.7 cm gives the 2,000-8,000 vertices of a 3DMAX garment.
SPACING = 0.017


def spow(t, p: float = SECTION_EXPONENT):
    """sign(t) |t|^(2/p): cos/sin of a superellipse |x/a|^p + |z/b|^p = 1 (p = 2: an ellipse)."""
    return np.sign(t) * np.abs(t) ** (2.0 / p)


def section_perimeter(a: float, b: float, p: float = SECTION_EXPONENT) -> float:
    """Perimeter (m) of the superellipse with half-axes a, b (polygon of 720 points)."""
    t = np.linspace(0, 2 * np.pi, 721)
    x, z = a * spow(np.cos(t), p), b * spow(np.sin(t), p)
    return float(np.hypot(np.diff(x), np.diff(z)).sum())


def half_axes(girth_m: float, ratio: float = DEPTH_RATIO) -> tuple[float, float]:
    """(half-width, half-depth) of the torso section of the given girth and depth/width ratio."""
    a = girth_m / section_perimeter(1.0, ratio)
    return a, a * ratio


# |x| of the body's leg axes at heights y, m (thigh 0.10 at 0.7 m, knee 0.11, ankle 0.125).
LEG_CENTRE_X = ((0.0, 0.47, 0.70), (0.125, 0.11, 0.10))
# z of the leg axes: the shins lean forward to the ankles (0.04 m ahead at the floor).
LEG_CENTRE_Z = ((0.0, 0.20), (0.04, 0.0))
# m: the least gap between a trouser leg's tube and the body's mid-plane below the crotch (a wide leg of a large
# size would otherwise cross its other leg there, and the cloth would start the drape through itself).
LEG_GAP = 0.001
# Height over the crotch point (m) in which the seat's figure eight opens into the hip ellipse.
SEAT_RISE = 0.10


def centre_z(y):
    """z (m) of the body's mid-plane at height y (``BODY_CENTRE_Z``)."""
    ys, zs = zip(*BODY_CENTRE_Z)
    return np.interp(y, ys, zs)


def smoothstep(t):
    t = np.clip(t, 0.0, 1.0)
    return t * t * (3 - 2 * t)


class MeshBuilder:
    """Vertices and quads (split into two triangles each) of a garment under construction."""

    def __init__(self):
        self.points: list[np.ndarray] = []
        self.count = 0
        self.faces: list[np.ndarray] = []
        self.part_starts: list[int] = [0]

    def new_part(self) -> None:
        """Start a part (a sleeve, a leg) whose winding is matched to the parts before it."""
        self.part_starts.append(len(self.faces))

    def add(self, pts: np.ndarray) -> np.ndarray:
        """Add (m, 3) points, return their ids."""
        pts = np.asarray(pts, dtype=np.float64).reshape(-1, 3)
        ids = np.arange(self.count, self.count + len(pts))
        self.points.append(pts)
        self.count += len(pts)
        return ids

    def strip(self, row_a: np.ndarray, row_b: np.ndarray, closed: bool) -> None:
        """Quads between two rows of equal length: (a_k, a_k+1, b_k+1) and (b_k+1, b_k, a_k)."""
        a0, b0 = row_a, row_b
        a1, b1 = (np.roll(row_a, -1), np.roll(row_b, -1)) if closed else (row_a[1:], row_b[1:])
        if not closed:
            a0, b0 = row_a[:-1], row_b[:-1]
        self.faces.append(np.column_stack([a0, a1, b1]))
        self.faces.append(np.column_stack([b1, b0, a0]))

    def mesh(self) -> trimesh.Trimesh:
        v = np.concatenate(self.points)
        n = len(v)
        parts = []
        seen = np.zeros(0, dtype=np.int64)  # directed edge keys of the parts so far
        bounds = [*self.part_starts, len(self.faces)]
        for s, e in zip(bounds[:-1], bounds[1:]):
            f = np.concatenate(self.faces[s:e])
            f = f[(f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 0] != f[:, 2])]
            keys = (f[:, [0, 1, 2]] * n + f[:, [1, 2, 0]]).ravel()
            if np.isin(keys, seen).any():  # a mirrored part: same directed edge as its neighbour
                f = f[:, ::-1]
                keys = (f[:, [0, 1, 2]] * n + f[:, [1, 2, 0]]).ravel()
            seen = np.concatenate([seen, keys])
            parts.append(f)
        mesh = trimesh.Trimesh(vertices=v, faces=np.concatenate(parts), process=False)
        mesh.remove_unreferenced_vertices()  # the crotch point was added twice, then merged
        # outward: normals point away from the vertical axis through the garment on average
        centre = v.mean(axis=0)
        radial = mesh.triangles_center - centre
        radial[:, 1] = 0.0
        if np.einsum("ij,ij->", mesh.face_normals, radial) < 0:
            mesh.faces = np.fliplr(mesh.faces)
        return mesh


# --- tops and dresses -----------------------------------------------------------------------------


@dataclass
class TopSpec:
    """A top or dress: girths (m, garment = body + ease) at heights (m), sleeves, neckline."""

    girths: list[tuple[float, float]]  # (y, girth) from the hem up to the armpit
    shoulder_half: float
    neck_half: float  # half-width of the neck opening, m
    neck_drop_front: float
    neck_drop_back: float
    neck_depth: float  # half-depth (z) of the neck opening, m
    armhole_angle_deg: float  # how far the armhole cuts into the ring's side, degrees
    sleeve_end: float | None  # distance of the cuff along the arm axis from the shoulder joint, m
    sleeve_top_girth: float = 0.0
    sleeve_end_girth: float = 0.0


def build_top(spec: TopSpec) -> trimesh.Trimesh:
    """Body tube (hem to shoulders) with armholes, neck opening and optional sleeves."""
    mb = MeshBuilder()
    ys, gs = np.array([g[0] for g in spec.girths]), np.array([g[1] for g in spec.girths])
    y_hem, y_arm = ys[0], ys[-1]
    n_half = 2 * int(round(gs.max() / 2 / SPACING / 2))  # columns per half ring (even)
    n_ring = 2 * n_half
    rows_low = max(2, int(round((y_arm - y_hem) / SPACING)))
    rows_high = max(3, int(round((Y_SHOULDER - y_arm) / SPACING)))
    a_arm, b_arm = half_axes(gs[-1])

    # lower body: closed rings from the hem up to the armpit
    rings = []
    theta = np.pi * np.arange(n_ring) / n_half
    for j in range(rows_low + 1):
        y = y_hem + (y_arm - y_hem) * j / rows_low
        a, b = half_axes(np.interp(y, ys, gs))
        rings.append(mb.add(np.column_stack([-a * spow(np.cos(theta)), np.full(n_ring, y),
                                             b * spow(np.sin(theta)) + centre_z(y)])))
    for j in range(rows_low):
        mb.strip(rings[j], rings[j + 1], closed=True)

    # upper body: front and back half rings with the armholes cut out of the sides
    delta_max = math.radians(spec.armhole_angle_deg)
    k = np.arange(n_half + 1) / n_half
    fronts, backs = [], []
    for j in range(1, rows_high + 1):
        u = j / rows_high
        delta = delta_max * math.sin(math.pi * u) ** 0.7
        a = a_arm + (spec.shoulder_half - a_arm) * u
        half = []
        for side in (+1, -1):  # front, back
            th = delta + (np.pi - 2 * delta) * k
            # towards the flat shoulder seam the columns go from even angles to even widths, or the ones
            # near the shoulder point (cos ~ 1) would bunch up there
            w = u ** 4
            x = -a * ((1 - w) * spow(np.cos(th)) + w * (1 - 2 * k))
            y_top = _shoulder_line(x, spec, side)
            y = y_arm + (y_top - y_arm) * u
            z_top = _neck_z(x, spec) * side
            # the depth closes towards the shoulder seam late (1 - u^4): the shoulders are round
            z = side * np.sqrt((b_arm * spow(np.sin(th))) ** 2 * (1 - u ** 4) + (np.abs(z_top) * u * u) ** 2)
            half.append(np.column_stack([x, y, z + centre_z(y)]))
        if j < rows_high:
            front_ids = mb.add(half[0])
            back_ids = mb.add(half[1][::-1])  # back runs from the +x side to the -x side
        else:
            # top row: the shoulder seams are shared by front and back; the neck opening is not
            neck = np.abs(half[0][:, 0]) < spec.neck_half
            front_ids = mb.add(half[0])
            back_pts = half[1][::-1]
            back_ids = np.empty(n_half + 1, dtype=np.int64)
            shared = ~neck[::-1]
            back_ids[shared] = front_ids[::-1][shared]
            back_ids[~shared] = mb.add(back_pts[~shared])
        fronts.append(front_ids)
        backs.append(back_ids)
    armpit = rings[-1]
    prev_front = armpit[: n_half + 1]
    prev_back = np.concatenate([armpit[n_half:], armpit[:1]])
    for front_ids, back_ids in zip(fronts, backs):
        mb.strip(prev_front, front_ids, closed=False)
        mb.strip(prev_back, back_ids, closed=False)
        prev_front, prev_back = front_ids, back_ids

    if spec.sleeve_end is not None:
        for side in (-1, +1):  # person's right (-x), left (+x)
            if side < 0:
                up_front = [f[0] for f in fronts]
                up_back = [b[-1] for b in backs]
                pit = armpit[0]
            else:
                up_front = [f[-1] for f in fronts]
                up_back = [b[0] for b in backs]
                pit = armpit[n_half]
            # armhole loop: armpit, up the front, shoulder point (shared), down the back
            root = np.array([pit, *up_front[:-1], up_front[-1], *up_back[:-1][::-1]])
            mb.new_part()
            _build_sleeve(mb, root, side, spec)
    return mb.mesh()


def _shoulder_line(x: np.ndarray, spec: TopSpec, side: int) -> np.ndarray:
    """Height of the top edge: rises from the shoulder point to the neck base, dips at the neckline."""
    ax = np.abs(x)
    t = np.clip((spec.shoulder_half - ax) / max(spec.shoulder_half - spec.neck_half, 1e-6), 0.0, 1.0)
    y = Y_SHOULDER + (Y_NECK_BASE - Y_SHOULDER) * t
    inside = ax < spec.neck_half
    drop = spec.neck_drop_front if side > 0 else spec.neck_drop_back
    y = np.where(inside, Y_NECK_BASE - drop * np.sqrt(np.clip(1 - (ax / spec.neck_half) ** 2, 0, 1)), y)
    return y


def _neck_z(x: np.ndarray, spec: TopSpec) -> np.ndarray:
    """Half-depth of the neck opening at x (0 on the shoulder seams)."""
    return spec.neck_depth * np.sqrt(np.clip(1 - (x / spec.neck_half) ** 2, 0.0, 1.0))


def _build_sleeve(mb: MeshBuilder, root: np.ndarray, side: int, spec: TopSpec) -> None:
    """A sleeve tube from the armhole loop ``root`` (ids) along the A-pose arm axis to the cuff."""
    alpha = math.radians(ARM_ANGLE_DEG)
    d = np.array([side * math.sin(alpha), -math.cos(alpha), 0.0])
    e1 = np.array([side * math.cos(alpha), math.sin(alpha), 0.0])  # towards the over-arm seam
    joint = np.array([side * SHOULDER_JOINT[0], SHOULDER_JOINT[1], ARM_Z])
    root_pts = np.concatenate(mb.points)[root]
    m = len(root)
    phi = 2 * np.pi * np.arange(m) / m  # 0 underarm, pi over-arm; front (z > 0) first
    r_top, r_end = spec.sleeve_top_girth / (2 * np.pi), spec.sleeve_end_girth / (2 * np.pi)
    # The first ring sits where its under-arm point is level with the armpit (root[0]): starting higher
    # would pull the under-arm seam up into the armpit and fold the cloth there.
    start = float((joint[1] - r_top * math.sin(alpha) - root_pts[0, 1]) / math.cos(alpha))
    # ... and outside the armpit: if the first ring's under-arm point would be inside it (a wide size),
    # start the sleeve's axis that much further out and bring it back onto the arm's axis over
    # ``SLEEVE_RETURN`` m, so that the sleeve still goes around the arm further down
    under_x = joint[0] * side + start * math.sin(alpha) - r_top * math.cos(alpha)
    shift = np.array([side * max(0.0, abs(root_pts[0, 0]) + 0.005 - under_x), 0.0, 0.0])
    length = spec.sleeve_end - start
    back = max(SLEEVE_RETURN, float(np.abs(shift).max()) / SLEEVE_SLOPE)
    rows = max(3, int(round(length / SPACING)))
    blend = max(1.0, 0.09 / (length / rows))  # rows over which the armhole turns into a circle (9 cm)
    prev = root
    for l_ in range(1, rows + 1):
        t = l_ / rows
        c = joint + (start + length * t) * d + shift * max(0.0, 1.0 - length * t / back)
        r = r_top + (r_end - r_top) * t
        circle = c + r * (-np.cos(phi)[:, None] * e1 + np.sin(phi)[:, None] * np.array([0.0, 0.0, 1.0]))
        w = smoothstep(l_ / blend)
        ids = mb.add((1 - w) * root_pts + w * circle)
        mb.strip(prev, ids, closed=True)
        prev = ids


# --- bottoms --------------------------------------------------------------------------------------


def build_skirt(girths: list[tuple[float, float]], spacing: float = SPACING) -> trimesh.Trimesh:
    """A tube of rings from the hem (first) to the waist (last), grid ``spacing`` m."""
    mb = MeshBuilder()
    ys, gs = np.array([g[0] for g in girths]), np.array([g[1] for g in girths])
    n_ring = 2 * int(round(np.mean(gs) / spacing / 2))
    rows = max(2, int(round((ys[-1] - ys[0]) / spacing)))
    theta = 2 * np.pi * np.arange(n_ring) / n_ring
    prev = None
    for j in range(rows + 1):
        y = ys[0] + (ys[-1] - ys[0]) * j / rows
        a, b = half_axes(np.interp(y, ys, gs))
        ids = mb.add(np.column_stack([-a * spow(np.cos(theta)), np.full(n_ring, y),
                                      b * spow(np.sin(theta)) + centre_z(y)]))
        if prev is not None:
            mb.strip(prev, ids, closed=True)
        prev = ids
    return mb.mesh()


def build_trousers(seat_girths: list[tuple[float, float]], thigh_girth: float, knee_girth: float,
                   hem_girth: float, y_hem: float) -> trimesh.Trimesh:
    """Seat tube (crotch to waist) whose first ring is a figure eight pinched at the crotch point, and
    two leg tubes from that ring down to the leg hems at ``y_hem``. ``seat_girths``: [(y, girth)] from the
    crotch up to the waist, m; the other girths (m) are the legs'.

    Seat ring node k (of 2 h, h even, q = h / 2): angle pi k / h around the seat from the person's right
    side (-x) over the front (+z); k = q is the front centre, k = h + q the back centre. On the crotch
    ring both are the crotch point. The right leg takes nodes 0..q and h+q..2h-1, the left q..h+q.
    """
    mb = MeshBuilder()
    h = 2 * int(round(thigh_girth / SPACING / 2))  # nodes per leg ring (even)
    n_ring, q = 2 * h, h // 2
    r_thigh = thigh_girth / (2 * np.pi)
    x_leg = r_thigh  # the two thigh circles touch at the crotch point

    # angle psi around each leg (0 at its outer side, pi at the crotch; front z > 0), and the leg's side
    k = np.arange(n_ring)
    side = np.where((k <= q) | (k >= h + q), -1, 1)
    psi = np.where(k <= q, np.pi * k / q, 0.0)
    psi = np.where(k >= h + q, np.pi + np.pi * (k - h - q) / q, psi)
    left_front = (k >= q) & (k <= h)
    psi = np.where(left_front, np.pi * (1 - (k - q) / q), psi)
    left_back = (k > h) & (k < h + q)
    psi = np.where(left_back, -np.pi * (k - h) / q, psi)

    def on_legs(y, r, xc):
        return np.column_stack([side * (xc + r * np.cos(psi)), np.full(n_ring, y), r * np.sin(psi)])

    theta = np.pi * k / h
    seat_rows = max(3, int(round((Y_WAIST - Y_CROTCH) / SPACING)))
    crotch_pts = on_legs(Y_CROTCH, r_thigh, x_leg)
    rings = []
    for j in range(seat_rows + 1):
        y = Y_CROTCH + (Y_WAIST - Y_CROTCH) * j / seat_rows
        g = np.interp(y, *zip(*seat_girths))
        a, b = half_axes(g)
        ellipse = np.column_stack([-a * spow(np.cos(theta)), np.full(n_ring, y),
                                   b * spow(np.sin(theta)) + centre_z(y)])
        # the seat rounds out quickly above the crotch point (the buttocks start just above it)
        w = np.sqrt(smoothstep((y - Y_CROTCH) / SEAT_RISE))
        ids = mb.add((1 - w) * crotch_pts + w * ellipse)
        if j == 0:
            ids[h + q] = ids[q]  # the crotch point: front and back centre are one vertex
        rings.append(ids)
    for j in range(seat_rows):
        mb.strip(rings[j], rings[j + 1], closed=True)

    crotch = rings[0]
    leg_nodes = (np.concatenate([k[: q + 1], k[h + q + 1:]]), k[q: h + q])  # right, left
    leg_rows = max(3, int(round((Y_CROTCH - y_hem) / SPACING)))
    for leg_side, nodes in zip((-1, +1), leg_nodes):
        mb.new_part()
        prev = crotch[nodes]
        for l_ in range(1, leg_rows + 1):
            y = Y_CROTCH - (Y_CROTCH - y_hem) * l_ / leg_rows
            # straight from the knee down over the calf (y 0.30), then narrowing to the hem
            g = np.interp(y, [Y_ANKLE, 0.30, Y_KNEE, Y_CROTCH], [hem_girth, knee_girth, knee_girth, thigh_girth])
            r = g / (2 * np.pi)
            # the leg's centre follows the body's legs (slightly apart towards the feet), but never so close to the
            # middle that the two legs' tubes overlap
            xc = max(np.interp(y, (*LEG_CENTRE_X[0], Y_CROTCH), (*LEG_CENTRE_X[1], x_leg)), r + LEG_GAP)
            zc = np.interp(y, LEG_CENTRE_Z[0], LEG_CENTRE_Z[1])
            pts = np.column_stack([leg_side * (xc + r * np.cos(psi[nodes])), np.full(len(nodes), y),
                                   r * np.sin(psi[nodes]) + zc])
            ids = mb.add(pts)
            mb.strip(prev, ids, closed=True)
            prev = ids
    return mb.mesh()


# --- the catalogue --------------------------------------------------------------------------------


def _cm(x: float) -> float:
    return x / 100.0


# The body's torso girth (tape around the convex hull, m) at heights y, from the size chart's chest,
# waist and hips: the shape of the service's parametric body between the buttocks (0.85 m) and the
# armpits, where the torso is measured. Garments are this plus their ease.
def body_girth_table(s: dict) -> list[tuple[float, float]]:
    # at 0.85-0.90 m the fronts of the thighs and the buttocks make the section fuller than an
    # ellipse of its girth: 4 and 2 cm more keep an elliptic garment around it
    return [(0.85, s["hips"] + 0.05), (0.90, s["hips"] + 0.02), (0.95, (s["hips"] + s["waist"]) / 2 + 0.02),
            (1.00, s["waist"] + 0.02), (Y_WAIST, s["waist"]), (1.10, s["waist"] + 0.03),
            (1.15, s["chest"] - 0.05), (1.20, s["chest"] - 0.01), (1.25, s["chest"] - 0.01)]


def fitted(s: dict, y0: float, y1: float, ease: float, floor: float = 0.0) -> list[tuple[float, float]]:
    """[(y, girth)] from y0 up to y1: the body's girth plus ``ease`` (m), at least ``floor`` (m)."""
    table = body_girth_table(s)
    ys = [y0, *[y for y, _ in table if y0 < y < y1], y1]
    ty, tg = zip(*table)
    return [(y, max(float(np.interp(y, ty, tg)) + ease, floor)) for y in ys]


def garment_mesh(kind: str, size: str) -> trimesh.Trimesh:
    """One catalogue garment: kind in ``GARMENTS``, size a key of ``SIZE_CHART`` (S .. XXL)."""
    s = {k: _cm(v) for k, v in SIZE_CHART[size].items()}
    neck = dict(neck_half=s["neck"] / (2 * np.pi) + 0.025, neck_depth=s["neck"] / (2 * np.pi) + 0.025)
    if kind == "tshirt":  # chest + 8 cm (body + 9 cm under the arms), straight, sleeves to mid upper arm
        return build_top(TopSpec(
            girths=fitted(s, 0.75, Y_ARMPIT, 0.09, floor=s["chest"] + 0.04),
            shoulder_half=SHOULDER_HALF[size], neck_drop_front=0.08, neck_drop_back=0.02,
            armhole_angle_deg=46.0, sleeve_end=0.24, sleeve_top_girth=s["upper_arm"] + 0.14,
            sleeve_end_girth=s["upper_arm"] + 0.12, **neck))
    if kind == "longsleeve":  # chest + 10 cm, straight, sleeves to the wrist
        return build_top(TopSpec(
            girths=fitted(s, 0.72, Y_ARMPIT, 0.11, floor=s["chest"] + 0.06),
            shoulder_half=SHOULDER_HALF[size], neck_drop_front=0.07, neck_drop_back=0.02,
            armhole_angle_deg=46.0, sleeve_end=0.60, sleeve_top_girth=s["upper_arm"] + 0.12,
            sleeve_end_girth=s["wrist"] + 0.08, **neck))
    if kind == "dress":  # sleeveless, fitted (ease 8 cm) down to the hips, then flared to the knee
        return build_top(TopSpec(
            girths=[(0.52, s["hips"] + 0.50), *fitted(s, 0.85, Y_ARMPIT, 0.08)],
            shoulder_half=SHOULDER_HALF[size] - 0.03, neck_drop_front=0.11, neck_drop_back=0.04,
            armhole_angle_deg=44.0, sleeve_end=None, **neck))
    if kind == "skirt":  # A-line to just above the knee, sits at the waist (ease 4 cm there)
        return build_skirt([(0.52, s["hips"] + 0.30), *fitted(s, 0.85, Y_WAIST, 0.08)[:-1],
                            (Y_WAIST, s["waist"] + 0.04)],
                           spacing=0.8 * SPACING)  # a small garment: a finer grid keeps >= 2,000 vertices
    # trousers and shorts: a seat with 6 cm of ease, a waistband 4 cm over the waist
    seat = [*fitted(s, Y_CROTCH, Y_WAIST, 0.06)[:-1], (Y_WAIST, s["waist"] + 0.04)]
    if kind == "trousers":
        return build_trousers(seat, s["thigh"] + 0.10, s["knee"] + 0.12,
                              s["knee"] + 0.04, y_hem=0.05)
    if kind == "shorts":
        return build_trousers(seat, s["thigh"] + 0.12, s["knee"] + 0.14,
                              s["knee"] + 0.14, y_hem=0.58)
    raise ValueError(f"unknown garment kind {kind!r}")


# kind -> (display name, category)
GARMENTS = {
    "tshirt": ("T-shirt", "top"),
    "longsleeve": ("Long-sleeve shirt", "top"),
    "dress": ("Sleeveless dress", "dress"),
    "skirt": ("A-line skirt", "bottom"),
    "trousers": ("Trousers", "bottom"),
    "shorts": ("Shorts", "bottom"),
}


# The girths each category's chart rows give (cm): what a shop's chart lists for it, and what the garment is
# built around (a top's body from the chest down past the waist, a bottom's seat from the waist to the hips).
CHART_GIRTHS = {"top": ("chest", "waist"), "bottom": ("waist", "hips"), "dress": ("chest", "waist", "hips")}


def chart_row(size: str, category: str) -> dict[str, list[float]]:
    """The size-chart row ``SIZE_CHART`` implies for ``size``: per girth of ``CHART_GIRTHS[category]`` the
    range [min, max] cm of bodies it is made for, from halfway to the next smaller size to halfway to the next
    larger one (the end sizes extend as far past their value as their neighbour's half step)."""
    labels = list(SIZE_CHART)
    i = labels.index(size)
    row = {}
    for girth in CHART_GIRTHS[category]:
        value = SIZE_CHART[size][girth]
        below = SIZE_CHART[labels[i - 1]][girth] if i > 0 else 2 * value - SIZE_CHART[labels[i + 1]][girth]
        above = SIZE_CHART[labels[i + 1]][girth] if i + 1 < len(labels) else 2 * value - SIZE_CHART[labels[i - 1]][girth]
        row[girth] = [(below + value) / 2, (value + above) / 2]
    return row


def obj_text(mesh: trimesh.Trimesh, title: str) -> str:
    """Minimal OBJ: a comment, ``v`` lines (m, 0.1 mm), ``f`` lines (1-based triangles)."""
    lines = [f"# {title}", "# generated by tryon.garment.generate: metres, y up, facing +z"]
    lines += [f"v {x:.4f} {y:.4f} {z:.4f}" for x, y, z in mesh.vertices]
    lines += [f"f {a} {b} {c}" for a, b, c in mesh.faces + 1]
    return "\n".join(lines) + "\n"


def write_catalogue(out_dir: Path) -> list[dict]:
    """Write every garment in every size as OBJ plus ``catalogue.json``; returns the entries. Each entry's
    ``style`` is its kind (``GARMENTS``), its ``chart`` the size-chart row it was built for (``chart_row``), its
    ``fabric`` its category's (``fabric.DEFAULT_FABRIC``: jersey tops and dresses, cotton twill bottoms)."""
    out_dir.mkdir(parents=True, exist_ok=True)
    entries = []
    for kind, (name, category) in GARMENTS.items():
        for size in SIZE_CHART:
            mesh = garment_mesh(kind, size)
            file = f"{kind}-{size.lower()}.obj"
            (out_dir / file).write_text(obj_text(mesh, f"{name}, size {size}"))
            entries.append(dict(file=file, name=f"{name} {size}", category=category, style=kind, size=size,
                                chart=chart_row(size, category), fabric=DEFAULT_FABRIC[category], units="m"))
    # one entry a line: 30 entries stay readable and a change shows as one line in a diff
    (out_dir / "catalogue.json").write_text("[\n" + ",\n".join(" " + json.dumps(e) for e in entries) + "\n]\n")
    return entries


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description="write the catalogue's garment meshes")
    parser.add_argument("out_dir", type=Path, help="directory for the OBJ files and catalogue.json")
    args = parser.parse_args(argv)
    for e in write_catalogue(args.out_dir):
        print(e["file"], e["name"], e["category"])
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
