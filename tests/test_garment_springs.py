"""Spring model: counts on meshes small enough to count by hand."""

import numpy as np
import pytest

from tryon.garment.springs import BENDING, SHEAR, STRUCTURAL
from tryon.garment.springs import spring_model


def quad_grid(nx: int, ny: int, spacing: float = 1.0):
    """(nx+1)(ny+1) nodes, each quad (a, b, c, d) split 3DMAX-style into (a, b, c) and (a, c, d)."""
    xs, ys = np.meshgrid(np.arange(nx + 1), np.arange(ny + 1))
    v = np.column_stack([xs.ravel(), ys.ravel(), np.zeros(xs.size)]).astype(float) * spacing
    idx = lambda i, j: j * (nx + 1) + i  # noqa: E731
    f = []
    for j in range(ny):
        for i in range(nx):
            a, b, c, d = idx(i, j), idx(i + 1, j), idx(i + 1, j + 1), idx(i, j + 1)
            f += [[a, b, c], [a, c, d]]
    return v, np.array(f)


def triangle_lattice(n: int):
    """Equilateral lattice: nodes (i + j/2, j sqrt(3)/2), i, j in 0..n; 2 n^2 triangles."""
    i, j = np.meshgrid(np.arange(n + 1), np.arange(n + 1), indexing="xy")
    v = np.column_stack([(i + j / 2).ravel(), (j * np.sqrt(3) / 2).ravel(), np.zeros(i.size)])
    idx = lambda a, b: b * (n + 1) + a  # noqa: E731
    f = []
    for b in range(n):
        for a in range(n):
            f += [[idx(a, b), idx(a + 1, b), idx(a, b + 1)], [idx(a + 1, b), idx(a + 1, b + 1), idx(a, b + 1)]]
    return v, np.array(f)


def test_quad_grid_3x3_counts_by_hand():
    v, f = quad_grid(3, 3)
    springs, rest, kind = spring_model(v, f)
    counts = np.bincount(kind, minlength=3)
    # structural: 4 rows x 3 horizontal edges + 4 columns x 3 vertical edges = 24
    # shear: 9 diagonals (near hypotenuses) + 9 other diagonals across them (rule 2) = 18
    # bending: each of 4 rows and 4 columns of 4 nodes has 2 "skip one" pairs = 16
    assert counts.tolist() == [24, 18, 16]
    assert np.allclose(rest[kind == STRUCTURAL], 1.0)
    assert np.allclose(rest[kind == SHEAR], np.sqrt(2))
    assert np.allclose(rest[kind == BENDING], 2.0)


def test_quad_grid_general_counts():
    nx, ny = 5, 2
    v, f = quad_grid(nx, ny, spacing=0.02)
    _, rest, kind = spring_model(v, f)
    counts = np.bincount(kind, minlength=3)
    structural = nx * (ny + 1) + ny * (nx + 1)
    shear = 2 * nx * ny
    bending = (nx - 1) * (ny + 1) + (ny - 1) * (nx + 1)
    assert counts.tolist() == [structural, shear, bending]
    assert np.allclose(rest[kind == BENDING], 0.04)


def test_springs_unique_and_no_self_springs():
    v, f = quad_grid(4, 3)
    springs, rest, kind = spring_model(v, f)
    assert springs.dtype == np.int32 and kind.dtype == np.int8 and rest.dtype == np.float64
    assert (springs[:, 0] < springs[:, 1]).all()
    assert len(np.unique(springs, axis=0)) == len(springs)
    assert np.allclose(rest, np.linalg.norm(v[springs[:, 0]] - v[springs[:, 1]], axis=1))


def test_fallback_on_equilateral_lattice_counts_by_hand():
    v, f = triangle_lattice(3)  # 16 nodes, 18 triangles, no right angles: the fallback rule
    springs, rest, kind = spring_model(v, f)
    counts = np.bincount(kind, minlength=3)
    # structural: every edge: 12 along i + 12 along j + 9 diagonals = 33
    # shear: one pair across each interior edge: (3 * 18 - 12 boundary edges) / 2 = 21, length sqrt(3)
    # bending: straight triples along the 3 lattice directions: 8 + 8 + 4 = 20, length 2
    assert counts.tolist() == [33, 21, 20]
    assert np.allclose(rest[kind == STRUCTURAL], 1.0)
    assert np.allclose(rest[kind == SHEAR], np.sqrt(3))
    assert np.allclose(rest[kind == BENDING], 2.0)


def test_grid_on_a_curved_tube_still_follows_the_paper_rules():
    # a quad grid wrapped into a tube (16 around, 5 rows): bending pairs along rings and columns
    n_around, rows = 16, 5
    theta = 2 * np.pi * np.arange(n_around) / n_around
    v = np.concatenate([np.column_stack([0.1 * np.cos(theta), np.full(n_around, 0.04 * r), 0.1 * np.sin(theta)])
                        for r in range(rows + 1)])
    f = []
    for r in range(rows):
        for k in range(n_around):
            a, b = r * n_around + k, r * n_around + (k + 1) % n_around
            c, d = b + n_around, a + n_around
            f += [[a, b, c], [a, c, d]]
    _, _, kind = spring_model(v, np.array(f))
    counts = np.bincount(kind, minlength=3)
    structural = n_around * (rows + 1) + n_around * rows
    shear = 2 * n_around * rows
    bending = n_around * (rows + 1) + n_around * (rows - 1)  # around every ring; 4 per column
    assert counts.tolist() == [structural, shear, bending]


@pytest.mark.parametrize("seed", [0, 1])
def test_random_mesh_gets_all_three_kinds(seed):
    rng = np.random.default_rng(seed)
    v, f = triangle_lattice(8)
    v = v + rng.normal(scale=0.08, size=v.shape) * [1, 1, 0]
    _, rest, kind = spring_model(v, f)
    assert set(np.unique(kind)) == {STRUCTURAL, SHEAR, BENDING}
    assert (rest > 0).all()
