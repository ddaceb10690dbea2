"""The three inside-triangle tests agree, edges and vertices included."""

from __future__ import annotations

import numpy as np
import pytest

from tryon.sim.collision.inside import (
    COUNTERS, inside_angle, inside_area, inside_barycentric, inside_barycentric_xyz, inside_triangle,
    inside_triangle_xyz, random_hits,
)

TESTS = [inside_angle, inside_area, inside_barycentric]
TRI = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])


def _tri_in_space(seed=0):
    """The unit triangle turned and moved somewhere in space, with its transform."""
    rng = np.random.default_rng(seed)
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    shift = rng.normal(size=3)
    return lambda p: np.asarray(p, float) @ q.T + shift


@pytest.mark.parametrize("test", TESTS, ids=lambda f: f.__name__)
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_cases(test, seed):
    place = _tri_in_space(seed)
    a, b, c = (place(v) for v in TRI)
    inside = [(0.2, 0.2, 0), (0.1, 0.8, 0), (1 / 3, 1 / 3, 0)]
    edges = [(0.5, 0, 0), (0, 0.5, 0), (0.5, 0.5, 0), (0.25, 0.75, 0)]
    vertices = [(0, 0, 0), (1, 0, 0), (0, 1, 0)]
    outside = [(-0.01, 0.5, 0), (0.5, -0.01, 0), (0.51, 0.5, 0), (1.2, 0.1, 0), (-0.5, -0.5, 0), (2, 2, 0),
               (-1, 0, 0), (0, 2, 0)]
    for p in inside + edges + vertices:
        assert test(place(p), a, b, c), p
    for p in outside:
        assert not test(place(p), a, b, c), p


@pytest.mark.parametrize("test", TESTS, ids=lambda f: f.__name__)
def test_thin_and_large_triangles(test):
    a, b, c = np.array([0.0, 0, 0]), np.array([1e3, 0, 0]), np.array([0.0, 1e-2, 0])
    assert test(np.array([500.0, 0.004, 0]), a, b, c)
    assert test(np.array([500.0, 0.0, 0]), a, b, c)  # on the long edge
    assert not test(np.array([500.0, 0.006, 0]), a, b, c)
    assert not test(np.array([500.0, -1e-4, 0]), a, b, c)


def test_all_three_agree_on_random_ray_hits():
    p, tri = random_hits(20000, seed=3)
    results = [np.array([f(p[i], tri[i, 0], tri[i, 1], tri[i, 2]) for i in range(len(p))]) for f in TESTS]
    assert np.array_equal(results[0], results[1])
    assert np.array_equal(results[1], results[2])
    # about 1/8 of the hits are inside (barycentric (u, v) uniform in [-0.5, 1.5]^2)
    assert 0.11 < results[0].mean() < 0.14


def test_counting_kernels_match_and_default_is_barycentric():
    p, tri = random_hits(5000, seed=4)
    counts = {name: counter(p, tri) for name, counter in COUNTERS.items()}
    assert len(set(counts.values())) == 1
    assert inside_triangle is inside_barycentric


def test_coordinate_form_is_the_default_test():
    """The collision's coordinate form of the default test gives its answer on every hit, edges included."""
    p, tri = random_hits(20000, seed=5)
    p[:50] = 0.5 * (tri[:50, 0] + tri[:50, 1])  # on an edge
    by_arrays = np.array([inside_barycentric(p[i], tri[i, 0], tri[i, 1], tri[i, 2]) for i in range(len(p))])
    by_coords = np.array([inside_barycentric_xyz(*p[i], *tri[i, 0], *tri[i, 1], *tri[i, 2]) for i in range(len(p))])
    assert np.array_equal(by_arrays, by_coords)
    assert by_coords[:50].all() and 0.1 < by_coords.mean() < 0.15
    assert inside_triangle_xyz is inside_barycentric_xyz
