"""Triangle collapse with mark recovery: B respected, shape, holes and orientation kept, re-attachment."""

import math

import numpy as np
import pytest
import scipy.sparse
import scipy.sparse.csgraph

from tryon.garment.generate import garment_mesh
from tryon.garment.ingest import CleanMesh
from tryon.garment.prepare import prepare, triangle_areas
from tryon.garment.simplify import collapse_faces, collapse_with_parents
from tryon.geometry import vertex_normals


def boundary_loops(faces: np.ndarray, n: int) -> list[int]:
    """Vertex counts of the boundary loops, sorted."""
    e = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    u, c = np.unique(e, axis=0, return_counts=True)
    b = u[c == 1]
    if len(b) == 0:
        return []
    g = scipy.sparse.coo_matrix((np.ones(len(b)), (b[:, 0], b[:, 1])), shape=(n, n))
    _, label = scipy.sparse.csgraph.connected_components(g, directed=False)
    return sorted(np.bincount(np.unique(label[np.unique(b)], return_inverse=True)[1]).tolist())


def flat_grid(n: int, spacing: float = 0.01):
    xs, ys = np.meshgrid(np.arange(n + 1), np.arange(n + 1))
    v = np.column_stack([xs.ravel(), ys.ravel(), np.zeros(xs.size)]) * spacing
    f = []
    for j in range(n):
        for i in range(n):
            a, b = j * (n + 1) + i, j * (n + 1) + i + 1
            f += [[a, b, b + n + 1], [a, b + n + 1, a + n + 1]]
    return v, np.array(f)


@pytest.fixture(scope="module")
def tshirt():
    m = garment_mesh("tshirt", "M")
    return np.asarray(m.vertices, float), np.asarray(m.faces, np.int64)


@pytest.fixture(scope="module")
def tshirt_model(tshirt):
    v, f = tshirt
    mesh = CleanMesh(vertices=v, faces=f.astype(np.int32), units="m", units_guessed=False)
    return prepare(mesh, id="t", name="t", category="top", size="M", source_sha256="", source_name="t.obj",
                   simplification=0.3, density=0.15)


@pytest.mark.parametrize("B", [0.2, 0.3, 0.5])
def test_degree_B_respected_and_kept_are_original_vertices(tshirt, B):
    v, f = tshirt
    kept, coarse = collapse_faces(f, len(v), B, v)
    n = len(v)
    assert len(kept) <= math.floor(B * n) + 2 - 0  # each collapse removes two vertices
    assert len(kept) >= math.floor(B * n) - 2
    assert kept.dtype == np.int32 and coarse.dtype == np.int32
    assert len(np.unique(kept)) == len(kept) and kept.min() >= 0 and kept.max() < n
    assert np.array_equal(np.unique(coarse), np.arange(len(kept)))  # every kept vertex is used


def test_paper_rule_without_geometry_reaches_B():
    v, f = flat_grid(30)
    kept, coarse = collapse_faces(f, len(v), 0.25)
    assert len(kept) <= 0.25 * len(v) + 2
    assert len(coarse) > 0


def test_B_one_keeps_everything(tshirt):
    v, f = tshirt
    kept, coarse = collapse_faces(f, len(v), 1.0, v)
    assert len(kept) == len(v) and len(coarse) == len(f)


def test_mark_recovery_spreads_kept_vertices_evenly():
    v, f = flat_grid(40, spacing=0.01)
    kept, _ = collapse_faces(f, len(v), 0.3, v)
    # distance from each original vertex to the nearest kept one: with 30% kept evenly, about
    # 1/sqrt(0.3) = 1.8 spacings apart, so nobody should be more than ~3 spacings from a kept vertex
    d = np.linalg.norm(v[:, None, :2] - v[kept][None, :, :2], axis=2).min(axis=1)
    assert d.max() <= 0.03 + 1e-9
    assert d.mean() < 0.01


