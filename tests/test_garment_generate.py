"""The catalogue's generated garments: real sizes, placement as worn, topology, committed files."""

import io
import json
import math
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse
import scipy.sparse.csgraph
import trimesh
from scipy.spatial import ConvexHull

from tryon.garment.generate import GARMENTS, SHOULDER_JOINT, SIZE_CHART, garment_mesh, write_catalogue

REPO_GARMENTS = Path(__file__).resolve().parents[1] / "garments"
LOOPS = {"tshirt": 4, "longsleeve": 4, "dress": 4, "skirt": 2, "trousers": 3, "shorts": 3}


@pytest.fixture(scope="module")
def meshes() -> dict:
    return {(k, s): garment_mesh(k, s) for k in GARMENTS for s in SIZE_CHART}


def loops(mesh: trimesh.Trimesh) -> list[np.ndarray]:
    """Boundary loops as arrays of vertex ids."""
    e = mesh.edges_sorted
    u, c = np.unique(e, axis=0, return_counts=True)
    b = u[c == 1]
    n = len(mesh.vertices)
    g = scipy.sparse.coo_matrix((np.ones(len(b)), (b[:, 0], b[:, 1])), shape=(n, n))
    _, label = scipy.sparse.csgraph.connected_components(g, directed=False)
    on = np.unique(b)
    return [on[label[on] == lab] for lab in np.unique(label[on])]


def girth(mesh: trimesh.Trimesh, y: float) -> float:
    """Tape-measure girth (convex hull perimeter, m) of the body's section at height y: the section
    loop around x = z = 0 (not the sleeves')."""
    from matplotlib.path import Path as PolyPath

    section = mesh.section(plane_origin=[0, y, 0], plane_normal=[0, 1, 0])
    for loop in section.discrete:
        xz = loop[:, [0, 2]]
        if PolyPath(xz).contains_point((0.0, 0.0)):
            return ConvexHull(xz).area  # in 2-D, "area" is the perimeter
    raise AssertionError(f"no section loop around the axis at y = {y}")


def test_vertex_counts_and_units(meshes):
    for (kind, size), m in meshes.items():
        assert 2000 <= len(m.vertices) <= 8000, (kind, size, len(m.vertices))
        assert m.bounds[0, 1] >= 0.0 and m.bounds[1, 1] <= 1.5  # metres, feet on y = 0


def test_topology_is_a_closed_around_tube(meshes):
    for (kind, size), m in meshes.items():
        assert m.is_winding_consistent, (kind, size)
        assert len(loops(m)) == LOOPS[kind], (kind, size)
        assert len(m.split(only_watertight=False)) == 1
        edges, counts = np.unique(m.edges_sorted, axis=0, return_counts=True)
        assert counts.max() == 2  # manifold
        # Euler characteristic of a sphere with h holes: 2 - h
        assert m.euler_number == 2 - LOOPS[kind]
        # normals point outwards (away from the vertical axis through the garment) on average
        radial = m.triangles_center - m.vertices.mean(axis=0)
        radial[:, 1] = 0
        assert np.einsum("ij,ij->", m.face_normals, radial) > 0


def test_quads_split_3dmax_style(meshes):
    m = meshes[("skirt", "M")]
    tri = m.vertices[m.faces]
    # angle at v1 is a right angle (a quad of the grid split along v2 v0)
    u, w = tri[:, 0] - tri[:, 1], tri[:, 2] - tri[:, 1]
    cos = np.einsum("ij,ij->i", u, w) / np.linalg.norm(u, axis=1) / np.linalg.norm(w, axis=1)
    assert np.median(np.abs(cos)) < 0.1


@pytest.mark.parametrize("size,chest", [("S", 88), ("M", 96), ("L", 104), ("XL", 112), ("XXL", 120)])
def test_tshirt_chest_girth_has_ease(meshes, size, chest):
    g = girth(meshes[("tshirt", size)], 1.20)  # just under the armpits (1.21 m)
    assert g * 100 == pytest.approx(chest + 8, abs=1.5)  # cm: ease of 8 cm over the body's chest


