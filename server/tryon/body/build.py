"""``build_body``: measurements and pose in, the body mesh with its collision maps out (SPEC section 2).

Steps: (1) stations and placements from the measurements (``shape.body_layout``); (2) scale every measured
section so that its sampled polygon has exactly the requested girth (the mesh row at that station *is* the
sampled section, see ``nurbs.py``, so the mesh then measures what was asked); (3) move the homogeneous
control sections into the world and evaluate each part's two surfaces on the cached (u, v) grid; (4)
solve the leg length so that the soles stand on y = 0 with the hips where the measurements put them
(spread legs are lengthened rather than the body lowered, so stature and crotch height hold in any pose),
raise arms asked to hang lower than they can rest against the torso (``ARM_PRESS``; a forearm
``FOREARM_PRESS``), each side on its own (every limb is built as a left one in its side's angles; the right
ones are mirrored, x -> -x), and scale y by the last ~1e-6 that makes the top of the head exactly the stature;
(5) normals, measurements of the built mesh, OBBs and cylinder maps.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import lru_cache

import numpy as np

from tryon.body import nurbs
from tryon.body.sections import SectionHulls, section_hulls
from tryon.geometry import face_vertex_normals
from tryon.body.maps import build_part_maps
from tryon.body.measure import horizontal_breadth, horizontal_girth, hull_perimeter, mesh_edges, section_girth
from tryon.body.params import POSE_RANGES, Measurements, Pose, check_measurements, check_pose, complete
from tryon.body.shape import A, B, F, MEASURED_STATIONS, SHAPE_NAMES, body_layout, station_params
from tryon.body.types import PART_NAMES, Body

# Grid intervals across the front half of the torso; every part's grid follows from it (``GRID``).
# 30 gives about 10,000 vertices (the vertex count grows as 11.3 * resolution^2).
DEFAULT_RESOLUTION = 30
MIN_RESOLUTION = 6
MAX_RESOLUTION = 200
# Leg-length solve: at most this many secant steps, stopping when the soles are within this many
# metres of the floor (the final fit of the stature absorbs what is left: a stretch below 1e-4).
LEG_ITERATIONS = 3
LEG_TOLERANCE = 1e-4
# End tangent of every part at its poles, as a multiple of (next section - pole) / parameter step:
# 1 makes the caps about spherical; the tangent is perpendicular to the axis, so no cap overshoots its pole.
CAP_ROUNDNESS = 1.0
# A hanging arm rests against the side of the torso: below the chest its flesh may press at most this far
# (m) into the torso's section, as soft tissue gives way; an arm angle that would press it deeper is
# raised until it does not (found to ARM_ANGLE_PRECISION degrees; sections taken every SECTION_STEP m).
# Lower, the arm would pass through the torso: at angle 0 the medium body's upper arm went 4 cm into the
# chest and the hand 2.6 cm into the hip, and no garment could lie between them (0 of 9 catalogue tops
# met the fit targets). With 1.5 cm the medium body's arms rest at 12.7 degrees and all 9 meet them; with
# 2 cm (8.4 degrees) 4 of the 9 still end with springs over their limits.
ARM_PRESS = 0.015
# The top of the upper arm, within this fraction of its length (shoulder joint to elbow) from the shoulder
# joint, is inside the shoulder where arm and torso meet: above the chest it is not counted as pressing.
# Beyond it, an arm raised forwards or a hand on the hip counts wherever it is (an arm swung forwards at 0
# degrees would otherwise cross the chest).
SHOULDER_REACH = 0.5
# A hand rests on the clothes, not in the body: it keeps this far (m) off the torso, room for a layer of cloth
# between them (the simulation keeps cloth 4 mm off every part, so 2 x 4 mm and 1 mm of cloth). Pressing
# 1.5 cm into the hip as an arm may, the hand pinched the shirt there: the shown shirt stretched 270 % round
# the hand, the hand showed through it, and the next pose came out with a sleeve off the arm. Hanging arms
# are unchanged by it: their hands never come near the torso, the upper arm rests against it first.
HAND_GAP = 0.009
# m: a forearm may go no deeper than this into the torso's section (an arm swung forwards and turned in with its
# elbow bent swings the forearm across the belly; below the upper arm's ARM_PRESS there is no soft tissue to
# give): deeper, the arm is raised as for ARM_PRESS. The motion stress's first sequence had such a pose, its
# right forearm 9.3 mm through the torso: no cloth can lie between the two, and 8 of the 30 garments ended it
# with a vertex inside the body. The tolerance of a penetration (2 mm), so every named and bench pose builds as
# before.
FOREARM_PRESS = 0.002
ARM_ANGLE_PRECISION = 0.25
SECTION_STEP = 0.005
# Margin (m) the OBBs and cylinder cells are grown by: the collision offset of the body surface is
# smaller than this (SPEC section 4), so a garment point near the offset surface is still found.
MAP_MARGIN = 0.01

# Per shape (u intervals per half, v intervals) as multiples of the resolution: proportional to the
# reference body's half circumference and profile length, so triangles are about the same size everywhere.
GRID = {
    "head": (0.6, 0.9), "torso": (1.0, 1.5), "upper_arm": (0.33, 0.85),
    "forearm": (0.30, 1.1), "thigh": (0.6, 1.1), "shin": (0.45, 1.2),
}
# Which shape each part is, and whether it is the mirror image (x -> -x) of the left one.
PART_SHAPES = {
    "head": ("head", False), "torso": ("torso", False),
    "upper_arm_l": ("upper_arm", False), "upper_arm_r": ("upper_arm", True),
    "forearm_l": ("forearm", False), "forearm_r": ("forearm", True),
    "thigh_l": ("thigh", False), "thigh_r": ("thigh", True),
    "shin_l": ("shin", False), "shin_r": ("shin", True),
}
LIMB_SHAPES = ("upper_arm", "forearm", "thigh", "shin")
GIRTHS = {"chest": "torso", "waist": "torso", "hips": "torso", "neck": "head", "thigh": "thigh",
          "upper_arm": "upper_arm"}

# The arms' parts (their names start so): raised above the head they are not part of the stature.
ARM_PARTS = ("upper_arm", "forearm")


@dataclass(frozen=True)
class Grid:
    """Everything that depends on the resolution only (cached).

    ring[shape] (n_ring, 8), rows[shape] (n_v, n_stations): the basis matrices (``nurbs.py``), the
    rows including every measured station; faces (f, 3) int32 and face_part (f,) int16 of the whole body
    (read-only, shared by every body of this resolution); part_vertices / part_faces: (start, stop) of
    each part's vertices / faces; part_edges: each part's unique edges (e, 2), indices local to the
    part's vertices."""

    ring: dict
    rows: dict
    faces: np.ndarray
    face_part: np.ndarray
    part_vertices: tuple
    part_faces: tuple
    part_edges: tuple


