"""build_part_maps: OBBs contain their parts, every face sits in the cells its points fall in."""

from __future__ import annotations

import numpy as np
import pytest

from tryon.body.maps import build_part_maps
from tryon.bench.synthetic import stick_body


@pytest.fixture(scope="module")
def body():
    return stick_body(n_around=32)


def _cells_of(maps, points, k):
    loc = (points - maps.cyl_origin[k]) @ maps.cyl_axes[k].T
    theta = np.arctan2(loc[:, 1], loc[:, 0])
    n_theta, n_z = maps.cyl_shape[k, 0], maps.cyl_shape[k, 1]
    it = np.minimum(np.floor((theta + np.pi) / (2 * np.pi) * n_theta).astype(int), n_theta - 1)
    z0, z1 = maps.cyl_zrange[k]
    iz = np.clip(np.floor((loc[:, 2] - z0) / (z1 - z0) * n_z).astype(int), 0, n_z - 1)
    return maps.cell_base[k] + it * n_z + iz


def test_every_point_of_a_face_is_in_a_cell_listing_it(body):
    maps = body.maps
    rng = np.random.default_rng(1)
    faces = rng.integers(0, len(body.faces), 5000)
    w = rng.dirichlet([1, 1, 1], len(faces))
    pts = np.einsum("nj,njk->nk", w, body.vertices[body.faces[faces]])
    parts = body.face_part[faces]
    for k in np.unique(parts):
        sel = parts == k
        cells = _cells_of(maps, pts[sel], k)
        for c, f in zip(cells, faces[sel]):
            assert f in maps.cell_faces[maps.cell_start[c]:maps.cell_start[c + 1]]


def test_points_offset_by_less_than_the_margin_stay_covered(body):
    maps = build_part_maps(body.vertices, body.faces, body.face_part, body.part_axes, 0.01)
    rng = np.random.default_rng(2)
    faces = rng.integers(0, len(body.faces), 3000)
    w = rng.dirichlet([1, 1, 1], len(faces))
    pts = np.einsum("nj,njk->nk", w, body.vertices[body.faces[faces]]) + 0.009 * body.face_normals[faces]
    parts = body.face_part[faces]
    missing = 0
    for k in np.unique(parts):
        sel = parts == k
        for c, f in zip(_cells_of(maps, pts[sel], k), faces[sel]):
            missing += f not in maps.cell_faces[maps.cell_start[c]:maps.cell_start[c + 1]]
    assert missing == 0


def test_obb_contains_its_part_grown_by_the_margin(body):
    maps = body.maps
    for k in range(len(body.parts)):
        v = np.unique(body.faces[body.face_part == k])
        pts = body.vertices[v] + 0.99 * maps.margin * body.vertex_normals[v]
        assert np.all(pts @ maps.obb_normals[k].T <= maps.obb_offsets[k] + 1e-12)
        # and the box is tight: some vertex within the margin of each face of the box
        slack = maps.obb_offsets[k] - (body.vertices[v] @ maps.obb_normals[k].T).max(axis=0)
        assert np.all(slack <= maps.margin + 1e-9)


def test_obb_corners_normals_offsets_agree(body):
    maps = body.maps
    for k in range(len(body.parts)):
        n = maps.obb_normals[k]
        assert np.allclose(np.linalg.norm(n, axis=1), 1.0)
        # every corner lies on exactly three of the six planes, inside the others
        s = maps.obb_corners[k] @ n.T - maps.obb_offsets[k]
        assert np.all(s <= 1e-9)
        assert np.all((np.abs(s) < 1e-9).sum(axis=1) == 3)


def test_frames_are_right_handed_with_z_along_the_axis(body):
    maps = body.maps
    for k in range(len(body.parts)):
        a = maps.cyl_axes[k]
        assert np.allclose(a @ a.T, np.eye(3), atol=1e-12)
        assert np.isclose(np.linalg.det(a), 1.0)
        d = body.part_axes[k, 1] - body.part_axes[k, 0]
        assert np.allclose(a[2], d / np.linalg.norm(d))


def test_cell_ids_match_the_layout(body):
    maps = body.maps
    sizes = maps.cyl_shape[:, 0] * maps.cyl_shape[:, 1]
    assert np.array_equal(maps.cell_base, np.concatenate([[0], np.cumsum(sizes)[:-1]]))
    assert len(maps.cell_start) == sizes.sum() + 1
    assert maps.cell_start[-1] == len(maps.cell_faces)
    assert np.all(np.diff(maps.cell_start) >= 0)
    # each listed face belongs to the part owning the cell
    owner = np.repeat(np.arange(len(sizes)), sizes)
    cell_of_entry = np.repeat(np.arange(sizes.sum()), np.diff(maps.cell_start))
    assert np.array_equal(body.face_part[maps.cell_faces], owner[cell_of_entry])


def test_theta_wraps_around():
    """A face straddling theta = +-pi is listed in the first and the last sector."""
    from tryon.bench.synthetic import capped_cylinder

    v, f = capped_cylinder([0, 0, 0], [0, 1, 0], 0.1, n_around=7, n_along=2)
    maps = build_part_maps(v, f, np.zeros(len(f), np.int16), np.array([[[0, 0, 0], [0, 1, 0]]], float), 0.002)
    n_theta, n_z = maps.cyl_shape[0]
    first = set(maps.cell_faces[maps.cell_start[n_z // 2]:maps.cell_start[n_z // 2 + 1]])
    last = set(maps.cell_faces[maps.cell_start[(n_theta - 1) * n_z + n_z // 2]:maps.cell_start[(n_theta - 1) * n_z + n_z // 2 + 1]])
    assert first & last  # the face across the seam is in both end sectors


def test_rebuilding_the_parts_that_changed_gives_the_maps_of_a_full_build():
    """A re-posed limb changing shape (``rebuild_part_maps``): only its parts built again, the others copied from
    the maps of the body as built, and the arrays are those of a full ``build_part_maps`` of the new shape."""
    from tryon.body.build import build_body
    from tryon.body.maps import build_part_maps, rebuild_part_maps
    from tryon.body.params import Measurements, Pose

    body = build_body(Measurements(height=170, chest=96, waist=82, hips=100), Pose(), resolution=16)
    arms = [body.parts.index(name) for name in ("upper_arm_l", "forearm_l", "forearm_r")]
    rng = np.random.default_rng(5)
    moved = np.isin(body.vertex_part, arms)
    for scale in (0.002, 0.03):  # a hand turning a little, a lot (the cells' count along the axis changes)
        vertices = body.vertices.copy()
        vertices[moved] += rng.normal(0.0, scale, (moved.sum(), 3)) + [0.0, -scale, 0.0]
        full = build_part_maps(vertices, body.faces, body.face_part, body.part_axes, body.maps.margin)
        part = rebuild_part_maps(body.maps, vertices, body.faces, body.face_part, body.part_axes, np.array(arms))
        for name in full.__dataclass_fields__:
            assert np.array_equal(getattr(full, name), getattr(part, name)), name
