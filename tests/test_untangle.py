"""Intersection-contour minimisation (``sim/collision/untangle.py``): crossed sheets come apart, the gradient
shortens the contour, what must not move does not."""

from __future__ import annotations

import numpy as np

from tryon.garment.topology import edge_faces
from tryon.sim.collision.crossings import self_intersections
from tryon.sim.collision.untangle import (_all_crossings, _crossings_after, contour_gradient, untangle_mesh,
                                         untangle_round)


def grid_sheet(n: int, size: float, height, shift=(0.0, 0.0)):
    """An n x n grid sheet over [0, size]^2 in x-y (shifted by ``shift``), z = height(x, y): vertices (n^2, 3) m,
    triangles (f, 3) int64."""
    xs = np.linspace(0.0, size, n)
    gx, gy = np.meshgrid(xs + shift[0], xs + shift[1], indexing="ij")
    v = np.stack([gx.ravel(), gy.ravel(), height(gx, gy).ravel()], axis=1)
    faces = []
    for i in range(n - 1):
        for j in range(n - 1):
            a, b, c, d = i * n + j, (i + 1) * n + j, i * n + j + 1, (i + 1) * n + j + 1
            faces += [[a, b, d], [a, d, c]]
    return v, np.array(faces, dtype=np.int64)


def dented_pair():
    """A flat sheet and, 1 cm over it, a sheet with a dent 2 cm deep through it: their crossing is one closed
    contour round the dent."""
    flat, f_flat = grid_sheet(11, 0.3, lambda x, y: 0.0 * x)
    dented, f_dent = grid_sheet(11, 0.3, lambda x, y: 0.01 - 0.03 * np.exp(-((x - 0.15) ** 2 + (y - 0.15) ** 2) / 0.003),
                                shift=(0.013, 0.013))
    v = np.vstack([flat, dented])
    faces = np.vstack([f_flat, f_dent + len(flat)])
    return v, faces, len(flat)


def rounds_to_untangle(v, faces, inv_mass, step=0.001, most=300):
    x, x_prev = v.copy(), v.copy()
    edges, adjacent = edge_faces(faces)
    for r in range(most):
        if untangle_round(x, x_prev, inv_mass, faces, edges, adjacent, step) == 0:
            return r, x, x_prev
    return most, x, x_prev


def test_edge_faces_pairs_each_edge_with_its_triangles():
    faces = np.array([[0, 1, 2], [2, 1, 3]], dtype=np.int64)
    edges, adjacent = edge_faces(faces)
    table = {tuple(e): tuple(a) for e, a in zip(edges.tolist(), adjacent.tolist())}
    assert table == {(0, 1): (0, -1), (0, 2): (0, -1), (1, 2): (0, 1), (1, 3): (1, -1), (2, 3): (1, -1)}


def test_the_contour_gradient_shortens_the_contour():
    """An edge through a large triangle: moving the edge's two ends a little along the gradient shortens the
    contour its two triangles cut in the large one's plane (finite differences, five random crossings)."""
    rng = np.random.default_rng(3)

    def cut(p, q, r, normal):
        ends = [a + (a @ normal) / ((a - b) @ normal) * (b - a) for a, b in ((p, q), (q, r), (r, p))
                if (a @ normal) * (b @ normal) < 0]
        return float(np.linalg.norm(ends[0] - ends[1])) if len(ends) == 2 else 0.0

    for _ in range(5):
        normal = rng.normal(size=3)
        normal /= np.linalg.norm(normal)
        u = np.cross(normal, [1.0, 0.0, 0.0])
        u /= np.linalg.norm(u)
        w = np.cross(normal, u)
        x = np.zeros((7, 3))
        x[0], x[1], x[2] = -5 * u - 5 * w, 5 * u - 5 * w, 10 * w
        x[3] = rng.normal(size=3) * 0.3 + 0.5 * normal
        x[4] = rng.normal(size=3) * 0.3 - 0.5 * normal
        x[5], x[6] = rng.normal(size=3) * 0.5, rng.normal(size=3) * 0.5
        faces = np.array([[0, 1, 2], [3, 4, 5], [4, 3, 6]], dtype=np.int64)

        def length(y):
            return cut(y[3], y[4], y[5], normal) + cut(y[4], y[3], y[6], normal)

        g = contour_gradient(x, 3, 4, 0, np.array([1, 2], dtype=np.int64), faces)
        moved = x.copy()
        moved[3:5] += 1e-4 * g / np.linalg.norm(g)
        assert length(moved) < length(x)