def tube_faces(n_v: int, n_ring: int) -> np.ndarray:
    """(f, 3) triangles of a closed tube sampled on n_v rows (rows 0 and n_v - 1 are poles, one vertex
    each) and n_ring columns, vertices ordered pole, rows 1..n_v-2, pole. Two triangles per grid cell
    (paper figure 1), one at the poles; counter-clockwise from outside when the columns run
    counter-clockwise about the row direction."""
    inner = n_v - 2
    c = np.arange(n_ring)
    c1 = (c + 1) % n_ring
    r = np.arange(inner - 1)[:, None]
    v00 = 1 + r * n_ring + c
    v01 = 1 + r * n_ring + c1
    v10 = v00 + n_ring
    v11 = v01 + n_ring
    body = np.concatenate([np.stack([v00, v01, v10], -1).reshape(-1, 3),
                           np.stack([v01, v11, v10], -1).reshape(-1, 3)])
    top = 1 + inner * n_ring
    bottom_fan = np.stack([np.zeros(n_ring, int), 1 + c1, 1 + c], -1)
    last = 1 + (inner - 1) * n_ring
    top_fan = np.stack([last + c, last + c1, np.full(n_ring, top)], -1)
    return np.concatenate([bottom_fan, body, top_fan]).astype(np.int32)


