"""Simulation kernels and synthetic drapes: free fall, pins, strain limits, collision, rest."""

from __future__ import annotations

import numpy as np
import pytest

from tryon.body.build import build_body
from tryon.body.params import Measurements, Pose
from tryon.sim.collision.collider import BodyCollider
from tryon.sim.collision.kernels import face_boxes
from tryon.sim.constraints import (
    limit_stretch_downward, pack_springs, satisfy_springs, satisfy_springs_numpy, spring_strain, top_down_order,
)
from tryon.sim.integrate import kinetic_energy_per_kg, verlet_step
from tryon.sim.run import drape
from tryon.bench.synthetic import body_from_parts, cloth_square
from tryon.sim.settings import SimSettings

LIMITS = np.array([0.10, 0.15, 0.30])
COMPRESSION = np.array([1.0, 1.0, 0.1])


@pytest.fixture(scope="module")
def table():
    """A 'body' that is one upright cylinder, 0.3 m radius, 1 m tall."""
    return body_from_parts(np.array([[[0, 0, 0], [0, 1.0, 0]]], float), np.array([0.3]), n_around=48)


def test_free_fall_matches_half_g_t_squared():
    dt, n, g = 0.01, 100, 9.81
    x = np.zeros((4, 3))
    x_prev = x.copy()
    w = np.ones(4)
    for _ in range(n):
        verlet_step(x, x_prev, w, dt, g, 0.0, 1e9)
    t = n * dt
    # Verlet from rest gives g dt^2 n (n + 1) / 2: g t^2 / 2 plus a first-order start-up term
    assert np.allclose(x[:, 1], -g * dt * dt * n * (n + 1) / 2, rtol=1e-12)
    assert np.allclose(x[:, 1], -0.5 * g * t * t, rtol=1.5 / n)
    assert np.allclose(x[:, [0, 2]], 0.0)
    v = (x - x_prev) / dt
    assert np.allclose(v[:, 1], -g * t, rtol=1.5 / n)


def test_air_drag_slows_the_fall_and_is_bounded():
    dt = 0.02
    x = np.zeros((1, 3))
    x_prev = x.copy()
    for _ in range(2000):
        verlet_step(x, x_prev, np.ones(1), dt, 9.81, 1.0, 1e9)
    v = (x_prev[0, 1] - x[0, 1]) / dt
    # terminal speed of v' = g - c v in the discrete scheme: g dt / (1 - (1 - c dt)) = g / c
    assert v == pytest.approx(9.81, rel=0.02)


def test_pinned_points_stay():
    model = cloth_square(1.0, 11, 1.0)
    x = model.coarse_vertices.copy()
    x_prev = x.copy()
    w = 1.0 / model.mass
    pinned = np.array([0, 10])
    w[pinned] = 0.0
    springs = model.springs.astype(np.int64)
    kind = model.kind.astype(np.int64)
    ends, table = pack_springs(springs, model.rest, kind, LIMITS, COMPRESSION)
    for _ in range(50):
        verlet_step(x, x_prev, w, 0.02, 9.81, 1.0, 10.0)
        satisfy_springs(x, w, ends, table, 8)
        limit_stretch_downward(x, x_prev, w, ends, table, top_down_order(x, springs), np.zeros(len(x), dtype=bool))
    assert np.array_equal(x[pinned], model.coarse_vertices[pinned])
    assert x[5, 1] < 0.9  # the rest fell


def test_springs_within_limits_after_the_passes():
    model = cloth_square(0.5, 9, 1.0)
    rng = np.random.default_rng(0)
    x = model.coarse_vertices + rng.normal(scale=0.02, size=(len(model.mass), 3))
    springs = model.springs.astype(np.int64)
    kind = model.kind.astype(np.int64)
    satisfy_springs(x, np.ones(len(x)), *pack_springs(springs, model.rest, kind, LIMITS, COMPRESSION), 300)
    strain = spring_strain(x, springs, model.rest)
    assert np.all(strain <= LIMITS[kind] + 1e-3)
    structural_or_shear = kind < 2
    assert np.all(strain[structural_or_shear] >= -1e-3)