def test_a_sheet_dented_through_another_comes_apart():
    v, faces, _ = dented_pair()
    assert self_intersections(v, faces) > 10
    rounds, x, _ = rounds_to_untangle(v, faces, np.ones(len(v)))
    assert rounds < 200
    assert self_intersections(x, faces) == 0
    assert np.abs(x - v).max() <= 0.02  # a local repair: the dent goes back out about its depth at most


def test_what_must_not_move_stays_and_no_velocity_is_made():
    v, faces, n_flat = dented_pair()
    inv_mass = np.ones(len(v))
    inv_mass[:n_flat] = 0.0  # the flat sheet pinned: the dented one alone moves out
    rounds, x, x_prev = rounds_to_untangle(v, faces, inv_mass)
    assert rounds < 300 and self_intersections(x, faces) == 0
    assert np.array_equal(x[:n_flat], v[:n_flat])
    assert np.array_equal(x, x_prev)
    # points on a body under them (the body below the dent) never move into it: a drape's untangling gives them
    # no weight (``untangle.untangle``: a point with a contact plane stays)
    on_body = np.zeros(len(v), dtype=np.bool_)
    on_body[n_flat:] = True
    _, x, _ = rounds_to_untangle(v, faces, np.where(on_body, 0.0, 1.0), most=20)
    assert (x[n_flat:, 2] >= v[n_flat:, 2] - 1e-12).all()


def test_an_untangled_mesh_is_left_alone():
    v, faces = grid_sheet(8, 0.2, lambda x, y: 0.02 * np.sin(10 * x))
    rounds, x, _ = rounds_to_untangle(v, faces, np.ones(len(v)))
    assert rounds == 0 and np.array_equal(x, v)


def test_the_crossings_after_a_move_are_those_a_whole_search_finds():
    """``untangle_mesh`` looks again only where points moved: after moving a random third of the dented pair's
    points by up to 1 cm (some crossings undone, others made), the pairs it finds are exactly a whole search's,
    each once."""
    v, faces, _ = dented_pair()
    edges, _ = edge_faces(faces)
    rng = np.random.default_rng(7)
    before = _all_crossings(v, faces, edges, 0.03)
    for trial in range(5):
        moved = rng.random(len(v)) < 0.33
        x = v.copy()
        x[moved] += rng.uniform(-0.01, 0.01, (int(moved.sum()), 3))
        found = _crossings_after(x, faces, edges, 0.03, moved, before)
        whole = _all_crossings(x, faces, edges, 0.03)
        assert len(whole) > 0
        assert len(found) == len(set(map(tuple, found.tolist())))
        assert set(map(tuple, found.tolist())) == set(map(tuple, whole.tolist()))


def test_untangling_in_rounds_looks_again_only_where_it_moved_and_ends_the_same():
    """Rounds that look again only where points moved take the dented pair apart as whole searches do."""
    v, faces, _ = dented_pair()
    edges, adjacent = edge_faces(faces)
    x, x_prev = v.copy(), v.copy()
    assert untangle_mesh(x, x_prev, np.ones(len(v)), faces, edges, adjacent, 0.001, 300) == 0
    rounds, y, _ = rounds_to_untangle(v, faces, np.ones(len(v)))
    assert self_intersections(x, faces) == 0 and np.abs(x - y).max() < 1e-9