@lru_cache(maxsize=8)
def grid(resolution: int) -> Grid:
    """Basis matrices and topology for ``resolution`` (built once per resolution)."""
    params = station_params()
    ring, rows = {}, {}
    for shape in SHAPE_NAMES:
        gu, gv = GRID[shape]
        n_u = max(4, round(gu * resolution)) + 1
        n_v = max(6, round(gv * resolution)) + 1
        t = params[shape]
        measured = sorted(MEASURED_STATIONS.get(shape, {}).values())
        v = nurbs.sample_params(n_v, tuple(t[i] for i in measured))
        ring[shape] = nurbs.ring_matrix(n_u)
        rows[shape] = nurbs.station_matrix(t, tuple(v))
    faces, face_part, part_vertices, part_faces, part_edges = [], [], [], [], []
    n_vert = n_face = 0
    for k, name in enumerate(PART_NAMES):
        shape, mirrored = PART_SHAPES[name]
        f = tube_faces(rows[shape].shape[0], ring[shape].shape[0])
        if mirrored:
            f = f[:, [0, 2, 1]]
        n_here = 2 + (rows[shape].shape[0] - 2) * ring[shape].shape[0]
        part_edges.append(mesh_edges(f))
        faces.append(f + n_vert)
        face_part.append(np.full(len(f), k, np.int16))
        part_vertices.append((n_vert, n_vert + n_here))
        part_faces.append((n_face, n_face + len(f)))
        n_vert += n_here
        n_face += len(f)
    faces = np.concatenate(faces).astype(np.int32)
    face_part = np.concatenate(face_part)
    for arr in (faces, face_part):
        arr.setflags(write=False)
    return Grid(ring, rows, faces, face_part, tuple(part_vertices), tuple(part_faces),
                tuple(part_edges))


def _homogeneous_world(stations: np.ndarray, params: tuple[float, ...], rotation: np.ndarray,
                       origin: np.ndarray, tilt: np.ndarray | None = None,
                       pivot: np.ndarray | None = None) -> np.ndarray:
    """(n + 2, 8, 4) interpolation data of a part in the world: its n homogeneous sections and the two
    end tangents (``nurbs.end_tangents``), first turned by ``tilt`` (n,) radians about the local z axis
    through ``pivot``, then moved by (rotation, origin). NURBS are affine invariant, so moving the data
    (points and tangents alike: the maps are linear in homogeneous coordinates) moves the surface."""
    pw = nurbs.ring_controls(*stations.T)
    pw = np.concatenate([pw, nurbs.end_tangents(pw, params, CAP_ROUNDNESS)])
    if tilt is not None and np.any(tilt):
        angle = np.concatenate([tilt, tilt[[0, -1]]])[:, None]
        c, s = np.cos(angle), np.sin(angle)
        w = pw[..., 3]
        x = pw[..., 0] - pivot[0] * w
        y = pw[..., 1] - pivot[1] * w
        pw[..., 0] = c * x - s * y + pivot[0] * w
        pw[..., 1] = s * x + c * y + pivot[1] * w
    out = np.empty_like(pw)
    out[..., :3] = pw[..., :3] @ rotation.T + pw[..., 3:4] * origin
    out[..., 3] = pw[..., 3]
    return out


def _fit_girths(stations: np.ndarray, measured: dict, targets: dict, ring: np.ndarray) -> np.ndarray:
    """``stations`` with each measured girth section scaled (a, f, b about its centre) so that the
    perimeter of the convex hull of its sampled polygon equals the target (metres). Exact: the hull
    perimeter of a section scaled about its centre scales by the same factor."""
    out = stations.copy()
    for name, i in measured.items():
        if name not in targets:
            continue
        pts = nurbs.sample_rings(nurbs.ring_controls(*stations[i:i + 1].T), ring)[0]
        achieved = hull_perimeter(pts[:, [0, 2]])
        out[i, [A, F, B]] *= targets[name] / achieved
    return out