def test_numba_passes_match_the_numpy_oracle():
    model = cloth_square(0.3, 5, 1.0)
    rng = np.random.default_rng(1)
    x = model.coarse_vertices + rng.normal(scale=0.03, size=(len(model.mass), 3))
    w = rng.uniform(0.5, 2.0, len(x))
    w[0] = 0.0
    springs = model.springs.astype(np.int64)
    kind = model.kind.astype(np.int64)
    expected = satisfy_springs_numpy(x, w, springs, model.rest, kind, LIMITS, COMPRESSION, 3)
    got = x.copy()
    satisfy_springs(got, w, *pack_springs(springs, model.rest, kind, LIMITS, COMPRESSION), 3)
    assert np.allclose(got, expected, atol=1e-12)


def test_hanging_cloth_keeps_its_strain_limit():
    """A cloth pinned at its top edge: the top-down sweep keeps every spring within its limit."""
    model = cloth_square(1.0, 21, 1.0)
    x0 = model.coarse_vertices
    x = np.stack([x0[:, 0], 1.0 + x0[:, 2], np.zeros(len(x0))], axis=1)
    x_prev = x.copy()
    w = 1.0 / model.mass
    w[x[:, 1] > x[:, 1].max() - 1e-6] = 0.0
    springs = model.springs.astype(np.int64)
    kind = model.kind.astype(np.int64)
    ends, table = pack_springs(springs, model.rest, kind, LIMITS, COMPRESSION)
    for step in range(200):
        verlet_step(x, x_prev, w, 0.02, 9.81, 1.0, 10.0)
        satisfy_springs(x, w, ends, table, 4)
        limit_stretch_downward(x, x_prev, w, ends, table, top_down_order(x, springs), np.zeros(len(x), dtype=bool))
    strain = spring_strain(x, springs, model.rest)
    assert np.all(strain <= 1.01 * (1 + LIMITS[kind]) - 1)
    assert x[:, 1].min() < 0.45  # it hangs (1 m cloth, 10 % stretch at most)
    assert kinetic_energy_per_kg(x, x_prev, model.mass, 0.02) < 1e-2


def test_points_inside_a_cylinder_end_outside_with_the_margin(table):
    margin = 0.004
    collider = BodyCollider(table, margin)
    rng = np.random.default_rng(2)
    n = 2000
    r = rng.uniform(0.0, 0.295, n)
    a = rng.uniform(-np.pi, np.pi, n)
    y = rng.uniform(0.05, 0.95, n)
    x = np.stack([r * np.cos(a), y, r * np.sin(a)], axis=1)
    x_prev = x.copy()
    contact = np.zeros(n, dtype=bool)
    moved = collider.collide(x, x_prev, np.ones(n), np.ones(n, dtype=bool), np.array([0]), 0.0005, 0.0, 0.0,
                             contact)
    assert moved == n
    radius = np.hypot(x[:, 0], x[:, 2])
    inside_real = (radius < 0.3) & (x[:, 1] > 0.0) & (x[:, 1] < 1.0)
    assert not inside_real.any()
    # each point left by the short way: through the side wall or a cap, whichever is nearer
    depth_side = 0.3 - r
    depth_cap = np.minimum(y, 1.0 - y)
    side = depth_side < depth_cap - 0.01
    assert np.allclose(radius[side], 0.3 + margin, atol=0.002)
    assert np.all(collider.depth(x, np.array([0]), offset=False) == 0.0)


def test_depth_of_points_near_the_surface(table):
    collider = BodyCollider(table, 0.004)
    a = np.linspace(-np.pi, np.pi, 50, endpoint=False)
    for d in (-0.02, -0.005, 0.003):  # inside by 2 cm, 5 mm; outside by 3 mm
        x = np.stack([(0.3 + d) * np.cos(a), np.full(50, 0.5), (0.3 + d) * np.sin(a)], axis=1)
        depth = collider.depth(x, np.array([0]), offset=False)
        # the faceted cylinder (48 sides) lies up to 0.6 mm inside the round one
        assert np.allclose(depth, max(-d, 0.0), atol=7e-4)


