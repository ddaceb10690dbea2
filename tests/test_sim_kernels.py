"""The loop's packed kernels: contact planes over a list of points, the step's spring subsets, the
collision's choice of points to test, the fused substeps. Each is checked against a plain numpy statement
of what it does, or against the kernels it stands for called one by one."""

from __future__ import annotations

import numpy as np
import pytest

from tryon.sim.collision.contacts import apply_friction, points_to_test, project_listed, project_planes
from tryon.sim.constraints import (
    STEEP, cap_stretch, contact_springs, pack_springs, pack_sweep, solve_constraints, solve_listed, sweep_downward,
    sweep_springs, top_down_order,
)
from tryon.sim.integrate import keep_above_floor, verlet_step
from tryon.sim.full_mesh import PINCHED_LEAST_DEEP
from tryon.bench.synthetic import body_from_parts, cloth_square
from tryon.sim.collision.collider import BodyCollider
from tryon.sim.state import DrapeState
from tryon.sim.substeps import Planes, Springs, Substeps, Sweep, finish_step

LIMITS = np.array([0.10, 0.15, 0.30])
COMPRESSION = np.array([1.0, 1.0, 0.1])


def _contacts(n=200, seed=0):
    """Points around the plane y = 0 (normal +y), half of them with a contact plane."""
    rng = np.random.default_rng(seed)
    x = rng.normal(scale=0.01, size=(n, 3))
    x_prev = x + rng.normal(scale=0.002, size=(n, 3))
    has_plane = rng.random(n) < 0.5
    point = np.zeros((n, 3))
    normal = np.zeros((n, 3))
    normal[:, 1] = 1.0
    return x, x_prev, has_plane, point, normal


def test_projection_puts_listed_points_on_their_plane_without_bounce():
    x, x_prev, has_plane, point, normal = _contacts()
    listed = np.flatnonzero(has_plane)
    below = has_plane & (x[:, 1] < 0)
    x0, prev0 = x.copy(), x_prev.copy()
    push = np.zeros(len(x))
    project_listed(x, x_prev, listed, point, normal, 0.0, 0.0, push)
    assert np.allclose(x[below, 1], 0.0, atol=1e-15)
    assert np.allclose(x[below][:, [0, 2]], x0[below][:, [0, 2]])  # frictionless: along the normal only
    assert np.allclose(push[below], -x0[below, 1])
    assert np.array_equal(x[~below], x0[~below]) and np.all(push[~below] == 0)
    # inelastic: no velocity along the normal is left to the pushed points
    assert np.allclose(x_prev[below, 1], x[below, 1])
    assert np.array_equal(x_prev[~below], prev0[~below])


def test_projection_by_mask_and_by_list_agree():
    x, x_prev, has_plane, point, normal = _contacts(seed=1)
    a, a_prev = x.copy(), x_prev.copy()
    project_planes(a, a_prev, has_plane, point, normal, 0.6, 0.4)
    b, b_prev = x.copy(), x_prev.copy()
    project_listed(b, b_prev, np.flatnonzero(has_plane), point, normal, 0.6, 0.4)
    assert np.array_equal(a, b) and np.array_equal(a_prev, b_prev)


def test_friction_sticks_under_the_static_limit_and_slides_over_it():
    x = np.zeros((3, 3))
    x_prev = np.zeros((3, 3))
    x[:, 0] = 0.001  # 1 mm of tangential motion each
    normal = np.tile([0.0, 1.0, 0.0], (3, 1))
    push = np.array([0.002, 0.001, 0.0005])  # mu_s x push: 1.2 mm (sticks), 0.6 mm and 0.3 mm (slide)
    listed = np.array([0, 1], dtype=np.int64)  # point 2 has no plane: untouched
    apply_friction(x, x_prev, listed, normal, push, 0.6, 0.4)
    assert x[0, 0] == 0.0
    assert np.isclose(x[1, 0], 0.001 - 0.4 * 0.001)
    assert x[2, 0] == 0.001
    assert np.all(push[:2] == 0.0)


def _post():
    """A body of one thin upright cylinder (5 cm radius, 1 m tall)."""
    return body_from_parts(np.array([[[0, 0, 0], [0, 1.0, 0]]], float), np.array([0.05]), n_around=16)