def test_no_degenerate_duplicate_or_flipped_faces(tshirt):
    v, f = tshirt
    kept, coarse = collapse_faces(f, len(v), 0.3, v)
    cv = v[kept]
    assert (coarse[:, 0] != coarse[:, 1]).all() and (coarse[:, 1] != coarse[:, 2]).all()
    assert (coarse[:, 0] != coarse[:, 2]).all()
    assert len(np.unique(np.sort(coarse, axis=1), axis=0)) == len(coarse)
    assert triangle_areas(cv, coarse).min() > 1e-7  # m^2: no zero-area face
    # each face the collapse changed faces the same way as the original surface at its corners (faces
    # it left alone are the source's own; at the sharp A-pose armpit crease a vertex normal is moot)
    vn = vertex_normals(v, f)[kept]
    n = np.cross(cv[coarse[:, 1]] - cv[coarse[:, 0]], cv[coarse[:, 2]] - cv[coarse[:, 0]])
    original = {tuple(t) for t in np.sort(f, axis=1)}
    changed = np.array([tuple(t) not in original for t in np.sort(kept[coarse], axis=1)])
    assert changed.sum() > 0.5 * len(coarse)
    assert (np.einsum("ij,ij->i", n, vn[coarse].sum(axis=1))[changed] > 0).all()
    # manifold and consistently wound: every edge at most twice, once in each direction
    directed = np.concatenate([coarse[:, [0, 1]], coarse[:, [1, 2]], coarse[:, [2, 0]]])
    assert len(np.unique(directed, axis=0)) == len(directed)


def test_openings_stay_open(tshirt):
    v, f = tshirt
    before = boundary_loops(f, len(v))
    kept, coarse = collapse_faces(f, len(v), 0.3, v)
    after = boundary_loops(coarse, len(kept))
    assert len(before) == len(after) == 4  # neck, hem, two cuffs
    for b, a in zip(before, after):
        assert math.ceil(math.sqrt(0.3) * b) <= a <= b


def test_coarse_mesh_keeps_the_shape(tshirt, tshirt_model):
    v, _ = tshirt
    cv = tshirt_model.coarse_vertices
    assert np.allclose(cv.min(axis=0), v.min(axis=0), atol=0.02)
    assert np.allclose(cv.max(axis=0), v.max(axis=0), atol=0.02)
    # every original vertex lies within 1.5 cm of the coarse surface
    assert np.abs(tshirt_model.attach_offset).max() < 0.015


def test_expand_reproduces_the_rest_mesh(tshirt_model):
    m = tshirt_model
    full = m.expand(m.coarse_vertices)
    assert np.abs(full - m.vertices).max() < 1e-6  # m (target: 1 mm)
    kept = m.coarse_index
    assert np.allclose(m.attach_offset[kept], 0.0)
    assert np.allclose(np.sort(m.attach_bary[kept], axis=1), [0, 0, 1])
    # attach faces are really faces containing the kept vertex
    corner = m.coarse_index[m.coarse_faces[m.attach_face[kept]]]
    assert (corner == kept[:, None]).any(axis=1).all()
    # barycentric coordinates stay near the face (nearest face chosen)
    assert m.attach_bary.min() > -1.0 and m.attach_bary.max() < 2.0


def test_expand_follows_a_rigid_motion(tshirt_model):
    m = tshirt_model
    c, s = np.cos(0.4), np.sin(0.4)
    rot = np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    moved = m.coarse_vertices @ rot.T + [0.1, 0.2, 0.3]
    assert np.allclose(m.expand(moved), m.vertices @ rot.T + [0.1, 0.2, 0.3], atol=1e-9)


def test_masses_sum_to_density_times_area(tshirt, tshirt_model):
    v, f = tshirt
    area = triangle_areas(v, f).sum()
    assert tshirt_model.mass.sum() == pytest.approx(0.15 * area, rel=1e-9)
    assert (tshirt_model.mass > 0).all()
    assert len(tshirt_model.mass) == len(tshirt_model.coarse_index)


