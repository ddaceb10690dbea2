"""Two threads for one drape (``tryon.sim.blocks``): a large garment's springs in two blocks that share no
point, run at once, with the numbers of one thread running them one after the other."""

from __future__ import annotations

import threading

import numpy as np
import pytest

from tryon.api.pool import SimPool
from tryon.bench.synthetic import cloth_square
from tryon.sim.blocks import (
    MIN_SPLIT_SPRINGS, block_order, machine_threads, parallel_ok, split_springs, sweep_blocked, use_threads,
)
from tryon.sim.constraints import pack_springs, satisfy_springs, solve_listed
from tryon.sim.settings import SimSettings

S = SimSettings()


def _packed(n: int):
    model = cloth_square(1.0, n, 1.0)
    order, blocks = split_springs(model.springs, model.coarse_vertices, min_springs=0)
    ends, table = pack_springs(model.springs[order], model.rest[order], model.kind[order], S.limits_array(),
                               S.compression_array())
    return model, ends, table, blocks


def test_the_blocks_share_no_point_and_the_boundary_is_thin():
    model, ends, _, blocks = _packed(41)
    na, nb = int(blocks[0]), int(blocks[1])
    a, b = set(ends[:na].ravel().tolist()), set(ends[na:na + nb].ravel().tolist())
    assert not a & b
    assert abs(na - nb) < 0.1 * na  # cut at the median: halves of about equal work (41 rows: 20 and 21)
    boundary = len(ends) - na - nb
    assert 0 < boundary < 0.05 * len(ends)  # one row's springs of 41
    # a small garment keeps one block, in its own order (the catalogue's drapes unchanged)
    order, small = split_springs(model.springs, model.coarse_vertices)
    assert len(model.springs) < MIN_SPLIT_SPRINGS and not small.any() and np.array_equal(order, np.arange(len(order)))


def test_blocked_passes_equal_block_a_then_b_then_the_boundary_on_one_or_two_threads():
    _, ends, table, blocks = _packed(41)
    na, nb = int(blocks[0]), int(blocks[1])
    m = na + nb
    rng = np.random.default_rng(3)
    start = cloth_square(1.0, 41, 1.0).coarse_vertices + rng.normal(0.0, 0.01, (41 * 41, 3))
    w = np.ones(len(start))
    # the reference: each pass block by block on one thread (forward A, B, boundary; backward boundary, A, B)
    ref = start.copy()
    for p in range(4):
        parts = [(0, na), (na, m), (m, len(ends))] if p % 2 == 0 else [(m, len(ends)), (0, na), (na, m)]
        for lo, hi in parts:
            sub = ends[lo:hi] if p % 2 == 0 else ends[lo:hi][::-1]
            tab = table[lo:hi] if p % 2 == 0 else table[lo:hi][::-1]
            satisfy_springs(ref, w, np.ascontiguousarray(sub), np.ascontiguousarray(tab), 1)
    none = np.zeros(0, dtype=np.int64)
    plane = np.zeros((len(start), 3))
    results = []
    for threads, allow in ((1, 0), (1, 1), (machine_threads(), 1)):
        use_threads(threads)
        x = start.copy()
        solve_listed(x, x.copy(), w, ends, table, 4, none, plane, plane, 0.0, 0.0, np.zeros(len(x)), 1.0,
                     np.array([na, nb, allow and int(parallel_ok())]))
        results.append(x)
    use_threads(machine_threads())
    for x in results:
        assert np.array_equal(x, ref)
    assert np.abs(results[0] - start).max() > 1e-3  # the passes did move the cloth


def test_a_blocked_sweep_keeps_top_down_order_within_each_block():
    _, ends, table, blocks = _packed(41)
    rng = np.random.default_rng(5)
    order = rng.permutation(len(ends))
    grouped, sizes = block_order(order, blocks)
    na, nb = int(blocks[0]), int(blocks[1])
    assert sizes[0] == (order < na).sum() and sizes[1] == ((order >= na) & (order < na + nb)).sum()
    a = grouped[:sizes[0]]
    assert np.array_equal(a, order[order < na])  # A's springs in the order given
    assert np.array_equal(np.sort(grouped), np.arange(len(ends)))
    # one thread or two, the same sweep
    x0 = cloth_square(1.0, 41, 1.0).coarse_vertices.copy()
    x0[:, 1] -= np.linspace(0.0, 0.2, len(x0))  # lower ends fell: the sweep lifts them
    sweep_ends = np.ascontiguousarray(ends[grouped])
    lmax = np.ascontiguousarray(table[grouped, 0] * 0.9)
    out = []
    for threads in (1, machine_threads()):
        use_threads(threads)
        x, xp = x0.copy(), x0.copy()
        xp[:, 1] += 0.05
        sweep_blocked(x, xp, np.ones(len(x)), sweep_ends, lmax, np.zeros(len(x), dtype=np.bool_), sizes)
        out.append(x)
    use_threads(machine_threads())
    assert np.array_equal(out[0], out[1])
    assert not np.array_equal(out[0], x0)