def test_no_frame_has_cloth_deep_in_the_ball():
    """Issue 26: a cloth dropped on a ball falls ~4 cm a step when it lands; the step's collision runs on its
    first substep, so before the within-step test of the points that moved far (``collision.movers``) it
    went 42 mm into the ball before the next step pushed it out. Every frame now stays within 2 mm (the
    probe measures against the true sphere, the body is an icosphere within 1 mm of it)."""
    from dataclasses import replace

    from tryon.bench.ours_cloth import run_sphere
    from tryon.sim.tuning import TUNING

    held = run_sphere(32, 60)
    assert held["max_penetration_mm"] <= 2.0, held
    assert held["outcome"] == "on the ball"
    # the test can fail: without the within-step test the landing goes centimetres deep
    unheld = run_sphere(32, 60, tuning=replace(TUNING, frame_depth=np.inf))
    assert unheld["max_penetration_mm"] > 10.0, unheld


@pytest.mark.parametrize("time_step", [0.02, 0.05])
def test_cloth_comes_to_rest_on_a_table(table, time_step):
    cloth = cloth_square(1.0, 31, 1.05)
    settings = SimSettings(time_step=time_step, max_steps=600, min_steps=20)
    result = drape(table, cloth, settings, initial=cloth.coarse_vertices)
    m = result.metrics
    assert m["rest_reached"], m
    assert m["penetrating_vertices"] == 0
    top = result.vertices[np.hypot(result.vertices[:, 0], result.vertices[:, 2]) < 0.25]
    # lying on the offset top (margin 4 mm + lambda 0.5 mm), a few small wrinkles allowed
    assert np.median(top[:, 1]) == pytest.approx(1.0045, abs=0.001)
    assert np.all((top[:, 1] > 1.0) & (top[:, 1] < 1.02))
    assert result.vertices[:, 1].min() < 0.85  # the corners hang down
    # The table's rim is a sharp 90-degree edge (a body has none): springs straddling it are the last to
    # settle; the relaxation after the loop still brings every spring within the target. At the paper's
    # 0.05 s the drape is stable and at rest but looser: bound it.
    if time_step <= 0.02:
        assert sum(k["over"] for k in m["strain_by_kind"].values()) == 0, m["strain_by_kind"]
        assert m["max_strain"] < 0.17
    else:
        assert m["max_strain"] < 0.3


def test_on_frame_false_stops_the_run(table):
    cloth = cloth_square(1.0, 11, 1.2)
    seen = []
    result = drape(table, cloth, SimSettings(max_steps=100), initial=cloth.coarse_vertices,
                   on_frame=lambda step, x: seen.append(step) or step < 5)
    assert seen == [1, 2, 3, 4, 5]
    assert result.metrics["steps"] == 5 and result.metrics["stopped"]


