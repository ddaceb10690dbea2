"""The fast projection of the strain limits (``sim/projection.py``): a stretched sheet brought back to its
limits at once, contact points kept on their planes, sticking points held."""

from __future__ import annotations

import numpy as np
import pytest

from tryon.bench.synthetic import cloth_square
from tryon.sim.constraints import pack_springs, spring_lengths
from tryon.sim.projection import STICK_MOVE, TOLERANCE, project_stretch, sticking

LIMITS = np.array([0.10, 0.15, 0.30])


def _sheet(n=21, pull=1.12, seed=0):
    """A square cloth (n x n points, 1 m) stretched to ``pull`` x its size in x and z, 0.2 mm of noise on top
    (seeded), its row at the least z pinned; with its packed springs."""
    model = cloth_square(size=1.0, n=n, height=1.0)
    x = model.vertices.copy()
    w = np.ones(len(x))
    w[x[:, 2] == x[:, 2].min()] = 0.0
    x[:, [0, 2]] *= pull
    x += np.random.default_rng(seed).normal(scale=0.0002, size=x.shape)
    ends, table = pack_springs(model.springs, model.rest, model.kind, LIMITS, np.array([1.0, 1.0, 0.1]))
    return x, w, ends, table


def _over(x, ends, table, w):
    """Each spring with an end that can move: its length over its limit, relative (l / l_max - 1)."""
    movable = (w[ends[:, 0]] > 0) | (w[ends[:, 1]] > 0)
    return (spring_lengths(x, ends.astype(np.int64)) / table[:, 0] - 1.0)[movable]


def test_a_stretched_sheet_comes_back_towards_its_limits_and_its_worst_spring_never_gets_worse():
    no_plane = np.zeros(21 * 21, dtype=bool)
    normals = np.zeros((21 * 21, 3))
    worst = []
    for steps in (1, 2, 4, 8):
        x, w, ends, table = _sheet(pull=1.12)  # structural springs 12 % long: 1.8 % past their 10 % limit
        start = _over(x, ends, table, w)
        pinned = x[w == 0].copy()
        project_stretch(x, w, ends, table, no_plane, normals, steps)
        assert np.array_equal(x[w == 0], pinned)  # a pinned point never moves
        worst.append(_over(x, ends, table, w).max())
    assert start.max() == pytest.approx(0.034, abs=0.002)  # 1.8 % and the noise
    assert worst == sorted(worst, reverse=True) and worst[-1] < 0.6 * start.max()
    # far past the limits (25 %) the linearised steps overshoot; halved or undone, they never leave it worse
    x, w, ends, table = _sheet(pull=1.25)
    start = _over(x, ends, table, w).max()
    project_stretch(x, w, ends, table, no_plane, normals, 8)
    assert _over(x, ends, table, w).max() <= start


def test_a_point_on_a_contact_plane_moves_along_it_only():
    x, w, ends, table = _sheet(n=9, pull=1.12)
    has_plane = np.zeros(len(x), dtype=bool)
    normals = np.zeros_like(x)
    on_body = np.flatnonzero(x[:, 2] > np.median(x[:, 2]))
    has_plane[on_body] = True
    normals[on_body] = [0.0, 1.0, 0.0]  # a floor under the far half
    before = x.copy()
    project_stretch(x, w, ends, table, has_plane, normals, 8)
    moved = x - before
    assert np.abs(moved[on_body, 1]).max() < 1e-12  # nothing along the normal
    assert np.linalg.norm(moved[on_body], axis=1).max() > 0.01  # but they slide along it
    assert _over(x, ends, table, w).max() <= TOLERANCE


def test_a_contact_point_that_has_not_slid_this_step_sticks():
    x = np.zeros((3, 3))
    x_step = x.copy()
    x[0] = [0.3 * STICK_MOVE, 0.01, 0.0]  # along its plane by less than STICK_MOVE (and off it: not counted)
    x[1] = [3.0 * STICK_MOVE, 0.0, 0.0]  # slid
    has_plane = np.array([True, True, False])
    normals = np.tile([0.0, 1.0, 0.0], (3, 1))
    w = np.full(3, 2.0)
    out = np.empty(3)
    sticking(x, x_step, w, has_plane, normals, out)
    assert out.tolist() == [0.0, 2.0, 2.0]
