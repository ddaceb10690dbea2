"""Cloth on cloth (issue 29): the layer push on constructed tubes, the layer depths with a known number of
crossing vertices, self-intersections counted on sheets that do and do not cross."""

from __future__ import annotations

import numpy as np
import pytest

from tryon.geometry import closest_uv_on_triangle
from tryon.sim.collision.cloth import (
    PAST_EDGE, build_tri_grid, face_sides, nearest_over, push_layer, signed_face_normals,
)
from tryon.sim.collision.crossings import layer_depths, self_intersections


def tube(radius: float, n_around: int = 40, n_along: int = 20, height: float = 0.5, y0: float = 0.0):
    """An open tube round the y axis: vertices (n_around * n_along, 3) m, triangles (f, 3) int64."""
    theta = np.linspace(0.0, 2 * np.pi, n_around, endpoint=False)
    t, y = np.meshgrid(theta, np.linspace(y0, y0 + height, n_along))
    v = np.stack([radius * np.cos(t).ravel(), y.ravel(), radius * np.sin(t).ravel()], axis=1)
    faces = []
    for j in range(n_along - 1):
        for i in range(n_around):
            a, b = j * n_around + i, j * n_around + (i + 1) % n_around
            faces += [[a, b, a + n_around], [b, b + n_around, a + n_around]]
    return v, np.array(faces, dtype=np.int64)


def radial(v: np.ndarray) -> np.ndarray:
    out = v.copy()
    out[:, 1] = 0.0
    return out / np.linalg.norm(out, axis=1, keepdims=True)


def inner_surface(radius: float = 0.15):
    v, f = tube(radius)
    return v, f, signed_face_normals(v, f, face_sides(v, f, radial(v)))


def test_face_sides_turn_every_triangle_outward_whatever_the_winding():
    v, f = tube(0.15)
    flipped = f.copy()
    flipped[::3] = flipped[::3, ::-1]  # a file wound every which way
    n = signed_face_normals(v, flipped, face_sides(v, flipped, radial(v)))
    centre = v[flipped].mean(axis=1)
    assert (np.einsum("ij,ij->i", n, radial(centre)) > 0.9).all()


def test_an_outer_tube_inside_the_inner_one_is_pushed_outside_it():
    inner, faces, normals = inner_surface(0.15)
    outer, _ = tube(0.145)  # 5 mm inside the inner tube
    grid = build_tri_grid(inner, faces, 0.03, 0.03)
    fixed = np.zeros(len(inner))
    x, x_prev = outer.copy(), outer.copy()
    pushed = push_layer(x, x_prev, np.ones(len(x)), np.ones(len(x), dtype=np.bool_), inner.copy(), inner.copy(),
                        fixed, faces, normals, grid, 0.004, 0.03)
    assert pushed == len(x)
    # 4 mm beyond the inner tube's triangles, whose planes lie between 0.15 cos(pi / 40) (the chords' middles)
    # and 0.15 (their corners) from the axis
    r = np.linalg.norm(x[:, [0, 2]], axis=1)
    assert (r >= 0.15 * np.cos(np.pi / 40) + 0.004 - 1e-9).all() and (r <= 0.154 + 1e-9).all()
    assert np.allclose(x - x_prev, 0.0)  # moved with its previous position: no velocity added
    assert layer_depths(x, inner, faces, normals, 0.03).max() == 0.0


def test_equal_masses_share_the_push_and_the_inner_tube_feels_it():
    inner, faces, normals = inner_surface(0.15)
    outer, _ = tube(0.145)
    grid = build_tri_grid(inner, faces, 0.03, 0.03)
    moved_inner = inner.copy()
    x = outer.copy()
    push_layer(x, x.copy(), np.ones(len(x)), np.ones(len(x), dtype=np.bool_), moved_inner, inner.copy(),
               np.ones(len(inner)), faces, normals, grid, 0.004, 0.03)
    outward = np.linalg.norm(x[:, [0, 2]], axis=1) - 0.145
    inward = 0.15 - np.linalg.norm(moved_inner[:, [0, 2]], axis=1)
    assert outward.min() > 0.0 and inward.max() > 0.0  # both moved, apart
    assert 0.3 < inward.mean() / outward.mean() < 3.0


def test_a_point_past_the_inner_hem_is_left_alone_and_not_counted():
    inner, faces, normals = inner_surface(0.15)
    below = np.array([[0.146, -0.01, 0.0], [0.14, -0.02, 0.0]])  # under the bottom ring, inside its radius
    grid = build_tri_grid(inner, faces, 0.03, 0.03)
    x = below.copy()
    assert push_layer(x, x.copy(), np.ones(2), np.ones(2, dtype=np.bool_), inner.copy(), inner.copy(),
                      np.zeros(len(inner)), faces, normals, grid, 0.004, 0.03) == 0
    assert np.array_equal(x, below)
    assert layer_depths(below, inner, faces, normals, 0.03).max() == 0.0


def test_layer_depths_count_exactly_the_vertices_moved_through():
    rng = np.random.default_rng(7)
    inner, faces, normals = inner_surface(0.15)
    outer, _ = tube(0.16, n_around=30, n_along=12, height=0.4, y0=0.05)  # 1 cm outside, over the inner tube
    through = rng.choice(len(outer), size=17, replace=False)
    outer[through, 0] *= 0.15 * 0.95 / 0.16
    outer[through, 2] *= 0.15 * 0.95 / 0.16  # 5 % of the radius inside the inner tube
    depth = layer_depths(outer, inner, faces, normals, 0.03)
    assert np.count_nonzero(depth > 0.002) == 17
    assert set(np.flatnonzero(depth > 0.002)) == set(through)
    assert np.allclose(depth[through], 0.15 * np.cos(np.pi / 40) - 0.1425, atol=1e-3)