def test_face_boxes_skip_only_faces_the_ray_cannot_hit(table):
    """The per-face (theta, z) boxes only skip faces a query ray cannot hit: depths with them equal depths
    with every face intersected, across the theta = +-pi seam, on the caps and around the rim."""
    collider = BodyCollider(table, 0.004)
    rng = np.random.default_rng(5)
    n = 4000
    r = rng.uniform(0.0, 0.33, n)
    a = rng.uniform(-np.pi, np.pi, n)
    a[: n // 8] = np.pi - rng.uniform(0.0, 1e-3, n // 8)  # at the seam
    y = rng.uniform(-0.02, 1.02, n)
    pts = np.stack([r * np.cos(a), y, r * np.sin(a)], axis=1)
    parts = np.array([0])
    with_boxes = collider.depth(pts, parts, offset=True)
    assert (with_boxes > 0).sum() > n // 2  # most points are inside: the test exercises the ray casts
    collider.offset_boxes[:, [0, 2]] = -np.inf
    collider.offset_boxes[:, [1, 3]] = np.inf
    every_face = collider.depth(pts, parts, offset=True)
    assert np.array_equal(with_boxes, every_face)


def test_face_boxes_from_shared_corners_equal_boxes_from_every_corner():
    """face_boxes computes each vertex's cylinder coordinates once, in its own part's frame, and a face
    corner of another part again in the face's: the boxes equal those with every corner computed in its
    face's frame (no vertex taken as its part's), on a grown body of 10 parts."""
    collider = BodyCollider(build_body(Measurements(height=170, chest=96, waist=82, hips=100), Pose()), 0.004)
    collider.set_scale(0.7)
    shared = collider.offset_boxes.copy()
    every_corner = np.empty_like(shared)
    face_boxes(collider.offset, collider.faces, collider.face_part, np.full(len(collider.offset), -1),
               collider.cyl_origin, collider.cyl_axes, collider.corners, every_corner)
    assert np.isfinite(shared[:, :2]).all()
    assert np.array_equal(shared, every_corner)


def test_a_point_pinched_between_touching_parts_is_held_where_it_came_from():
    """Two 'thighs' (radius 8 cm, axes 15 cm apart) whose offset surfaces overlap by 1.8 cm: a point that
    moves from in front of the gap into the overlap has no way out nearby. Pushed out of one part it lands
    in the other, every round; with ``hold_pinched`` it stays at its start-of-step position (outside both),
    while a point inside one part only is still pushed out radially."""
    thighs = body_from_parts(np.array([[[0.0, 0.0, 0.0], [0.0, 1.0, 0.0]], [[0.15, 0.0, 0.0], [0.15, 1.0, 0.0]]]),
                             np.array([0.08, 0.08]), n_around=48)
    collider = BodyCollider(thighs, 0.004)
    parts = np.array([0, 1])
    start = np.array([[0.075, 0.5, 0.10], [-0.12, 0.5, 0.0]])  # in front of the gap; beside the left thigh
    moved_to = np.array([[0.075, 0.5, 0.0], [-0.07, 0.5, 0.0]])  # into the overlap; 1 cm into the left one
    results = {}
    for hold in (False, True):
        x, x_prev = moved_to.copy(), start.copy()
        contact = np.zeros(2, dtype=np.bool_)
        collider.collide(x, x_prev, np.ones(2), np.ones(2, dtype=np.bool_), parts, 0.0005, 0.0, 0.0, contact,
                         hold_pinched=hold)
        results[hold] = x
        assert contact.all()
    held, pushed = results[True], results[False]
    assert np.allclose(held[0], start[0])  # held where it came from, outside both
    assert np.all(collider.depth(held, parts, offset=True) == 0.0)
    assert not np.allclose(pushed[0], start[0])  # without holding: pushed from one thigh into the other
    for x in (held, pushed):  # the point beside one thigh only: out along the radius either way
        assert np.hypot(x[1, 0], x[1, 2]) == pytest.approx(0.0845, abs=0.001) and abs(x[1, 2]) < 0.001


def test_the_rest_test_reads_the_force_left_over_two_steps():
    """``step._balance``: a point creeping at a drag-limited speed is neither at rest nor balanced (its force is
    what the drag takes); one flipping between two places every step goes nowhere and is balanced; one still
    is both."""
    from tryon.sim.step import _balance

    dt, drag = 0.02, 20.0
    still = np.zeros((4, 1, 3))
    creeping = np.tile([0.0, -1e-4, 0.0], (4, 1, 1))  # 0.1 mm a step: 5 mm/s
    flipping = np.array([[[0.0, 0.01, 0.0]], [[0.0, -0.01, 0.0]], [[0.0, 0.01, 0.0]], [[0.0, -0.01, 0.0]]])
    assert _balance(still, dt, drag, 1.0) == (0.0, 0.0)
    speed, force = _balance(creeping, dt, drag, 1.0)
    assert speed == pytest.approx(0.005) and force == pytest.approx(drag * 0.005)
    assert _balance(flipping, dt, drag, 1.0) == pytest.approx((0.0, 0.0))