def test_trouser_waist_and_hems(meshes):
    m = meshes[("trousers", "M")]
    assert girth(m, 1.04) * 100 == pytest.approx(SIZE_CHART["M"]["waist"] + 4, abs=2.0)
    hems = sorted(loops(m), key=lambda lp: m.vertices[lp, 1].mean())[:2]
    for hem in hems:
        assert m.vertices[hem, 1].mean() == pytest.approx(0.05, abs=0.01)
    xs = sorted(m.vertices[h, 0].mean() for h in hems)
    assert xs[0] < -0.05 and xs[1] > 0.05  # one leg each side


def test_placed_as_worn_facing_plus_z(meshes):
    m = meshes[("tshirt", "M")]
    neck = max(loops(m), key=lambda lp: m.vertices[lp, 1].mean())
    lowest = neck[np.argmin(m.vertices[neck, 1])]
    assert m.vertices[lowest, 2] > 0  # the front neckline dips lower than the back: front is +z
    assert m.vertices[:, 1].max() == pytest.approx(1.45, abs=0.02)  # neck base of a 1.70 m person


@pytest.mark.parametrize("kind", ["tshirt", "longsleeve"])
def test_sleeves_point_down_and_out_in_an_a_pose(meshes, kind):
    m = meshes[(kind, "M")]
    cuffs = [lp for lp in loops(m) if abs(m.vertices[lp, 0].mean()) > 0.15]
    assert len(cuffs) == 2
    centres = sorted((m.vertices[c].mean(axis=0) for c in cuffs), key=lambda c: c[0])
    for side, c in zip((-1, 1), centres):
        assert np.sign(c[0]) == side  # left arm towards +x
        dx, dy = abs(c[0]) - SHOULDER_JOINT[0], SHOULDER_JOINT[1] - c[1]
        assert math.degrees(math.atan2(dx, dy)) == pytest.approx(27.0, abs=4.0)


def test_no_garment_passes_through_itself(meshes):
    """Every size of every style is made without its cloth crossing itself (the written OBJ, rounded to 0.1 mm,
    as the catalogue ingests it): a large size's two trouser or shorts legs do not overlap below the crotch
    (before: trousers L-XXL, shorts M-XXL), and a wide top's sleeve, started outside the armpit, comes back onto
    the arm gently enough that its first rows stay out of the body tube (before: the T-shirt and long-sleeve
    XXL, 36 and 30 edges through)."""
    from tryon.garment.generate import obj_text
    from tryon.sim.collision.crossings import self_intersections

    crossed = {}
    for key, m in meshes.items():
        rounded = trimesh.load(io.StringIO(obj_text(m, "")), file_type="obj", process=False)
        n = self_intersections(np.asarray(rounded.vertices), np.asarray(rounded.faces))
        if n:
            crossed[key] = n
    assert crossed == {}


def test_committed_files_match_the_generator(tmp_path):
    entries = write_catalogue(tmp_path)
    listed = json.loads((REPO_GARMENTS / "catalogue.json").read_text())
    assert listed == entries
    assert len(entries) == len(SIZE_CHART) * len(GARMENTS)
    assert {e["category"] for e in entries} == {"top", "bottom", "dress"}
    for e in entries:
        assert set(e) == {"file", "name", "category", "style", "size", "chart", "fabric", "units"}
        assert e["fabric"] == {"top": "jersey", "dress": "jersey", "bottom": "cotton-twill"}[e["category"]]
        assert (REPO_GARMENTS / e["file"]).read_bytes() == (tmp_path / e["file"]).read_bytes(), e["file"]
    assert sum((REPO_GARMENTS / e["file"]).stat().st_size for e in entries) < 10_000_000