def _cloth():
    model = cloth_square(0.5, 9, 1.0)
    rng = np.random.default_rng(3)
    x = model.coarse_vertices + rng.normal(scale=0.01, size=(len(model.mass), 3))
    springs = model.springs.astype(np.int64)
    ends, table = pack_springs(springs, model.rest, model.kind.astype(np.int64), LIMITS, COMPRESSION)
    on_body = rng.random(len(x)) < 0.6
    return x, springs, ends, table, on_body


def test_contact_springs_are_those_on_the_body_stretch_only():
    x, springs, ends, table, on_body = _cloth()
    assert ends.dtype == np.uint32
    body_ends, body_table, _ = contact_springs(ends, table, on_body)
    both = on_body[springs[:, 0]] & on_body[springs[:, 1]]
    assert both.sum() > 0 and (~both).sum() > 0
    assert np.array_equal(body_ends, ends[both])
    assert np.array_equal(body_table[:, 0], table[both, 0])  # stretch limits kept, in spring order
    assert np.all(body_table[:, 1:] == 0.0)  # no compression target at all


def test_sweep_springs_keep_the_top_down_order_of_those_off_the_body():
    x, springs, ends, table, on_body = _cloth()
    order = top_down_order(x, springs)
    ordered_ends, ordered_lmax = pack_sweep(ends, table, order)
    assert np.array_equal(ordered_ends, ends[order]) and np.array_equal(ordered_lmax, table[order, 0])
    hangs = np.ones(len(x), dtype=np.bool_)
    sweep_ends, sweep_lmax, _ = sweep_springs(ordered_ends, ordered_lmax, on_body, hangs)
    off = ~(on_body[springs[order, 0]] & on_body[springs[order, 1]])
    assert np.array_equal(sweep_ends, ends[order[off]])
    assert np.array_equal(sweep_lmax, table[order[off], 0])
    # a piece that hangs from nothing is left out whole (it falls)
    hangs[:] = False
    assert len(sweep_springs(ordered_ends, ordered_lmax, on_body, hangs)[0]) == 0


def test_solve_by_list_matches_solve_by_mask():
    x, springs, ends, table, on_body = _cloth()
    x_prev = x.copy()
    w = np.ones(len(x))
    point = np.zeros((len(x), 3))
    point[:, 1] = x[:, 1].mean()
    normal = np.tile([0.0, 1.0, 0.0], (len(x), 1))
    a, a_prev, a_push = x.copy(), x_prev.copy(), np.zeros(len(x))
    solve_constraints(a, a_prev, w, ends, table, 4, on_body, point, normal, 0.0, 0.0, a_push)
    b, b_prev, b_push = x.copy(), x_prev.copy(), np.zeros(len(x))
    solve_listed(b, b_prev, w, ends, table, 4, np.flatnonzero(on_body), point, normal, 0.0, 0.0, b_push)
    assert np.array_equal(a, b) and np.array_equal(a_prev, b_prev) and np.array_equal(a_push, b_push)
    assert np.all(b[on_body, 1] >= point[0, 1] - 1e-12)  # the planes hold after the passes


def test_points_to_test_moved_or_touching_unless_reused():
    rng = np.random.default_rng(4)
    n = 500
    x = rng.normal(size=(n, 3))
    x_checked = x + rng.normal(scale=1e-4, size=(n, 3))
    has_plane = rng.random(n) < 0.3
    reused = has_plane & (rng.random(n) < 0.5)
    active = np.zeros(n, dtype=bool)
    count = points_to_test(x, x_checked, has_plane, reused, 1e-4, active)
    moved = np.linalg.norm(x - x_checked, axis=1) > 1e-4
    expected = (moved | has_plane) & ~reused
    assert np.array_equal(active, expected) and count == expected.sum()
    assert 0 < count < n