def test_a_large_drape_is_the_same_on_one_thread_and_on_two():
    from tryon.bench.ours_cloth import run_sphere

    runs = []
    for threads in (1, machine_threads()):
        use_threads(threads)
        runs.append(run_sphere(64, 12))  # 4,096 points, 23,938 springs: split in two blocks
    use_threads(machine_threads())
    keys = ("max_stretch", "final_stretch", "final_lowest_y", "max_penetration_mm", "answer_stretch")
    assert [runs[0][k] for k in keys] == [runs[1][k] for k in keys]
    assert runs[0]["finite"] and runs[0]["max_penetration_mm"] <= 2.0


def test_the_pool_shares_the_cores_between_running_try_ons():
    pool = SimPool(workers=2, queue=0, wall_limit_s=5.0)
    cores = machine_threads()
    release = threading.Event()
    seen = []

    started = [threading.Event(), threading.Event()]

    def job():
        seen.append(pool.thread_share())
        started[len(seen) - 1].set()
        release.wait(60.0)
        return True

    try:
        first = pool.submit(job)
        assert started[0].wait(60.0)  # a guard against a hang, not a measured limit
        assert seen == [cores]  # alone: every core
        second = pool.submit(job)
        assert started[1].wait(60.0)
        assert seen[1] == max(1, cores // 2)
        assert pool.thread_share() == max(1, cores // 2)
        release.set()
        assert first.result(60.0) and second.result(60.0)
    finally:
        release.set()
        pool.shutdown()


@pytest.mark.skipif(not parallel_ok(), reason="no thread-safe threading layer on this machine")
def test_two_pool_threads_launch_parallel_passes_at_once():
    """The pool's worker threads launch the parallel kernels at the same time: a thread-safe layer (OpenMP,
    TBB) is required for that, and ``blocks`` asks for one."""
    import numba

    _, ends, table, blocks = _packed(41)
    start = cloth_square(1.0, 41, 1.0).coarse_vertices + 0.01
    out = [None, None]

    def run(k):
        use_threads(machine_threads())
        x = start.copy()
        none = np.zeros(0, dtype=np.int64)
        plane = np.zeros((len(x), 3))
        for _ in range(20):
            solve_listed(x, x.copy(), np.ones(len(x)), ends, table, 4, none, plane, plane, 0.0, 0.0,
                         np.zeros(len(x)), 1.0, blocks)
        out[k] = x

    threads = [threading.Thread(target=run, args=(k,)) for k in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert numba.threading_layer() in ("omp", "tbb")
    assert np.array_equal(out[0], out[1])


def test_the_collision_on_two_threads_equals_one_call_over_all_points():
    """``collide_halves``: half the points a thread, each writing only its own rows: the same pushes, planes and
    held flags as one ``collide_points`` call."""
    from tryon.bench.ours_cloth import sphere_body
    from tryon.sim.collision.collider import BodyCollider

    collider = BodyCollider(sphere_body(0.3), 0.004)
    rng = np.random.default_rng(11)
    d = rng.normal(size=(2001, 3))
    x0 = d / np.linalg.norm(d, axis=1)[:, None] * rng.uniform(0.27, 0.33, (2001, 1))  # inside and outside
    outs = []
    for two in (False, True):
        x, xp = x0.copy(), x0 * 0.99
        planes = (np.zeros(len(x), dtype=np.bool_), np.zeros((len(x), 3)), np.zeros((len(x), 3)))
        contact, held = np.zeros(len(x), dtype=np.bool_), np.zeros(len(x), dtype=np.bool_)
        moved = collider.collide(x, xp, np.ones(len(x)), np.ones(len(x), dtype=np.bool_), np.zeros(1, np.int64),
                                 0.0005, 0.6, 0.4, contact, near=0.005, planes=planes, hold_pinched=True, held=held,
                                 hold_depth=0.006, two=two)
        outs.append((moved, x, xp, contact, held, *planes))
    assert outs[0][0] > 500  # about half the points started inside
    for a, b in zip(outs[0], outs[1]):
        assert np.array_equal(a, b)



def test_the_relaxations_collision_on_two_threads_equals_one_call():
    """The relaxation's collision (``relax.collide_all``: no planes asked, no pinch held) on two threads: the same
    pushes and contacts as one call."""
    from tryon.bench.ours_cloth import sphere_body
    from tryon.sim.collision.collider import BodyCollider

    collider = BodyCollider(sphere_body(0.3), 0.004)
    rng = np.random.default_rng(12)
    d = rng.normal(size=(1501, 3))
    x0 = d / np.linalg.norm(d, axis=1)[:, None] * rng.uniform(0.27, 0.33, (1501, 1))
    outs = []
    for two in (False, True):
        x, contact = x0.copy(), np.zeros(len(x0), dtype=np.bool_)
        moved = collider.collide(x, x0 * 0.99, np.ones(len(x)), np.ones(len(x), dtype=np.bool_),
                                 np.zeros(1, np.int64), 0.0005, 0.0, 0.0, contact, two=two)
        outs.append((moved, x, contact))
    assert outs[0][0] > 400
    for a, b in zip(outs[0], outs[1]):
        assert np.array_equal(a, b)

def test_the_depth_on_two_threads_equals_one_call_over_all_points():
    """``depth_halves``: half the points a thread, each writing its own half of the answer: the depths of one
    ``penetration_depth`` call (an odd count, so the halves differ in size)."""
    from tryon.bench.ours_cloth import sphere_body
    from tryon.sim.collision.collider import BodyCollider

    collider = BodyCollider(sphere_body(0.3), 0.004)
    rng = np.random.default_rng(12)
    d = rng.normal(size=(2001, 3))
    x = d / np.linalg.norm(d, axis=1)[:, None] * rng.uniform(0.27, 0.33, (2001, 1))
    one, two = (collider.depth(x, np.zeros(1, np.int64), two=t) for t in (False, True))
    assert np.array_equal(one, two)
    # about half start inside, as deep as the ball's radius minus theirs (within its facets' sag)
    expected = 0.3 - np.linalg.norm(x, axis=1)
    inside = expected > 0.002
    assert inside.sum() > 500 and np.abs(one[inside] - expected[inside]).max() < 0.002
    assert np.all(one[expected < -0.002] == 0.0)


def test_the_points_kernels_on_two_threads_equal_one_call():
    """``verlet_split``, ``project_split`` and ``friction_split`` with ``two``: half the points (or half the
    listed ones) a thread, each writing its own rows: the positions, pushes and friction of one call over all
    (an odd count, so the halves differ in size)."""
    from tryon.sim.collision.contacts import friction_split, project_split
    from tryon.sim.integrate import verlet_split

    rng = np.random.default_rng(13)
    k = 3001
    x0 = rng.normal(size=(k, 3))
    xp0 = x0 + rng.normal(scale=0.01, size=(k, 3))
    w = rng.uniform(0.0, 2.0, k)
    w[::7] = 0.0  # pinned points
    listed = np.flatnonzero(rng.random(k) < 0.6)
    normal = rng.normal(size=(k, 3))
    normal /= np.linalg.norm(normal, axis=1)[:, None]
    point = x0 + normal * rng.uniform(-0.02, 0.02, (k, 1))  # some points behind their plane, some in front
    outs = []
    for two in (False, True):
        x, xp, push = x0.copy(), xp0.copy(), np.zeros(k)
        verlet_split(x, xp, w, 0.01, 9.81, 1.0, 10.0, two)
        project_split(x, xp, listed, point, normal, 0.6, 0.4, None, two)
        project_split(x, xp, listed, point, normal, 0.0, 0.0, push, two)
        pushed = push.copy()
        friction_split(x, xp, listed, normal, push, 0.6, 0.4, two)
        outs.append((x, xp, pushed, push))
    assert (outs[0][2] > 0).sum() > 100  # the planes pushed many points
    for a, b in zip(outs[0], outs[1]):
        assert np.array_equal(a, b)


def test_the_projections_active_set_on_two_threads_is_that_of_one_scan():
    """The fast projection's scan for the springs over their limits (``projection._active``) on two blocks at once:
    the same springs, in the same order, with the same directions and excesses as one scan over all; and a
    projection with the blocks lands where one without them does."""
    from tryon.sim.projection import _active, project_stretch

    model, ends, table, blocks = _packed(40)
    assert blocks[2] == int(parallel_ok())
    rng = np.random.default_rng(14)
    x0 = model.coarse_vertices * 1.08 + rng.normal(scale=0.002, size=model.coarse_vertices.shape)  # stretched
    w = np.ones(len(x0))
    free_along = np.zeros(len(x0), dtype=np.bool_)
    normals = np.tile([0.0, 1.0, 0.0], (len(x0), 1))
    found = []
    for b in (np.zeros(3, np.int64), np.array([blocks[0], blocks[1], 1])):
        act, dirs, c, diag = np.empty(len(ends), np.int64), np.empty((len(ends), 3)), np.empty(len(ends)), \
            np.empty(len(ends))
        m, left = _active(x0, w, ends, table, free_along, normals, act, dirs, c, diag, b)
        x = x0.copy()
        project_stretch(x, w, ends, table, free_along, normals, 4, b)
        found.append((m, left, act[:m], dirs[:m], c[:m], diag[:m], x))
    assert found[0][0] > 1000  # most springs start over their limit
    for a, b in zip(found[0], found[1]):
        assert np.array_equal(a, b)