def test_model_contract_types(tshirt_model):
    m = tshirt_model
    for name in ("faces", "coarse_index", "coarse_faces", "springs", "attach_face"):
        assert getattr(m, name).dtype == np.int32, name
    assert m.kind.dtype == np.int8
    assert set(m.meta.springs) == {"structural", "shear", "bending"}
    assert all(c > 0 for c in m.meta.springs.values())
    assert m.springs.max() < len(m.coarse_index)


def test_parents_point_to_kept_vertices(tshirt):
    v, f = tshirt
    kept, _, root = collapse_with_parents(f, len(v), 0.3, v)
    assert np.isin(root, kept).all()
    assert np.array_equal(root[kept], kept)


def two_piece_outfit():
    """A generated skirt (first in face order, as in a MakeHuman outfit) and a long-sleeve top above it,
    as one mesh of two separate pieces; returns vertices, faces and each vertex's piece (0 skirt, 1 top)."""
    skirt, top = garment_mesh("skirt", "M"), garment_mesh("longsleeve", "M")
    vs, vt = np.asarray(skirt.vertices, float), np.asarray(top.vertices, float)
    vs = vs + [0.0, vt[:, 1].min() - 0.05 - vs[:, 1].max(), 0.0]  # the skirt's waist 5 cm under the top's hem
    v = np.vstack([vs, vt])
    f = np.vstack([np.asarray(skirt.faces, np.int64), np.asarray(top.faces, np.int64) + len(vs)])
    piece = np.repeat([0, 1], [len(vs), len(vt)])
    return v, f, piece


@pytest.mark.parametrize("B", [0.2, 0.3])
def test_each_piece_keeps_its_share(B):
    v, f, piece = two_piece_outfit()
    kept, coarse = collapse_faces(f, len(v), B, v)
    for p in (0, 1):
        n = int((piece == p).sum())
        k = int((piece[kept] == p).sum())
        assert math.floor(B * n) - 1 <= k <= math.floor(B * n), (p, n, k)  # one collapse removes two
    # the pieces stay apart and every opening stays open (skirt: waist, hem; top: neck, hem, two cuffs)
    assert (piece[kept][coarse] == piece[kept][coarse][:, :1]).all()
    assert len(boundary_loops(coarse, len(kept))) == len(boundary_loops(f, len(v))) == 6


def test_one_piece_result_does_not_depend_on_another_piece_beside_it():
    """A piece is simplified exactly as it would be alone."""
    v, f, piece = two_piece_outfit()
    alone_v, alone_f = v[piece == 1], f[piece[f[:, 0]] == 1] - int((piece == 0).sum())
    kept_alone, coarse_alone = collapse_faces(alone_f, len(alone_v), 0.3, alone_v)
    kept, _ = collapse_faces(f, len(v), 0.3, v)
    assert np.array_equal(kept[piece[kept] == 1] - int((piece == 0).sum()), kept_alone)


def jittered_tube(n_around: int = 18, n_along: int = 30, radius: float = 0.046, length: float = 0.5, seed: int = 2):
    """An open tube (a trouser leg 29 cm round, 18 points round its hems), its points shifted round at random and
    its quads cut either way: an irregular mesh like a real garment's, not the generator's even rings."""
    rng = np.random.default_rng(seed)
    step = 2.0 * np.pi / n_around
    v = []
    for j in range(n_along + 1):
        turn = np.arange(n_around) * step + rng.uniform(-0.4, 0.4, n_around) * step
        v += [[radius * math.cos(t), -j * length / n_along, radius * math.sin(t)] for t in turn]
    f = []
    for j in range(n_along):
        for i in range(n_around):
            p, q = j * n_around + i, j * n_around + (i + 1) % n_around
            r, s = p + n_around, q + n_around
            f += [[p, q, s], [p, s, r]] if rng.random() < 0.5 else [[p, q, r], [q, s, r]]
    return np.array(v), np.array(f, dtype=np.int64)