def test_finish_step_is_the_substeps_kernels_one_by_one():
    """finish_step = the first substep's tail and the other substeps, each kernel called from Python as
    the loop did before they were fused: the same positions bit for bit."""
    x, springs, ends, table, on_body = _cloth()
    rng = np.random.default_rng(6)
    x_prev = x + rng.normal(scale=0.002, size=x.shape)
    inv_mass = np.ones(len(x))
    inv_mass[0] = 0.0  # one pinned corner
    w_eff = np.where(on_body, 0.2, 1.0) * inv_mass
    point = np.zeros((len(x), 3))
    point[:, 1] = x[:, 1].mean()
    normal = np.tile([0.0, 1.0, 0.0], (len(x), 1))
    touching = np.flatnonzero(on_body)
    body_ends, body_table, _ = contact_springs(ends, table, on_body)
    sweep_ends, sweep_lmax, _ = sweep_springs(*pack_sweep(ends, table, top_down_order(x, springs)), on_body,
                                              np.ones(len(x), dtype=np.bool_))
    h, n_sub, floor_y = 0.02 / 8, 8, float(x[:, 1].min()) + 0.01
    # the within-step test of points that moved far: never here (reach infinite), see test_sim.py for it
    idle = BodyCollider(_post(), 0.004).movers(DrapeState.at(x.copy(), inv_mass), np.zeros(0, dtype=np.int64), 0.0005,
                                               0.005, np.inf, False)
    a, a_prev, a_push = x.copy(), x_prev.copy(), np.zeros(len(x))
    one = np.zeros(3, dtype=np.int64)
    finish_step(a, a_prev, inv_mass, w_eff, Springs(ends, table, one), Springs(body_ends, body_table, one),
                Sweep(sweep_ends, sweep_lmax, one), Planes(touching, point, normal, on_body, a_push),
                Substeps(h, n_sub, 1, 2, 9.81, 1.0, 10.0, 0.6, 0.4, True, True, floor_y), idle)
    b, b_prev, b_push = x.copy(), x_prev.copy(), np.zeros(len(x))
    for sub in range(n_sub):
        if sub > 0:
            verlet_step(b, b_prev, inv_mass, h, 9.81, 1.0, 10.0)
            project_listed(b, b_prev, touching, point, normal, 0.6, 0.4)
            solve_listed(b, b_prev, w_eff, ends, table, 1, touching, point, normal, 0.0, 0.0, b_push)
            solve_listed(b, b_prev, w_eff, body_ends, body_table, 2, touching, point, normal, 0.0, 0.0, b_push)
        sweep_downward(b, b_prev, w_eff, sweep_ends, sweep_lmax, on_body)
        project_listed(b, b_prev, touching, point, normal, 0.0, 0.0, b_push)
        apply_friction(b, b_prev, touching, normal, b_push, 0.6, 0.4)
        keep_above_floor(b, b_prev, floor_y)
    assert not np.array_equal(a, x)  # it moved
    assert np.array_equal(a, b) and np.array_equal(a_prev, b_prev) and np.array_equal(a_push, b_push)


def test_the_within_step_test_takes_points_with_a_plane_too_while_a_reposed_body_moves():
    """A point that got a contact plane at the step's collision (on another part, here anywhere) and was then
    pulled 2 cm into the post by the springs: the within-step test passes it over as before (its plane is
    trusted), unless ``retest_planes`` (a re-posed body moving), which pushes it out onto the post's surface and
    gives it the post's plane; a point with a plane that has not moved past the reach is not tested at all."""
    from tryon.sim.collision.movers import collide_movers

    x = np.array([[0.03, 0.5, 0.0], [0.0, 0.5, 0.052]])  # 2 cm inside the 5 cm post; just outside it
    checked = np.array([[0.08, 0.5, 0.0], [0.0, 0.5, 0.052]])  # where the step's collision tested them
    inv_mass = np.ones(2)
    parts = np.zeros(1, dtype=np.int64)
    collider = BodyCollider(_post(), 0.004)
    for retest in (False, True):
        state = DrapeState.at(x.copy(), inv_mass)
        state.x_checked[:] = checked
        has_plane = np.ones(2, dtype=np.bool_)
        point = np.tile([0.0, 2.0, 0.0], (2, 1))  # a plane far above: it holds nothing here
        normal = np.tile([0.0, 1.0, 0.0], (2, 1))
        movers = collider.movers(state, parts, 0.0005, 0.005, 0.006, False, retest_planes=retest)
        y, y_prev = x.copy(), x.copy()
        tested = collide_movers(y, y_prev, inv_mass, movers, 0.6, 0.4, has_plane, point, normal)
        assert np.array_equal(y[1], x[1]) and normal[1, 1] == 1.0  # not moved past the reach: untouched
        if not retest:
            assert tested == 0 and np.array_equal(y, x)
        else:
            assert tested == 1 and has_plane[0]
            assert collider.depth(y[:1], parts, offset=True)[0] < 1e-6  # out of the post and its 4 mm offset
            assert normal[0] @ np.array([1.0, 0.0, 0.0]) > 0.9  # the post's plane, facing the point


