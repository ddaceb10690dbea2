"""The sleeves-and-legs metric (``sim/limbs.py``) on a synthetic limb: an upright cylinder of radius 4 cm."""

from __future__ import annotations

import numpy as np
import pytest

from tryon.sim.limbs import around_part, ring_order

A = np.array([0.0, 1.0, 0.0])  # the joint
B = np.array([0.0, 0.6, 0.0])  # the far end: a 40 cm part pointing down


def _ring(radius: float, y: float, start_deg: float = 0.0, span_deg: float = 360.0, n: int = 16,
          centre=(0.0, 0.0)) -> np.ndarray:
    a = np.radians(start_deg + span_deg * np.arange(n) / (n if span_deg == 360.0 else n - 1))
    return np.stack([centre[0] + radius * np.cos(a), np.full(n, y), centre[1] + radius * np.sin(a)], axis=1)


@pytest.fixture(scope="module")
def surface():
    ys = np.linspace(0.6, 1.0, 41)
    return np.concatenate([_ring(0.04, y, n=24) for y in ys])


def test_a_cuff_around_the_limb_is_around_it(surface):
    assert around_part(_ring(0.05, 0.8), A, B, surface)
    # tilted 40 degrees and flattened to an ellipse it still goes round
    ring = _ring(0.06, 0.8)
    ring[:, 0] *= 0.7
    ring[:, 1] += np.tan(np.radians(40)) * ring[:, 0]
    assert around_part(ring, A, B, surface)
    # over the far end (a hand, a foot) and a little past it
    assert around_part(_ring(0.05, 0.55), A, B, surface)


def test_a_wide_armhole_the_limb_passes_through_near_its_edge_is_around_it(surface):
    assert around_part(_ring(0.12, 0.95, centre=(0.08, 0.0), n=24), A, B, surface)


def test_an_opening_beside_the_limb_is_not_around_it(surface):
    assert not around_part(_ring(0.05, 0.8, centre=(0.15, 0.0)), A, B, surface)  # a cuff hanging beside it
    # a cuff flattened against one side (a hand come out through the side of the sleeve's end)
    flat = _ring(0.05, 0.8)
    flat[:, 2] *= 0.1
    flat[:, 0] += 0.1
    assert not around_part(flat, A, B, surface)
    assert not around_part(_ring(0.3, 0.8), A, B, surface)  # a skirt-wide ring
    assert not around_part(_ring(0.05, 1.2), A, B, surface)  # above the joint, around nothing of this part


def test_ring_order_puts_a_shuffled_tilted_ring_back_in_order():
    ring = _ring(0.05, 0.8, n=20)
    ring[:, 1] += 0.5 * ring[:, 0]
    shuffled = np.random.default_rng(0).permutation(20)
    order = shuffled[ring_order(ring[shuffled])]
    steps = np.diff(np.append(order, order[0])) % 20
    assert set(steps) in ({1}, {19})  # consecutive round the ring, one way or the other


def test_an_armhole_the_arm_leaves_across_its_plane_is_round_the_arm():
    """``through_root``: an armhole round a raised arm's root that lies along the arm (its plane holds the arm's
    axis: seen along the axis a sliver beside it, so the winding test fails) is round the arm if the path from
    the torso's axis out through the shoulder joint and along the arm pierces it; the same ring moved off the
    shoulder, or one round the middle of the upper arm (not its root), is not taken so."""
    from tryon.body.build import build_body
    from tryon.body.params import Measurements, Pose
    from tryon.sim.landmarks import part_points
    from tryon.sim.limbs import through_root

    body = build_body(Measurements(height=170, chest=96, waist=82, hips=100), Pose(arm_forward_right=89.0))
    k = body.parts.index("upper_arm_r")
    a, b = body.part_axes[k]
    axis = (b - a) / np.linalg.norm(b - a)  # forwards
    up = np.array([0.0, 1.0, 0.0]) - axis[1] * axis
    up /= np.linalg.norm(up)
    t0, t1 = body.part_axes[body.parts.index("torso")]
    trunk = t0 + ((a - t0) @ (t1 - t0)) / ((t1 - t0) @ (t1 - t0)) * (t1 - t0)
    angles = np.linspace(0.0, 2.0 * np.pi, 24, endpoint=False)[:, None]
    # a ring in the plane of the arm's axis and "up", round the shoulder between the torso's axis and the joint
    along = a + 0.3 * (trunk - a) + 0.07 * (np.cos(angles) * axis + np.sin(angles) * up)
    assert not around_part(along, a, b, part_points(body, k)) and through_root(along, body, k)
    assert not through_root(along + 0.25 * up, body, k)  # above the shoulder
    side = np.cross(axis, up)
    across = a + 0.45 * (b - a) + 0.06 * (np.cos(angles) * side + np.sin(angles) * up)  # round the middle
    assert around_part(across, a, b, part_points(body, k)) and not through_root(across, body, k)


def test_a_tight_coarse_hem_chorded_across_the_leg_is_judged_on_the_shown_hem():
    """The MakeHuman trousers on a 163 cm ANSUR body: a few coarse hem points, one chord across the ankle,
    leave the shin's centre outside the coarse ring while the shown hem goes round it."""
    from types import SimpleNamespace

    from tryon.body.build import build_body
    from tryon.body.params import Measurements, Pose
    from tryon.sim.landmarks import part_points
    from tryon.sim.limbs import openings_on_limbs, openings_on_shown_limbs

    body = build_body(Measurements(height=170, chest=96, waist=82, hips=100), Pose())
    k = body.parts.index("shin_l")
    a, b = body.part_axes[k]
    skin = part_points(body, k)
    y = float((a + 0.7 * (b - a))[1])
    section = skin[np.abs(skin[:, 1] - y) < 0.015]
    centre = section.mean(axis=0)
    radius = float(np.linalg.norm((section - centre)[:, [0, 2]], axis=1).max()) + 0.006

    def hem(shift: float) -> np.ndarray:
        return _ring(radius, y, n=18, centre=(centre[0] + shift, centre[2]))

    coarse_ids = np.array([1, 3, 6, 8])  # 20, 60, 120, 160 degrees: the chord 160 -> 20 passes the front
    for shift, on in ((0.0, True), (0.15, False)):  # round the shin; hanging 15 cm beside it
        full = hem(shift)
        model = SimpleNamespace(vertices=full, loops=[np.arange(18)], coarse_index=coarse_ids)
        openings = [("left", "leg", np.arange(4))]
        assert not openings_on_limbs(full[coarse_ids], body, openings)[0]["ok"]
        judged = openings_on_shown_limbs(full[coarse_ids], full, model, body, openings)[0]
        assert judged["ok"] is on and judged["around"] == ("shin_l" if on else None)
