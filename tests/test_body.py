"""The parametric body: measurements honoured, closed outward surfaces, symmetry, collision maps, API."""

from __future__ import annotations

import io

import numpy as np
import pytest
import trimesh
from scipy.spatial import ConvexHull

from tryon.body import nurbs
from tryon.body.build import ARM_PRESS, DEFAULT_RESOLUTION, build_body
from tryon.body.kernels import hull_perimeter_2d
from tryon.body.params import (
    MEASUREMENT_RANGES,
    OPTIONAL,
    REQUIRED,
    Measurements,
    Pose,
    check_measurements,
    complete,
)
from tryon.body.types import PART_NAMES

GIRTH_TOL_CM = 0.5  # the accuracy target for chest, waist, hips and height


def random_people(n: int, seed: int) -> list[Measurements]:
    """Seeded plausible people spanning the whole ranges (rejection sampling against the sanity checks)."""
    rng = np.random.default_rng(seed)
    people = []
    while len(people) < n:
        m = Measurements(**{k: float(rng.uniform(*MEASUREMENT_RANGES[k])) for k in REQUIRED})
        if not check_measurements(m):
            people.append(m)
    return people


SPREAD = random_people(10, seed=3) + [
    Measurements(height=175.0, chest=100.0, waist=88.0, hips=100.0),  # average man
    Measurements(height=162.0, chest=92.0, waist=76.0, hips=104.0),  # pear-shaped woman
    Measurements(height=170.0, chest=112.0, waist=128.0, hips=118.0),  # waist > chest and > hips
    Measurements(height=141.0, chest=72.0, waist=58.0, hips=78.0),  # near the small ends
    Measurements(height=209.0, chest=148.0, waist=145.0, hips=149.0),  # near the large ends
]


@pytest.fixture(scope="session")
def bodies():
    """(measurements, body) for the spread, default pose and resolution (also warms numba up once)."""
    return [(m, build_body(m)) for m in SPREAD]


@pytest.fixture(scope="session")
def average():
    return build_body(Measurements(height=175.0, chest=100.0, waist=88.0, hips=100.0))


def part_faces(body, name: str) -> np.ndarray:
    return body.faces[body.face_part == PART_NAMES.index(name)]


def oracle_girth(body, y: float) -> float:
    """Independent tape measure: trimesh's plane section of the torso, scipy's convex hull perimeter (m)."""
    torso = trimesh.Trimesh(body.vertices, part_faces(body, "torso"), process=False)
    # a hair above the level: the section polygon is the same to ~1e-9 m and no vertex lies on the plane
    lines = trimesh.intersections.mesh_plane(torso, [0.0, 1.0, 0.0], [0.0, y + 1e-9, 0.0])
    pts = lines.reshape(-1, 3)[:, [0, 2]]
    return ConvexHull(pts).area