def _post_and_arm_overlap() -> tuple[BodyCollider, np.ndarray, np.ndarray]:
    """A post and an arm pressed 1.5 cm into its front (a forearm on the torso), their collider (4 mm margin), the
    two part ids, and 300 seeded points (300, 3) m inside both offset parts (cloth squeezed between them)."""
    body = body_from_parts(np.array([[[0, 0.2, 0], [0, 0.8, 0]], [[-0.15, 0.5, 0.065], [0.15, 0.5, 0.065]]], float),
                           np.array([0.05, 0.03]))
    collider = BodyCollider(body, 0.004)
    parts = np.arange(2, dtype=np.int64)
    rng = np.random.default_rng(0)
    pts = np.column_stack([rng.uniform(-0.06, 0.06, 4000), rng.uniform(0.45, 0.55, 4000),
                           rng.uniform(0.02, 0.06, 4000)])
    both = (collider.depth(pts, parts[:1], offset=True) > 0) & (collider.depth(pts, parts[1:], offset=True) > 0)
    return collider, parts, pts[both][:300]


def test_a_pinched_point_is_held_only_where_it_is_not_deep():
    """Points in the overlap of a post and an arm pressed 1.5 cm into its front (cloth squeezed between a forearm
    and the torso): held where they were (a drape from scratch), most stay deeper than the reach of a step's
    collision (6 mm in the offset body); with ``hold_depth`` (a re-posed drape) those are put where the pushes
    left them least deep instead; points not held (the body moving) end at the least deep push, never deeper
    than at the last one."""
    collider, parts, pts = _post_and_arm_overlap()
    assert len(pts) == 300

    def deep_after(hold: bool, hold_depth: float) -> np.ndarray:
        x, n = pts.copy(), len(pts)
        planes = (np.zeros(n, dtype=np.bool_), np.zeros((n, 3)), np.zeros((n, 3)))
        collider.collide(x, pts.copy(), np.ones(n), np.ones(n, dtype=np.bool_), parts, 0.0005, 0.0, 0.0,
                         np.zeros(n, dtype=np.bool_), planes=planes, hold_pinched=hold,
                         held=np.zeros(n, dtype=np.bool_), hold_depth=hold_depth)
        return collider.depth(x, parts, offset=True)

    held, limited = deep_after(True, 1e9), deep_after(True, 0.006)
    assert (held > 0.006).sum() > 200 and (limited > 0.006).sum() < 30
    assert np.all(limited <= held + 1e-9)
    assert np.all(deep_after(False, 0.006) <= deep_after(False, 1e9) + 1e-9)


def test_a_point_pinched_between_two_parts_ends_between_them():
    """The shown mesh's last collision (``full_mesh.PINCHED_LEAST_DEEP``): points in the overlap of a post and an
    arm pressed 1.5 cm into it, pushed out of each into the other, end at the least deep of their pushes or of
    the middles of two pushes in a row (between the two parts, as deep in each): at most 4.2 mm inside the real
    surfaces, where the last push alone left them up to 9.8 mm inside the other part."""
    collider, parts, pts = _post_and_arm_overlap()

    def deepest_after(hold_depth: float) -> float:
        x, n = pts.copy(), len(pts)
        collider.collide(x, pts.copy(), np.ones(n), np.ones(n, dtype=np.bool_), parts, 0.0005, 0.0, 0.0,
                         np.zeros(n, dtype=np.bool_), hold_depth=hold_depth)
        return float(collider.depth(x, parts).max())

    assert deepest_after(1e9) > 0.008 and deepest_after(PINCHED_LEAST_DEEP) < 0.005