def test_an_opening_keeps_no_coarse_edge_a_limb_could_pass_through():
    # collapsed unevenly, a hem of ten coarse points had chords of 8 cm among 1 cm ones, and a 7 cm shin went
    # through one (a MakeHuman trouser leg on a 178.5 cm ANSUR body); here the same kind of irregular tube had
    # a hem chord of 22 % of the hem's length before the rule, and keeps every one under an eighth now
    v, f = jittered_tube()
    kept, coarse = collapse_faces(f, len(v), 0.3, v)
    for ring in (np.arange(18), np.arange(18) + 30 * 18):  # the two hems, in order round
        length = np.linalg.norm(v[np.roll(ring, -1)] - v[ring], axis=1).sum()
        on = ring[np.isin(ring, kept)]
        assert len(on) >= math.ceil(math.sqrt(0.3) * len(ring))
        chords = np.linalg.norm(v[np.roll(on, -1)] - v[on], axis=1)
        assert chords.max() <= length / 8 + 1e-12, chords.max() / length


def seamed_tube(n_around: int = 24, n_along: int = 30, radius: float = 0.05, length: float = 0.4,
                gaps: tuple = (1e-4, 3e-4)):
    """An open tube of even rings 1.3 cm apart, with two more rings 0.1 and 0.4 mm under its top: a sleeve's
    first rows blending out of its armhole, as the generator makes them on a fine grid."""
    ys = list(-np.arange(n_along + 1) * length / n_along)
    ys = [ys[0]] + [ys[0] - g for g in np.cumsum(gaps)] + ys[1:]
    turn = np.arange(n_around) * 2 * np.pi / n_around
    v = np.array([[radius * math.cos(t), y, radius * math.sin(t)] for y in ys for t in turn])
    f = []
    for j in range(len(ys) - 1):
        for i in range(n_around):
            p, q = j * n_around + i, j * n_around + (i + 1) % n_around
            f += [[p, q, q + n_around], [p, q + n_around, p + n_around]]
    return v, np.array(f, dtype=np.int64)


def edge_ratios(v, kept, coarse):
    """Every coarse edge's length over the median coarse edge (each interior edge twice)."""
    corners = v[kept[coarse]]
    length = np.linalg.norm(corners - np.roll(corners, -1, axis=1), axis=2).ravel()
    return length / np.median(length)


def test_no_coarse_edge_is_far_shorter_than_the_others(monkeypatch):
    # the paper's collapse takes faces in order, so rows 0.1 mm apart outlived it (a fine T-shirt's 182 springs
    # under 1 mm among 7.8 mm ones, stretched 10-16x every step); they are welded now
    import tryon.garment.weld as weld

    v, f = seamed_tube()
    monkeypatch.setattr(weld, "SHORT_EDGE", 0.0)
    kept, coarse, _ = collapse_with_parents(f, len(v), 0.3, v)
    assert edge_ratios(v, kept, coarse).min() < 0.01  # without the weld: the rows are still there
    monkeypatch.undo()
    kept, coarse, root = collapse_with_parents(f, len(v), 0.3, v)
    assert edge_ratios(v, kept, coarse).min() >= weld.SHORT_EDGE
    assert np.isin(root, kept).all()  # every original vertex attached to a kept one
    assert len(boundary_loops(coarse, len(kept))) == 2  # both openings still open
    edges = np.sort(np.concatenate([coarse[:, [0, 1]], coarse[:, [1, 2]], coarse[:, [2, 0]]]), axis=1)
    assert np.unique(edges, axis=0, return_counts=True)[1].max() <= 2  # no pinch
    assert (np.diff(np.sort(coarse, axis=1), axis=1) > 0).all()  # no degenerate face


def test_a_mesh_without_short_edges_is_not_welded(tshirt):
    import tryon.garment.weld as weld

    v, f = tshirt
    kept, coarse, root = collapse_with_parents(f, len(v), 0.3, v)
    assert edge_ratios(v, kept, coarse).min() > 2 * weld.SHORT_EDGE  # the catalogue's meshes: nothing to weld
    nowhere = np.zeros(len(v), bool)
    assert weld.weld_short_edges(v, kept, coarse, root, nowhere, nowhere)[0] is kept