def brute_crossings(v: np.ndarray, f: np.ndarray) -> int:
    """Edge-triangle crossings by brute force (the edge sharing no corner with the triangle)."""
    edges = np.unique(np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1), axis=0)
    count = 0
    for i, j in edges:
        p, q = v[i], v[j]
        for tri in f:
            if i in tri or j in tri:
                continue
            a, b, c = v[tri]
            n = np.cross(b - a, c - a)
            dp, dq = n @ (p - a), n @ (q - a)
            if dp * dq >= 0:
                continue
            s = p + (q - p) * dp / (dp - dq)
            w = [np.cross(b - a, s - a) @ n, np.cross(c - b, s - b) @ n, np.cross(a - c, s - c) @ n]
            count += all(x > 0 for x in w)
    return count


def sheet(n: int, size: float, transform) -> tuple[np.ndarray, np.ndarray]:
    u, w = np.meshgrid(np.linspace(0, size, n), np.linspace(0, size, n))
    v = transform(np.stack([u.ravel(), np.zeros(n * n), w.ravel()], axis=1))
    f = []
    for j in range(n - 1):
        for i in range(n - 1):
            a = j * n + i
            f += [[a, a + 1, a + n], [a + 1, a + n + 1, a + n]]
    return v, np.array(f, dtype=np.int64)


def test_self_intersections_count_the_crossing_edges_of_two_sheets_and_none_of_one():
    a, fa = sheet(9, 0.2, lambda v: v)
    b, fb = sheet(7, 0.2, lambda v: v[:, [1, 0, 2]] * [1, 1, 1] + [0.1031, -0.05, 0.0133])  # upright, across a
    v = np.vstack([a, b])
    f = np.vstack([fa, fb + len(a)])
    expected = brute_crossings(v, f)
    assert expected > 10
    assert self_intersections(v, f) == expected
    assert self_intersections(a, fa) == 0
    tube_v, tube_f = tube(0.15)
    assert self_intersections(tube_v, tube_f) == 0


def test_an_outer_shown_mesh_is_kept_off_the_fixed_ones_under_it_both_ways():
    """``OverFixed``: an outer tube 12 mm inside a fixed inner one comes out over its rounds (6 mm a round),
    and an inner point standing out through the outer tube pushes the outer triangle over it out; the inner
    mesh never moves."""
    from tryon.sim.collision.over_fixed import OverFixed

    inner, faces, _ = inner_surface(0.15)
    bump = inner.copy()
    k = 10 * 40 + 7  # a point halfway up, standing 2 cm out of its tube
    bump[k, [0, 2]] *= 0.17 / 0.15
    outer, outer_faces = tube(0.138)  # 12 mm inside the inner tube's corners
    x, x_prev = outer.copy(), outer.copy()
    fixed = OverFixed([(bump, faces, face_sides(bump, faces, radial(bump)))], outer_faces, 0.0015, 0.006, 5, 0.03,
                      0.03)
    held = bump.copy()
    pushes = fixed.push(x, x_prev, face_sides(x, outer_faces, radial(x)))
    assert pushes > len(x)  # more than one round
    assert np.array_equal(bump, held)
    inner_normals = signed_face_normals(bump, faces, face_sides(bump, faces, radial(bump)))
    assert layer_depths(x, bump, faces, inner_normals, 0.03).max() <= 1e-9  # every outer point outside
    outer_normals = signed_face_normals(x, outer_faces, -face_sides(x, outer_faces, radial(x)))
    assert layer_depths(bump, x, outer_faces, outer_normals, 0.03).max() <= 1e-9  # every inner point under
    assert np.allclose(x - x_prev, 0.0)


def test_the_triangle_a_point_lies_over_is_the_nearest_of_all_not_past_their_edge():
    # the grid search (its box test passing over far triangles) against every triangle, one by one
    import trimesh

    rng = np.random.default_rng(5)
    sphere = trimesh.creation.icosphere(subdivisions=3, radius=0.2)
    x = sphere.vertices * (1.0 + rng.uniform(-0.03, 0.03, (len(sphere.vertices), 1)))
    faces = np.ascontiguousarray(sphere.faces, dtype=np.int64)
    normals = signed_face_normals(x, faces, np.ones(len(faces)))
    reach = 0.03
    grid = build_tri_grid(x, faces, 0.03, reach)
    points = rng.normal(size=(60, 3))
    points *= (0.2 + rng.uniform(-0.03, 0.03, (60, 1))) / np.linalg.norm(points, axis=1)[:, None]
    found = 0
    for p in points:
        f, s, _, _ = nearest_over(*p, x, faces, normals, grid.lo, grid.cell, grid.shape, grid.cell_start,
                                  grid.cell_tris, reach)
        best, best_dd, best_s = -1, reach * reach, 0.0
        for k, (a, b, c) in enumerate(faces):
            u, v = closest_uv_on_triangle(*p, *x[a], *x[b], *x[c])
            d = p - (x[a] + u * (x[b] - x[a]) + v * (x[c] - x[a]))
            dd = float(d @ d)
            along = float(d @ normals[k])
            if dd < best_dd and dd - along * along <= PAST_EDGE ** 2:
                best, best_dd, best_s = k, dd, along
        assert f == best
        assert s == pytest.approx(best_s, abs=1e-12)
        found += f >= 0
    assert found > 50