def test_a_pass_lengthens_a_crushed_spring_by_at_most_its_cap():
    """A chain of structural springs crushed to 5 % of their length (cloth in the fold of a bent elbow): a pass
    puts each back to its length at once, or with ``pack_springs``' fourth column (a re-posed drape's
    ``tuning.unfold_per_pass``) lengthens each by at most that much; stretched springs are not capped."""
    from tryon.sim.constraints import satisfy_springs, spring_lengths
    from tryon.sim.tuning import TUNING

    n = 6
    x = np.column_stack([np.linspace(0.0, 0.005 * 0.05 * (n - 1), n), np.zeros(n), np.zeros(n)])
    springs = np.column_stack([np.arange(n - 1), np.arange(1, n)])
    rest = np.full(n - 1, 0.005)
    ends, table = pack_springs(springs, rest, np.zeros(n - 1, dtype=np.int64), np.full(3, 0.1), np.ones(3))
    free = x.copy()
    satisfy_springs(free, np.ones(n), ends, table, 1)
    assert spring_lengths(free, springs).min() > 0.5 * 0.005  # sprung open at once
    table[:, 3] = TUNING.unfold_per_pass
    capped = x.copy()
    satisfy_springs(capped, np.ones(n), ends, table, 1)
    grown = spring_lengths(capped, springs) - spring_lengths(x, springs)
    assert 0.0 < grown.max() <= 2 * TUNING.unfold_per_pass + 1e-12  # each spring's own cap, and its neighbour's
    long, uncapped = x * 60.0, x * 60.0  # springs 3 x their length: shortened as without a cap
    satisfy_springs(long, np.ones(n), ends, table, 5)
    table[:, 3] = 0.0
    satisfy_springs(uncapped, np.ones(n), ends, table, 5)
    assert np.array_equal(long, uncapped) and spring_lengths(long, springs).max() < 2.0 * 0.005


def test_top_down_order_is_a_stable_sort_of_the_steep_springs_by_upper_end():
    x, springs, ends, table, on_body = _cloth()
    x[::7, 1] = x[0, 1]  # some exact height ties: they keep spring order
    a, b = x[springs[:, 0]], x[springs[:, 1]]
    everything = np.argsort(-np.maximum(a[:, 1], b[:, 1]), kind="stable")
    d = a - b
    steep = np.abs(d[:, 1]) >= 0.5 * STEEP * np.linalg.norm(d, axis=1)
    assert np.array_equal(top_down_order(x, springs, False), everything)
    order = top_down_order(x, springs)
    assert np.array_equal(order, everything[steep[everything]])
    assert 0 < len(order) < len(springs)


def test_spring_visits_count_the_passes_and_sweeps_of_a_step():
    """``perf.spring_visits`` (what the perf figure's step is made of) from finish_step's own arguments: 8
    substeps of 2 passes over 10 springs and 1 over the 4 on the body, the 6 hanging ones swept every
    substep, or only in the last; ``passed=1`` leaves out the first substep's passes (the caller's)."""
    import inspect

    from tryon.bench import perf

    names = list(inspect.signature(finish_step.py_func).parameters)
    one = np.zeros(3, dtype=np.int64)
    args = dict.fromkeys(names, 0)
    run = Substeps(0.02 / 8, 8, 2, 1, 9.81, 1.0, 10.0, 0.6, 0.4, True, True, 0.0)
    args.update(springs=Springs(np.zeros((10, 2)), np.zeros((10, 5)), one),
                on_body=Springs(np.zeros((4, 2)), np.zeros((4, 5)), one),
                sweep=Sweep(np.zeros((6, 2)), np.zeros(6), one), run=run)
    visits = perf.spring_visits([args[n] for n in names])
    assert visits["per_step"] == {"springs": 160, "contact_springs": 32, "sweep_springs": 48}
    assert visits["total"] == 240
    assert perf.spring_visits([args[n] for n in names], passed=1)["total"] == 140 + 28 + 48
    args["run"] = run._replace(sweep_every_substep=False)
    assert perf.spring_visits([args[n] for n in names])["per_step"]["sweep_springs"] == 6


def test_the_tear_guard_stops_once_every_spring_is_back_at_its_cap():
    # 50 separate springs of 1-3 cm pulled out to 2.6-4 x: the first sweep puts each back at 2.5 x, the second
    # finds none over and ends it (before the guard's slack, a spring put back at its cap was found over it
    # again by rounding, and the guard ran all its sweeps on every step where one had reached it)
    rng = np.random.default_rng(3)
    n = 50
    start = rng.normal(size=(n, 3))
    way = rng.normal(size=(n, 3))
    way /= np.linalg.norm(way, axis=1)[:, None]
    rest = rng.uniform(0.01, 0.03, n)
    x = np.vstack([start, start + way * (rest * rng.uniform(2.6, 4.0, n))[:, None]])
    springs = np.stack([np.arange(n), np.arange(n) + n], axis=1).astype(np.int64)
    sweeps = cap_stretch(x, np.ones(2 * n), springs, rest, 2.5, 100)
    assert sweeps == 2
    assert np.linalg.norm(x[:n] - x[n:], axis=1) / rest == pytest.approx(np.full(n, 2.5), rel=1e-9)