def build_body(m: Measurements, pose: Pose = Pose(), resolution: int = DEFAULT_RESOLUTION) -> Body:
    """Build the body for measurements ``m`` (cm) in ``pose`` (degrees); mesh resolution ``resolution``
    (grid intervals across the front of the torso; ~11.3 * resolution^2 vertices). See the module doc.
    Raises ValueError, naming the field and its range, for measurements or angles out of range."""
    if not MIN_RESOLUTION <= resolution <= MAX_RESOLUTION:
        raise ValueError(f"resolution={resolution} is outside [{MIN_RESOLUTION}, {MAX_RESOLUTION}]")
    problems = check_measurements(m) + check_pose(pose)
    if problems:
        raise ValueError("; ".join(problems))
    full = complete(m)
    g = grid(int(resolution))
    sides = ("left", "right")
    layouts = {side: body_layout(full, pose, 1.0, side) for side in sides}
    targets = {name: getattr(full, name) / 100.0 for name in GIRTHS}

    # ---- surfaces --------------------------------------------------------------------------------------
    # shape_points[(shape, side)]: the left-side limbs of the layout of that side (the right ones are
    # mirrored below); head and torso are the same in both layouts and evaluated once ("left").
    shape_points = {}
    shape_axes = {}
    params = station_params()

    def evaluate(shapes, side):
        part_layout = layouts[side]
        for shape in shapes:
            part = part_layout.parts[shape]
            stations = _fit_girths(part.stations, part.measured, targets, g.ring[shape])
            pw = _homogeneous_world(stations, params[shape], part.rotation, part.origin, part.tilt, part.pivot)
            pts = nurbs.evaluate_tube(pw, g.rows[shape], g.ring[shape])
            shape_points[shape, side] = np.concatenate([pts[0, :1], pts[1:-1].reshape(-1, 3), pts[-1, :1]])
            shape_axes[shape, side] = np.stack([pts[0, 0], pts[-1, 0]])

    evaluate(SHAPE_NAMES, "left")
    evaluate(LIMB_SHAPES, "right")
    # Legs long enough for the soles to stand on y = 0 (secant steps on the leg length; the sole's height
    # is nearly linear in it): the crotch, the torso levels and the stature then stay where the
    # measurements put them, in any leg spread. Each leg has its own spread, so its own length.
    hip_y = layouts["left"].landmarks["hip_joint"][1]
    leg_scale = {}
    for side in sides:
        leg_scale[side] = 1.0
        for _ in range(LEG_ITERATIONS):
            sole = shape_points["shin", side][:, 1].min()
            if abs(sole) < LEG_TOLERANCE:
                break
            leg_scale[side] *= hip_y / (hip_y - sole)
            layouts[side] = body_layout(full, pose, leg_scale[side], side)
            evaluate(("thigh", "shin"), side)
    # Arms no lower than where they rest against the torso (``ARM_PRESS``), each side on its own; the torso
    # does not depend on the arms, so only the arms are evaluated again.
    torso_vertices, torso_edges = shape_points["torso", "left"], g.part_edges[PART_NAMES.index("torso")]
    start, stop = g.part_faces[PART_NAMES.index("torso")]
    torso_faces = g.faces[start:stop] - g.part_vertices[PART_NAMES.index("torso")][0]
    torso = section_hulls(torso_vertices, torso_edges, SECTION_STEP)
    grown = section_hulls(torso_vertices + HAND_GAP * face_vertex_normals(torso_vertices, torso_faces)[1], torso_edges,
                          SECTION_STEP)
    chest_y = layouts["left"].landmarks["levels"]["chest"]

    def pressing(side: str) -> bool:
        arm = np.concatenate([shape_points["upper_arm", side], shape_points["forearm", side]])
        lm = layouts[side].landmarks
        arm_depth, _ = arm_press(arm, lm["shoulder_joint"], lm["elbow"], lm["wrist"], torso, chest_y)
        _, hand_depth = arm_press(arm, lm["shoulder_joint"], lm["elbow"], lm["wrist"], grown, chest_y)
        forearm_depth, _ = arm_press(shape_points["forearm", side], lm["shoulder_joint"], lm["elbow"], lm["wrist"],
                                     torso, chest_y)
        return arm_depth > ARM_PRESS or hand_depth > 0.0 or forearm_depth > FOREARM_PRESS

    def pose_arm(side: str, angle: float) -> None:
        layouts[side] = body_layout(full, replace(pose, **{f"arm_angle_{side}": angle}), leg_scale[side], side)
        evaluate(("upper_arm", "forearm"), side)

    for side in sides:
        if not pressing(side):
            continue
        lo, hi = getattr(pose, f"arm_angle_{side}"), POSE_RANGES[f"arm_angle_{side}"][1]
        while hi - lo > ARM_ANGLE_PRECISION:
            mid = 0.5 * (lo + hi)
            pose_arm(side, mid)
            lo, hi = (mid, hi) if pressing(side) else (lo, mid)
        pose = replace(pose, **{f"arm_angle_{side}": hi})
        pose_arm(side, hi)
    layout = layouts["left"]
    mirror = np.array([-1.0, 1.0, 1.0])

    def points(name):
        shape, mirrored = PART_SHAPES[name]
        if shape in LIMB_SHAPES:
            return shape_points[shape, "right" if mirrored else "left"] * (mirror if mirrored else 1.0)
        return shape_points[shape, "left"]

    def axis(name):
        shape, mirrored = PART_SHAPES[name]
        if shape in LIMB_SHAPES:
            return shape_axes[shape, "right" if mirrored else "left"] * (mirror if mirrored else 1.0)
        return shape_axes[shape, "left"]

    pieces = [points(name) for name in PART_NAMES]
    vertices = np.concatenate(pieces)
    part_axes = np.stack([axis(name) for name in PART_NAMES])

    # ---- floor and stature -----------------------------------------------------------------------------
    y0 = vertices[:, 1].min()
    # stature is the top of the head: hands raised above it (arms_raised) must not shrink the body to fit
    top = max(float(p[:, 1].max()) for name, p in zip(PART_NAMES, pieces) if not name.startswith(ARM_PARTS))
    stretch = (full.height / 100.0) / (top - y0)

    def to_floor(p):
        q = np.array(p, dtype=float, copy=True)
        q[..., 1] = (q[..., 1] - y0) * stretch
        return q

    vertices = to_floor(vertices)
    part_axes = to_floor(part_axes)
    faces = g.faces

    # ---- normals ---------------------------------------------------------------------------------------
    face_normals, vertex_normals = face_vertex_normals(vertices, faces)  # vertex: area-weighted

    # ---- what the built mesh measures ------------------------------------------------------------------
    lm = layout.landmarks
    levels = {k: float((v - y0) * stretch) for k, v in lm["levels"].items()}
    achieved = _measure(vertices, g, layout, levels, to_floor)

    joints = {}
    for side in sides:
        flip = mirror if side == "right" else 1.0
        for name in ("shoulder_joint", "elbow", "wrist", "hip_joint", "knee"):
            joints[f"{name.removesuffix('_joint')}_{side[0]}"] = to_floor(layouts[side].landmarks[name] * flip)
    maps = build_part_maps(vertices, faces, g.face_part, map_axes(part_axes, joints, pose), margin=MAP_MARGIN)
    requested = {k: v for k, v in m.as_dict().items() if v is not None}
    return Body(
        vertices=vertices, faces=faces, vertex_normals=vertex_normals, face_normals=face_normals,
        face_part=g.face_part, parts=PART_NAMES, part_axes=part_axes, maps=maps,
        requested=requested, achieved=achieved,
        levels={k: levels[k] for k in ("chest", "waist", "hips")},
        estimated={k: getattr(full, k) for k in full.as_dict() if getattr(m, k) is None},
        pose=pose.as_dict(), joints=joints, resolution=int(resolution),
    )