def winding_number(vertices: np.ndarray, faces: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Generalised winding number (k,) of closed triangle mesh at points (k, 3): ~1 inside, ~0 outside."""
    a = vertices[faces[:, 0]][None] - points[:, None]
    b = vertices[faces[:, 1]][None] - points[:, None]
    c = vertices[faces[:, 2]][None] - points[:, None]
    la, lb, lc = (np.linalg.norm(x, axis=2) for x in (a, b, c))
    det = np.einsum("pfi,pfi->pf", a, np.cross(b, c))
    den = la * lb * lc + np.einsum("pfi,pfi->pf", a, b) * lc + np.einsum("pfi,pfi->pf", b, c) * la \
        + np.einsum("pfi,pfi->pf", c, a) * lb
    return np.arctan2(det, den).sum(axis=1) / (2.0 * np.pi)


# ---- measurements ------------------------------------------------------------------------------------------

def test_girths_and_height_match_the_request(bodies):
    for m, body in bodies:
        for name in ("chest", "waist", "hips"):
            measured = oracle_girth(body, body.levels[name]) * 100.0
            assert abs(measured - getattr(m, name)) < GIRTH_TOL_CM, (m, name, measured)
            assert abs(body.achieved[name] - measured) < 1e-3, (name, body.achieved[name], measured)
        height = (body.vertices[:, 1].max() - body.vertices[:, 1].min()) * 100.0
        assert body.vertices[:, 1].min() == pytest.approx(0.0, abs=1e-12)
        assert abs(height - m.height) < GIRTH_TOL_CM
        assert body.achieved["height"] == pytest.approx(height, abs=1e-3)


def test_levels_are_anatomical(bodies):
    for m, body in bodies:
        lv = body.levels
        h = m.height / 100.0
        assert lv["hips"] < lv["waist"] < lv["chest"], lv
        assert 0.68 * h < lv["chest"] < 0.76 * h
        assert 0.57 * h < lv["waist"] < 0.63 * h
        assert complete(m).inseam / 100.0 < lv["hips"] < lv["waist"]


def test_waist_larger_than_chest_is_kept(bodies):
    m, body = bodies[SPREAD.index(Measurements(height=170.0, chest=112.0, waist=128.0, hips=118.0))]
    assert body.achieved["waist"] > body.achieved["chest"] + 15.0
    assert body.achieved["waist"] > body.achieved["hips"] + 9.0


def test_thighs_stay_inside_the_hip_tape(bodies):
    """A tape at hip level goes round the thighs too: they must not bulge out of the torso's section, in
    the default pose nor with the legs spread."""
    spread = [(m, build_body(m, Pose(leg_spread=20.0), resolution=20)) for m in SPREAD[-5:]]
    for m, body in bodies + spread:
        keep = np.isin(body.face_part, [PART_NAMES.index(p) for p in ("torso", "thigh_l", "thigh_r")])
        union = trimesh.Trimesh(body.vertices, body.faces[keep], process=False)
        lines = trimesh.intersections.mesh_plane(union, [0.0, 1.0, 0.0], [0.0, body.levels["hips"] + 1e-9, 0.0])
        tape = ConvexHull(lines.reshape(-1, 3)[:, [0, 2]]).area * 100.0
        assert abs(tape - m.hips) < GIRTH_TOL_CM, (m, tape)


def test_default_pose_keeps_the_arms_off_the_torso():
    """In the default A-pose no forearm or hand vertex, and no upper-arm vertex below the ribs (half-way
    from chest to waist level), is inside the torso, even for a large belly (near the armpit the arm of a
    large chest touches the torso, as it does on real people)."""
    for m in SPREAD:
        body = build_body(m, resolution=12)
        torso = part_faces(body, "torso")
        for name in ("forearm_l", "upper_arm_l"):
            pts = body.vertices[np.unique(part_faces(body, name))]
            if name == "upper_arm_l":
                pts = pts[pts[:, 1] < 0.5 * (body.levels["chest"] + body.levels["waist"])]
            assert (winding_number(body.vertices, torso, pts) < 0.5).all(), (m, name)


def arm_press_mm(body) -> float:
    """How far (mm) the left arm goes into the torso below the chest: the deepest of its vertices there
    that are inside the torso (winding number), measured in the plane to the torso's horizontal section
    through it (trimesh's plane section; at least the distance to the surface)."""
    faces = part_faces(body, "torso")
    torso = trimesh.Trimesh(body.vertices, faces, process=False)
    pts = body.vertices[np.unique(np.concatenate([part_faces(body, "upper_arm_l"), part_faces(body, "forearm_l")]))]
    pts = pts[pts[:, 1] < body.levels["chest"]]
    deepest = 0.0
    for p in pts[winding_number(body.vertices, faces, pts) > 0.5]:
        seg = trimesh.intersections.mesh_plane(torso, [0.0, 1.0, 0.0], p)[:, :, [0, 2]]
        a, b, q = seg[:, 0], seg[:, 1], p[[0, 2]]
        t = np.clip(np.einsum("si,si->s", q - a, b - a) / np.maximum(np.einsum("si,si->s", b - a, b - a), 1e-18), 0, 1)
        deepest = max(deepest, float(np.linalg.norm(a + t[:, None] * (b - a) - q, axis=1).min()))
    return 1000.0 * deepest


@pytest.mark.parametrize("m", [SPREAD[0], Measurements(height=170, chest=96, waist=82, hips=100),
                               Measurements(height=185, chest=116, waist=104, hips=116)])
def test_hanging_arms_rest_against_the_torso_instead_of_passing_into_it(m):
    """Asked for arms hanging straight down (0 degrees), the body raises them to where they rest against the
    torso: below the chest they press at most ARM_PRESS into it (the medium body's went 40 mm into the chest
    and its hand 26 mm into the hip), and a degree lower they would press deeper. The built pose says so."""
    body = build_body(m, Pose(arm_angle=0.0), resolution=16)
    raised = body.pose["arm_angle_left"]
    assert 0.0 < raised < 30.0 and body.pose["arm_angle_right"] == raised
    assert body.pose == {**Pose().as_dict(), "arm_angle_left": raised, "arm_angle_right": raised}
    assert arm_press_mm(body) <= 1000.0 * ARM_PRESS + 1.0
    lower = build_body(m, Pose(arm_angle=raised - 1.0), resolution=16)
    assert lower.pose["arm_angle_left"] == pytest.approx(raised, abs=0.5)  # raised again to the same angle
    # the default A-pose is not raised for these bodies
    assert build_body(m, resolution=16).pose == Pose().as_dict() == {
        **{f"arm_angle_{s}": 30.0 for s in ("left", "right")}, **{f"leg_spread_{s}": 3.0 for s in ("left", "right")},
        **{f"{j}_{s}": 0.0 for j in ("arm_forward", "arm_rotation", "elbow_bend", "wrist_bend") for s in ("left", "right")}}


def test_optional_measurements_are_honoured():
    m = Measurements(height=180.0, chest=104.0, waist=92.0, hips=103.0, shoulder_width=42.0, arm_length=63.0,
                     inseam=86.0, neck=39.0, thigh=64.0, upper_arm=35.0)
    body = build_body(m)
    spread = build_body(m, Pose(arm_angle=70.0, elbow_bend=90.0, leg_spread=20.0))
    for b in (body, spread):
        for name in ("neck", "thigh", "upper_arm", "shoulder_width", "arm_length", "inseam"):
            assert abs(b.achieved[name] - getattr(m, name)) < 0.05, name
    assert body.estimated == {}


def test_missing_optional_measurements_are_estimated():
    m = Measurements(height=175.0, chest=100.0, waist=88.0, hips=100.0)
    full = complete(m)
    for name in OPTIONAL:
        lo, hi = MEASUREMENT_RANGES[name]
        assert lo <= getattr(full, name) <= hi
    # ANSUR II fit for an average man: biacromial ~40 cm, arm ~60 cm, crotch ~85 cm, neck ~37 cm
    assert full.shoulder_width == pytest.approx(40.3, abs=0.5)
    assert full.arm_length == pytest.approx(60.2, abs=0.5)
    assert full.inseam == pytest.approx(85.0, abs=0.5)
    assert set(build_body(m, resolution=10).estimated) == set(OPTIONAL)


def test_other_resolutions_are_exact_too():
    m = Measurements(height=158.0, chest=95.0, waist=99.0, hips=110.0)
    coarse = build_body(m, resolution=8)
    fine = build_body(m, resolution=45)
    assert len(coarse.vertices) < 1000 < 10000 < len(fine.vertices)
    for body in (coarse, fine):
        for name in ("chest", "waist", "hips", "height"):
            assert abs(body.achieved[name] - getattr(m, name)) < 1e-3


def test_build_refuses_out_of_range():
    with pytest.raises(ValueError, match=r"height=120 cm is outside \[140, 210\] cm"):
        build_body(Measurements(height=120.0, chest=100.0, waist=88.0, hips=100.0))
    with pytest.raises(ValueError, match="inseam/height"):
        build_body(Measurements(height=175.0, chest=100.0, waist=88.0, hips=100.0, inseam=100.0))
    with pytest.raises(ValueError, match="elbow_bend"):
        build_body(Measurements(height=175.0, chest=100.0, waist=88.0, hips=100.0), Pose(elbow_bend=170.0))


def test_default_resolution_is_about_ten_thousand_vertices(average):
    assert 9000 <= len(average.vertices) <= 11000
    assert DEFAULT_RESOLUTION == 30


# ---- mesh --------------------------------------------------------------------------------------------------

def test_deterministic():
    m, pose = SPREAD[0], Pose(arm_angle=40.0, elbow_bend=30.0, leg_spread=8.0)
    a, b = build_body(m, pose), build_body(m, pose)
    assert np.array_equal(a.vertices, b.vertices)
    assert np.array_equal(a.faces, b.faces)
    assert np.array_equal(a.maps.cell_faces, b.maps.cell_faces)
    assert a.achieved == b.achieved


def test_left_right_symmetric(average):
    v = average.vertices
    for left in ("upper_arm_l", "forearm_l", "thigh_l", "shin_l"):
        right = left[:-1] + "r"
        vl = v[np.unique(part_faces(average, left))]
        vr = v[np.unique(part_faces(average, right))]
        assert np.allclose(vl * [-1.0, 1.0, 1.0], vr, atol=1e-12)
    for name in ("torso", "head"):
        pts = v[np.unique(part_faces(average, name))]
        tree = trimesh.proximity.cKDTree(pts)
        dist, _ = tree.query(pts * [-1.0, 1.0, 1.0])
        assert dist.max() < 1e-9, name


def test_parts_are_closed_and_outward(average):
    """Every part is a closed surface (front and back share their seam vertices: no boundary edge), wound
    counter-clockwise from outside (positive volume), its face normals pointing away from its axis."""
    for k, name in enumerate(PART_NAMES):
        faces = part_faces(average, name)
        part = trimesh.Trimesh(average.vertices, faces, process=False)
        edges = np.sort(part.edges, axis=1)
        _, counts = np.unique(edges, axis=0, return_counts=True)
        assert (counts == 2).all(), (name, np.bincount(counts))
        assert part.volume > 0.0, name
        start, end = average.part_axes[k]
        axis = (end - start) / np.linalg.norm(end - start)
        centres = average.vertices[faces].mean(axis=1)
        rel = centres - start
        radial = rel - np.outer(rel @ axis, axis)
        outward = np.einsum("ij,ij->i", radial, average.face_normals[average.face_part == k]) > 0
        assert outward.mean() > 0.9, (name, outward.mean())


def cylinder_folds(body, k: int) -> np.ndarray:
    """Centres (m, 3) of part k's faces that fold over in the (theta, z) plane of the part's axis, i.e.
    where the surface is not a radial function r(theta, z) about the axis as a cylinder map assumes.
    Faces touching the poles (on the axis, theta undefined) are skipped."""
    faces = body.faces[body.face_part == k]
    start, end = body.part_axes[k]
    z = (end - start) / np.linalg.norm(end - start)
    ref = np.array([0.0, 0.0, 1.0]) if abs(z[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    x = ref - (ref @ z) * z
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    rel = body.vertices - start
    lx, ly, lz = rel @ x, rel @ y, rel @ z
    theta = np.arctan2(ly, lx)
    faces = faces[(np.hypot(lx, ly)[faces] > 1e-7).all(axis=1)]
    d1 = np.angle(np.exp(1j * (theta[faces[:, 1]] - theta[faces[:, 0]])))
    d2 = np.angle(np.exp(1j * (theta[faces[:, 2]] - theta[faces[:, 0]])))
    area = d1 * (lz[faces[:, 2]] - lz[faces[:, 0]]) - d2 * (lz[faces[:, 1]] - lz[faces[:, 0]])
    return body.vertices[faces[area <= 0]].mean(axis=1)


def test_parts_are_radial_about_their_axes(bodies):
    """Each section surrounds the part axis, so a ray from the axis meets the surface once (what the
    cylinder-map collision assumes); only under the sole, within 1 cm of the floor, the cap may fold."""
    posed = build_body(SPREAD[3], Pose(arm_angle=80.0, elbow_bend=110.0, leg_spread=18.0), resolution=20)
    for body in [b for _, b in bodies] + [posed]:
        for k, name in enumerate(PART_NAMES):
            folds = cylinder_folds(body, k)
            if name.startswith("shin"):
                folds = folds[folds[:, 1] > 0.01]
            assert len(folds) == 0, (name, folds[:3])


def test_normals_are_unit(average):
    assert np.allclose(np.linalg.norm(average.face_normals, axis=1), 1.0)
    assert np.allclose(np.linalg.norm(average.vertex_normals, axis=1), 1.0)
    assert average.faces.dtype == np.int32 and average.face_part.dtype == np.int16


def test_front_and_back_surfaces_meet_at_the_seams():
    """Evaluated as two separate NURBS surfaces, front and back coincide along both seams."""
    rng = np.random.default_rng(0)
    n = 5
    stations = nurbs.ring_controls(
        np.linspace(0.0, 1.0, n), rng.uniform(0.05, 0.2, n), rng.uniform(0.05, 0.2, n), rng.uniform(0.05, 0.2, n),
        rng.uniform(-0.02, 0.02, n), rng.uniform(-0.02, 0.02, n), rng.uniform(0.6, 0.9, n), rng.uniform(0.6, 0.9, n),
    )
    params = (0.0, 0.2, 0.5, 0.7, 1.0)
    data = np.concatenate([stations, nurbs.end_tangents(stations, params, 1.0)])  # (n + 2, 8, 4)
    rows = nurbs.station_matrix(params, tuple(np.linspace(0.0, 1.0, 9)))
    bu = nurbs.basis_matrix(np.linspace(0.0, 1.0, 7), nurbs.RING_KNOTS, nurbs.RING_DEGREE)

    def surface(columns):
        per_row = np.einsum("vn,nic->vic", rows, data[:, list(columns)])  # (n_v, 5, 4) homogeneous
        h = np.einsum("ui,vic->vuc", bu, per_row)  # Bu @ Pw @ Bv^T
        return h[..., :3] / h[..., 3:]

    front, back = surface(nurbs.FRONT_COLUMNS), surface(nurbs.BACK_COLUMNS)
    assert np.allclose(front[:, 0], back[:, -1], atol=1e-14)
    assert np.allclose(front[:, -1], back[:, 0], atol=1e-14)
    # the rows at station parameters are the stations' sections themselves (exact girths rely on it)
    sections = nurbs.sample_rings(stations, nurbs.ring_matrix(7))
    tube = nurbs.evaluate_tube(data, nurbs.station_matrix(params, params), nurbs.ring_matrix(7))
    assert np.allclose(tube, sections, atol=1e-14)


def test_elbow_and_knee_joints_have_no_holes():
    """Bent joints stay solid: points around the elbow and knee centres, at 70 % of the joint radius, are
    inside the union of the two parts that meet there."""
    m = Measurements(height=175.0, chest=100.0, waist=88.0, hips=100.0)
    body = build_body(m, Pose(arm_angle=45.0, elbow_bend=120.0, leg_spread=20.0), resolution=16)
    full = complete(m)
    dirs = np.random.default_rng(1).normal(size=(60, 3))
    dirs /= np.linalg.norm(dirs, axis=1)[:, None]
    for upper, lower, radius in (("upper_arm_l", "forearm_l", 0.82 * full.upper_arm / 200 / np.pi),
                                 ("thigh_l", "shin_l", 0.62 * full.thigh / 200 / np.pi)):
        start, end = body.part_axes[PART_NAMES.index(upper)]
        joint = end - 0.9 * radius * (end - start) / np.linalg.norm(end - start)  # the end cap is 0.9 r long
        pts = joint + 0.7 * radius * dirs
        inside = np.zeros(len(pts), bool)
        for name in (upper, lower):
            inside |= winding_number(body.vertices, part_faces(body, name), pts) > 0.5
        assert inside.all(), (upper, lower, (~inside).sum())


def test_hull_kernel_matches_scipy():
    rng = np.random.default_rng(5)
    for _ in range(50):
        pts = np.round(rng.normal(size=(int(rng.integers(3, 60)), 2)), 1)
        assert hull_perimeter_2d(pts) == pytest.approx(ConvexHull(pts).area, abs=1e-12)


# ---- collision maps ----------------------------------------------------------------------------------------

def test_obb_contains_its_part(average):
    maps = average.maps
    for k, name in enumerate(PART_NAMES):
        pts = average.vertices[np.unique(part_faces(average, name))]
        assert (pts @ maps.obb_normals[k].T <= maps.obb_offsets[k] + 1e-12).all(), name
        # grown by the margin: a point offset outward by the margin is still inside
        normals = average.vertex_normals[np.unique(part_faces(average, name))]
        grown = pts + 0.9 * maps.margin * normals
        assert (grown @ maps.obb_normals[k].T <= maps.obb_offsets[k] + 1e-12).all(), name


def cylinder_map_inside(body, k: int, points: np.ndarray) -> np.ndarray:
    """The paper's inside test through part k's cylinder map, in numpy (k, bool): cast the ray from the
    point's projection on the axis through the point, intersect the faces of the point's cell, inside iff
    the point is nearer the axis than the hit."""
    maps = body.maps
    rel = points - maps.cyl_origin[k]
    local = rel @ maps.cyl_axes[k].T
    r = np.hypot(local[:, 0], local[:, 1])
    n_theta, n_z = maps.cyl_shape[k]
    z0, z1 = maps.cyl_zrange[k]
    it = np.minimum(((np.arctan2(local[:, 1], local[:, 0]) + np.pi) / (2 * np.pi) * n_theta).astype(int), n_theta - 1)
    iz = np.clip(((local[:, 2] - z0) / (z1 - z0) * n_z).astype(int), 0, n_z - 1)
    inside = np.zeros(len(points), bool)
    for i, p in enumerate(points):
        cell = maps.cell_base[k] + it[i] * n_z + iz[i]
        tri = body.vertices[body.faces[maps.cell_faces[maps.cell_start[cell]:maps.cell_start[cell + 1]]]]
        origin = maps.cyl_origin[k] + local[i, 2] * maps.cyl_axes[k, 2]
        d = (p - origin) / r[i]
        e1, e2 = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]  # Moeller-Trumbore
        h = np.cross(d, e2)
        det = np.einsum("ij,ij->i", e1, h)
        s = origin - tri[:, 0]
        with np.errstate(divide="ignore", invalid="ignore"):
            u = np.einsum("ij,ij->i", s, h) / det
            q = np.cross(s, e1)
            v = (q @ d) / det
            t = np.einsum("ij,ij->i", e2, q) / det
        hit = (np.abs(det) > 1e-15) & (u >= -1e-9) & (v >= -1e-9) & (u + v <= 1 + 1e-9) & (t > 0)
        inside[i] = hit.any() and r[i] < t[hit].min()
    return inside


def test_cylinder_maps_tell_inside_from_outside(average):
    """5 mm inside the skin is inside, 5 mm outside is outside, for points all over every part, with the
    cylinder-map ray test the simulation uses (under the sole excepted, see the radial test)."""
    rng = np.random.default_rng(7)
    for k, name in enumerate(PART_NAMES):
        ids = np.unique(part_faces(average, name))
        ids = ids[average.vertices[ids, 1] > 0.01]
        ids = rng.choice(ids, size=min(60, len(ids)), replace=False)
        p, n = average.vertices[ids], average.vertex_normals[ids]
        assert cylinder_map_inside(average, k, p - 0.005 * n).all(), name
        assert not cylinder_map_inside(average, k, p + 0.005 * n).any(), name


def test_every_triangle_is_in_a_cylinder_cell_of_its_part(average):
    maps = average.maps
    cell_count = np.diff(maps.cell_start)
    cell_part = np.searchsorted(maps.cell_base, np.arange(len(cell_count)), side="right") - 1
    owner = np.repeat(cell_part, cell_count)
    listed = maps.cell_faces
    assert np.array_equal(np.unique(listed), np.arange(len(average.faces)))
    assert (average.face_part[listed] == owner).all()


# ---- API ---------------------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def client(tmp_path_factory):
    from fastapi.testclient import TestClient

    from tryon.api.app import create_app
    from tryon.config import Settings

    return TestClient(create_app(Settings(data_dir=tmp_path_factory.mktemp("body-api"))))


AVERAGE = {"height": 175, "chest": 100, "waist": 88, "hips": 100}


def test_api_builds_a_body(client):
    r = client.post("/api/bodies", json={"measurements": AVERAGE, "pose": {"arm_angle": 35}})
    assert r.status_code == 200, r.text
    data = r.json()
    v = np.array(data["vertices"])
    f = np.array(data["faces"])
    assert v.shape[1] == 3 and f.shape[1] == 3 and len(data["face_part"]) == len(f)
    assert data["parts"] == list(PART_NAMES)
    assert v[:, 1].min() == pytest.approx(0.0, abs=1e-5) and v[:, 1].max() == pytest.approx(1.75, abs=1e-4)
    meas = data["measurements"]
    assert meas["requested"] == {k: float(x) for k, x in AVERAGE.items()}
    for name in AVERAGE:
        assert abs(meas["achieved"][name] - AVERAGE[name]) < GIRTH_TOL_CM
    assert set(meas["levels"]) == {"chest", "waist", "hips"}
    assert 1.2 < meas["levels"]["chest"] < 1.3
    assert set(meas["estimated"]) == set(OPTIONAL)
    # the shorthand sets both sides; the answer gives every side field
    assert data["pose"]["requested"] == data["pose"]["achieved"] == Pose(arm_angle=35.0).as_dict()
    hanging = client.post("/api/bodies", json={"measurements": AVERAGE, "pose": {"arm_angle": 0}}).json()["pose"]
    for side in ("left", "right"):
        assert hanging["requested"][f"arm_angle_{side}"] == 0 and 5.0 < hanging["achieved"][f"arm_angle_{side}"] < 30.0


@pytest.mark.parametrize("payload, field, words", [
    ({"measurements": {**AVERAGE, "height": 100}}, "height", "[140, 210] cm"),
    ({"measurements": {**AVERAGE, "chest": 200}}, "chest", "[70, 150] cm"),
    ({"measurements": {**AVERAGE, "thigh": 20}}, "thigh", "[40, 100] cm"),
    ({"measurements": AVERAGE, "pose": {"arm_angle": 120}}, "arm_angle", "[0, 90] degrees"),
    ({"measurements": AVERAGE, "pose": {"leg_spread": -5}}, "leg_spread", "[0, 20] degrees"),
])
def test_api_refuses_out_of_range(client, payload, field, words):
    r = client.post("/api/bodies", json=payload)
    assert r.status_code == 422
    detail = r.json()["detail"][0]
    assert detail["loc"][-1] == field
    assert field in detail["msg"] and words in detail["msg"]


@pytest.mark.parametrize("text, field, words", [
    ('{"measurements": {"height": NaN, "chest": 100, "waist": 88, "hips": 100}}', "height", "finite"),
    ('{"measurements": {"height": 1e400, "chest": 100, "waist": 88, "hips": 100}}', "height", "finite"),
    ('{"measurements": {"height": 175, "chest": 100, "waist": 88, "hips": 100, "neck": Infinity}}', "neck",
     "finite"),
    ('{"measurements": {"height": 175, "chest": 100, "waist": 88, "hips": 100}, "pose": {"arm_angle": -Infinity}}',
     "arm_angle", "finite"),
])
def test_api_refuses_non_finite_numbers(client, text, field, words):
    """Python's json reads NaN / Infinity / 1e400: a 422 naming the field (was a 500: the error echoed NaN)."""
    r = client.post("/api/bodies", content=text, headers={"content-type": "application/json"})
    assert r.status_code == 422, r.text
    detail = r.json()["detail"][0]
    assert detail["loc"][-1] == field and words in detail["msg"]


@pytest.mark.parametrize("payload, field, words", [
    ({"measurements": {**AVERAGE, "height": True}}, "height", "measurements.height must be a number (cm), got true"),
    ({"measurements": {**AVERAGE, "chest": "100"}}, "chest", 'measurements.chest must be a number (cm), got "100"'),
    ({"measurements": AVERAGE, "pose": {"arm_angle": "45"}}, "arm_angle", 'pose.arm_angle must be a number'),
])
def test_api_refuses_booleans_and_strings_as_numbers(client, payload, field, words):
    """JSON true was read as 1 (and refused as 'outside [140, 210]'), "170" as 170: both are a client's mistake."""
    r = client.post("/api/bodies", json=payload)
    assert r.status_code == 422
    detail = r.json()["detail"][0]
    assert detail["loc"][-1] == field and words in detail["msg"], detail


def test_api_refuses_implausible_combinations(client):
    r = client.post("/api/bodies", json={"measurements": {**AVERAGE, "inseam": 105}})
    assert r.status_code == 422
    assert "inseam/height" in r.json()["detail"][0]["msg"]
    r = client.post("/api/bodies", json={"measurements": {**AVERAGE, "waist": 140, "chest": 80}})
    assert r.status_code == 422 and "waist/chest" in r.json()["detail"][0]["msg"]
    r = client.post("/api/bodies", json={"measurements": {"height": 175, "chest": 100, "waist": 88}})
    assert r.status_code == 422 and r.json()["detail"][0]["loc"][-1] == "hips"


def test_api_glb_loads_in_trimesh(client):
    r = client.post("/api/bodies?format=glb", json={"measurements": AVERAGE, "resolution": 12})
    assert r.status_code == 200 and r.headers["content-type"] == "model/gltf-binary"
    mesh = trimesh.load(io.BytesIO(r.content), file_type="glb", force="mesh", process=False)
    body = build_body(Measurements(**AVERAGE), resolution=12)
    assert mesh.vertices.shape == body.vertices.shape
    assert np.allclose(mesh.vertices, body.vertices, atol=1e-6)


def test_api_ranges(client):
    r = client.get("/api/bodies/ranges")
    assert r.status_code == 200
    data = r.json()
    assert set(data["measurements"]) == set(MEASUREMENT_RANGES)
    assert data["measurements"]["height"]["min"] == 140 and data["measurements"]["height"]["required"]
    assert data["measurements"]["inseam"]["default"] is None
    assert data["pose"]["arm_angle_left"]["default"] == Pose().arm_angle_left
    assert data["pose"]["arm_angle"]["default"] is None  # the shorthand: both sides at once
    assert set(data["estimated_defaults"]) == set(OPTIONAL)
