"""The part grids of a re-pose's carry (``sim.nearest``) against k-d trees, the plain oracle: the same nearest
distances, a far part left out only where it weighs under the spread's power, and the bounded near test."""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

from tryon.body.build import build_body
from tryon.body.params import Measurements, pose_from
from tryon.sim.nearest import any_within, build_grids, nearest_distances


def scene():
    """A posed body, points around it (on it, a few cm off, far away) and random rigid motions of its parts."""
    body = build_body(Measurements(height=170, chest=96, waist=82, hips=100), pose_from("hands_on_hips"),
                      resolution=16)
    rng = np.random.default_rng(3)
    x = body.vertices[rng.integers(0, len(body.vertices), 600)] + rng.normal(0.0, 0.03, (600, 3))
    x = np.concatenate([x, rng.uniform(-1.0, 2.0, (100, 3))])
    n_parts = len(body.parts)
    moves = np.tile(np.eye(4), (n_parts, 1, 1))
    turn = Rotation.from_rotvec(rng.normal(0.0, 0.3, (n_parts, 3))).as_matrix()
    moves[2:, :3, :3] = turn[2:]  # the limbs turned, head and torso not
    moves[2:, :3, 3] = rng.normal(0.0, 0.05, (n_parts - 2, 3))
    # the oracle: each part's vertices where ``moves`` puts them, in a tree
    trees = [cKDTree(body.vertices[body.vertex_part == k] @ moves[k, :3, :3].T + moves[k, :3, 3])
             for k in range(n_parts)]
    return body, x, moves, np.stack([t.query(x)[0] for t in trees], axis=1)


def test_the_grids_give_the_trees_distances_and_leave_out_only_the_far_parts():
    body, x, moves, ref = scene()
    grids = build_grids(body.vertices, body.vertex_part, len(body.parts))
    every = np.ones(len(body.parts), dtype=np.bool_)
    exact = np.empty_like(ref)
    nearest_distances(x, moves, every, *grids, 0.005, np.inf, exact)
    np.testing.assert_allclose(exact, ref, rtol=0, atol=1e-12)
    spread = np.empty_like(ref)
    nearest_distances(x, moves, every, *grids, 0.005, 10.0, spread)
    kept = np.isfinite(spread)
    np.testing.assert_allclose(spread[kept], ref[kept], rtol=0, atol=1e-12)
    # a part left out is more than 10 x (in distance + softening) farther than the point's nearest part
    nearest = ref.min(axis=1, keepdims=True)
    assert ((ref + 0.005 > 10.0 * (nearest + 0.005) - 1e-12) | kept).all()
    assert kept.all(axis=1).sum() < len(x) and kept.any(axis=1).all()
    # a point is weighed only where it matters: none of the wanted parts near, only its nearest part
    torso_only = np.zeros(len(body.parts), dtype=np.bool_)
    torso_only[body.parts.index("forearm_l")] = True
    some = np.empty_like(ref)
    nearest_distances(x, moves, torso_only, *grids, 0.005, 10.0, some)
    np.testing.assert_array_equal(np.isfinite(some[:, torso_only]), kept[:, torso_only])


def test_any_within_is_the_bounded_lookup():
    body, x, moves, ref = scene()
    grids = build_grids(body.vertices, body.vertex_part, len(body.parts))
    for k in range(len(body.parts)):
        for reach in (0.005, 0.02, 0.05, 0.3):
            for chosen in (slice(0, 50), slice(600, None), slice(None)):
                expected = bool((ref[chosen, k] < reach).any())
                assert any_within(x[chosen], moves[k], k, *grids, reach) == expected, (k, reach)