def with_hands_straight(body: Body) -> Body:
    """The body ``body`` was built as (the same measurements, pose and resolution) with both hands straight at
    the wrist; ``body`` itself if neither hand is turned or it was not built by ``build_body``. Built anew, so
    an arm whose straight hand would press into the torso is raised as ``build_body`` raises any (the hands on
    the hips, straight, point into them). A drape in a pose with turned hands starts on it
    (``sim.repose.fresh_drape``)."""
    if not body.hands_turned or body.resolution is None:
        return body
    pose = replace(Pose(**body.pose), wrist_bend_left=0.0, wrist_bend_right=0.0)
    return build_body(Measurements(**body.requested), pose, body.resolution)


def arm_press(arm: np.ndarray, joint: np.ndarray, elbow: np.ndarray, wrist: np.ndarray, torso: SectionHulls,
              chest_y: float) -> tuple[float, float]:
    """How far (m) an arm's points ``arm`` (n, 3) go into the torso (its sections every ``SECTION_STEP``,
    ``torso``; for the hand, the torso grown by ``HAND_GAP``):
    the deepest of them inside the torso's horizontal section at its height, (the arm's, the hand's). The
    hand: the points farther from the ``elbow`` than the ``wrist`` joint is (3,) each. Counted: every point
    below ``chest_y`` and, above it, those farther than ``SHOULDER_REACH`` x the upper arm's length from the
    shoulder ``joint`` (3,): the top of the arm is inside the shoulder where the parts meet, and an arm
    hanging at the side may touch the torso at the armpit."""
    reach = SHOULDER_REACH * float(np.linalg.norm(elbow - joint))
    counted = arm[(arm[:, 1] < chest_y) | (np.linalg.norm(arm - joint, axis=1) > reach)]
    depth = torso.depths(counted)
    hand = np.linalg.norm(counted - elbow, axis=1) > np.linalg.norm(wrist - elbow)
    return float(depth[~hand].max(initial=0.0)), float(depth[hand].max(initial=0.0))


def _part_mesh(vertices: np.ndarray, g: Grid, name: str) -> tuple[np.ndarray, np.ndarray]:
    """(vertices, edges) of one part, edges indexing the part's own vertices."""
    k = PART_NAMES.index(name)
    start, stop = g.part_vertices[k]
    return vertices[start:stop], g.part_edges[k]


def _measure(vertices: np.ndarray, g: Grid, layout, levels: dict, to_floor) -> dict:
    """Measurements (cm) of the built mesh: height, the six girths (convex hull of plane sections of
    the part that carries them), shoulder breadth at acromion level, arm length along the skeleton,
    inseam (lowest point of the torso)."""
    torso = _part_mesh(vertices, g, "torso")
    out = {"height": float(vertices[:, 1].max() - vertices[:, 1].min())}
    for name in ("chest", "waist", "hips"):
        out[name] = horizontal_girth(*torso, levels[name])
    out["neck"] = horizontal_girth(*_part_mesh(vertices, g, "head"), levels["neck"])
    for name, shape in (("thigh", "thigh"), ("upper_arm", "upper_arm")):
        part = layout.parts[shape]
        i = part.measured[name]
        centre = to_floor(part.rotation @ part.stations[i, [4, 0, 5]] + part.origin)
        axis = to_floor(part.rotation[:, 1] + part.origin) - to_floor(part.origin)
        out[name] = section_girth(*_part_mesh(vertices, g, shape + "_l"), centre, axis / np.linalg.norm(axis))
    out["shoulder_width"] = horizontal_breadth(*torso, levels["acromion"])
    lm = {k: to_floor(layout.landmarks[k]) for k in ("acromion", "elbow", "wrist")}
    out["arm_length"] = float(np.linalg.norm(lm["acromion"] - lm["elbow"]) + np.linalg.norm(lm["elbow"] - lm["wrist"]))
    out["inseam"] = float(torso[0][:, 1].min())
    return {k: round(v * 100.0, 3) for k, v in out.items()}


def map_axes(part_axes: np.ndarray, joints: dict, pose: Pose) -> np.ndarray:
    """(P, 2, 3) m: the axes the parts' cylinder maps are made along: ``part_axes``, except the forearm of a hand
    turned at the wrist, whose axis points from the elbow at the wrist joint (as long as its own). The forearm's
    own axis runs to the fingertips: with the hand turned 70 degrees it left the forearm a few cm below the
    elbow, rays from it out through the cloth around the forearm missed the surface, and cloth 2.4 cm outside
    was judged 2.4 cm inside (a sleeve point pushed through the forearm in one step)."""
    out = np.array(part_axes, dtype=np.float64, copy=True)
    for side, name in (("l", "left"), ("r", "right")):
        if getattr(pose, f"wrist_bend_{name}"):
            k = PART_NAMES.index(f"forearm_{side}")
            a, b = out[k]
            direction = joints[f"wrist_{side}"] - a
            out[k, 1] = a + direction * (np.linalg.norm(b - a) / np.linalg.norm(direction))
    return out
