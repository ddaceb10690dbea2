"""Cloth on its own cloth within a step (``sim/collision/self_contact.py``): what passes through another part of
the mesh in a step goes back to its side, a thickness off it; what goes round an edge, or began crossed, is left
where it is."""

from __future__ import annotations

import numpy as np

from tryon.garment.topology import face_edge_ids
from tryon.sim.collision.cloth import build_tri_grid
from tryon.sim.collision.crossings import find_crossings, self_intersections
from tryon.sim.collision.ccd import event_side
from tryon.sim.collision.contact_pairs import SelfContact
from tryon.sim.collision.self_contact import keep_sides
from test_untangle import grid_sheet

THICKNESS = 0.003


def two_sheets(gap: float, shift=(0.013, 0.0171)):
    """A flat sheet at z = 0 and a second over it at z = gap, shifted in x-y so that no point lies over a corner:
    vertices (2 n^2, 3) m, triangles (f, 3) int64, how many points the lower one has."""
    low, f_low = grid_sheet(7, 0.3, lambda x, y: 0.0 * x)
    high, f_high = grid_sheet(7, 0.3, lambda x, y: gap + 0.0 * x, shift=shift)
    return np.vstack([low, high]), np.vstack([f_low, f_high + len(low)]), len(low)


def contacts_for(faces: np.ndarray) -> SelfContact:
    faces = np.ascontiguousarray(faces, dtype=np.int64)
    edges, face_edges = face_edge_ids(faces)
    return SelfContact(faces, edges, face_edges, THICKNESS, THICKNESS + 0.01)


def dented(x0: np.ndarray, n_low: int, depth: float) -> np.ndarray:
    """x0 with the upper sheet's middle pushed ``depth`` m down (a dent), its rim where it was."""
    x = x0.copy()
    r2 = (x[n_low:, 0] - 0.15) ** 2 + (x[n_low:, 1] - 0.15) ** 2
    x[n_low:, 2] -= depth * np.exp(-r2 / 0.005)
    return x


def test_a_sheet_driven_through_another_within_a_step_comes_back_over_it():
    x0, faces, n_low = two_sheets(0.01)
    x = dented(x0, n_low, 0.03)  # 2 cm through the lower sheet within the step
    assert self_intersections(x, faces) > 0
    keep_sides(contacts_for(faces), x, x0.copy(), x0, np.ones(len(x)), THICKNESS, 3)
    assert self_intersections(x, faces) == 0
    # the push is shared: the lower sheet gave way too
    assert x[:n_low, 2].min() < -0.001


def test_a_held_sheet_does_not_move_and_the_other_ends_a_thickness_over_it():
    x0, faces, n_low = two_sheets(0.01)
    x = dented(x0, n_low, 0.03)
    w = np.ones(len(x))
    w[:n_low] = 0.0
    keep_sides(contacts_for(faces), x, x0.copy(), x0, w, THICKNESS, 3)
    assert self_intersections(x, faces) == 0
    np.testing.assert_array_equal(x[:n_low], x0[:n_low])
    over = (x[n_low:, 0] < 0.3) & (x[n_low:, 1] < 0.3)
    assert x[n_low:][over, 2].min() >= THICKNESS * 0.99


def test_sheets_apart_and_moving_apart_are_not_touched():
    x0, faces, n_low = two_sheets(0.02)
    x = x0.copy()
    x[n_low:, 2] += 0.005
    before = x.copy()
    pushed = keep_sides(contacts_for(faces), x, x0.copy(), x0, np.ones(len(x)), THICKNESS, 3)
    assert pushed == 0
    np.testing.assert_array_equal(x, before)


def test_a_point_that_goes_round_a_triangles_edge_keeps_the_side_it_ends_on():
    # one triangle in z = 0 over [0, 1] x [0, 1]; a point goes from above it, round its edge x = 1, to under it
    x0 = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.3, 0.3, 0.01]])
    x = x0.copy()
    x[3] = [0.3, 0.3, -0.002]
    mid = x0.copy()
    mid[3] = [1.5, 0.3, 0.0]
    # straight through: crossed, and back to the side it began on (above: the winding normal is +z)
    assert event_side(3, 0, 1, 0, 2, x, x0, True) == (1.0, True)
    # round the edge (two straight moves, the first to beside the triangle): not crossed, under it
    assert event_side(3, 0, 1, 0, 2, mid, x0, True)[1] is False
    assert event_side(3, 0, 1, 0, 2, x, mid, True) == (-1.0, False)


def test_two_edges_that_pass_through_each_other_go_back():
    # a wide strip along x and a narrow one along y over it, 5 mm up, crossing like a plus seen from above; the
    # narrow one's far end is driven 12 mm down, so that it ends through the wide one. No point of either is
    # ever over the other's triangles: only their edges meet
    x0 = np.array([[-0.1, -0.05, 0.0], [0.1, -0.05, 0.0], [-0.1, 0.05, 0.0], [0.1, 0.05, 0.0],
                   [0.0, -0.1, 0.005], [0.0, 0.1, 0.005], [0.001, -0.1, 0.005], [0.001, 0.1, 0.005]])
    faces = np.array([[0, 1, 3], [0, 3, 2], [4, 5, 7], [4, 7, 6]], dtype=np.int64)
    x = x0.copy()
    x[[4, 6], 2] -= 0.012
    assert self_intersections(x, faces) > 0
    keep_sides(contacts_for(faces), x, x0.copy(), x0, np.ones(len(x)), THICKNESS, 3)
    assert self_intersections(x, faces) == 0
    # the narrow strip is over the wide one where they cross, a thickness off it
    at_edge = 0.5 * (x[4] + x[6]) + (0.05 / 0.2) * (0.5 * (x[5] + x[7]) - 0.5 * (x[4] + x[6]))  # y = -0.05
    assert at_edge[2] - 0.5 * (x[0, 2] + x[1, 2]) >= THICKNESS * 0.99


def test_a_mesh_that_began_crossed_is_left_crossed_not_locked_worse():
    # the second sheet already through the first where the step begins: nothing passes through anything within
    # the step, so nothing is pushed back (the untangling's work, not this)
    x0, faces, n_low = two_sheets(-0.005)
    x0[n_low:, 2] += 0.01 * np.sin(x0[n_low:, 0] * 20.0 + 0.3)  # wavy: partly over, partly under
    start = self_intersections(x0, faces)
    assert start > 0
    x = x0.copy()
    x[:, 2] -= 0.001  # both fall together a millimetre
    keep_sides(contacts_for(faces), x, x0.copy(), x0, np.ones(len(x)), THICKNESS, 3)
    assert self_intersections(x, faces) == start


def test_where_a_mesh_began_crossed_no_side_is_kept():
    # the crossed sheets above, the upper one lifted 3 cm within the step: the points of the edges and triangles
    # that cross where the step begins keep no side (the untangling's), so they go where the step takes them; the
    # rest of the upper sheet keeps its sides
    x0, faces, n_low = two_sheets(-0.005)
    x0[n_low:, 2] += 0.01 * np.sin(x0[n_low:, 0] * 20.0 + 0.3)
    start = self_intersections(x0, faces)
    edges, _ = face_edge_ids(faces)
    hits = find_crossings(x0, edges, faces, build_tri_grid(x0, faces, 0.03, 0.0))
    tangled = np.unique(np.concatenate([edges[hits[:, 0]].ravel(), faces[hits[:, 1]].ravel()]))
    x = x0.copy()
    x[n_low:, 2] += 0.03
    lifted = x.copy()
    keep_sides(contacts_for(faces), x, x0.copy(), x0, np.ones(len(x)), THICKNESS, 3)
    np.testing.assert_array_equal(x[tangled], lifted[tangled])
    assert self_intersections(x, faces) <= start


def _pair_sets(contacts: SelfContact) -> tuple[set, set]:
    return set(map(tuple, contacts.points.tolist())), set(map(tuple, contacts.edge_pairs.tolist()))


def test_a_point_that_strays_has_its_pairs_listed_again_and_nothing_near_is_missed():
    """A list kept while a few points move (a hem still swinging) is made again for those points only (here one of
    98, under ``PARTIAL_SHARE``); it must hold every pair a whole new list finds, and it is kept as it is while the
    mesh moves as a whole."""
    x0, faces, n_low = two_sheets(0.006)
    contacts = contacts_for(faces)
    contacts.update(x0, x0)
    assert contacts.whole and len(contacts.points) > 0
    # the whole mesh moved 5 cm: no pair came nearer, nothing is listed again
    moved = x0 + np.array([0.0, 0.05, 0.0])
    listed = contacts.points.copy()
    contacts.update(moved, moved)
    np.testing.assert_array_equal(contacts.points, listed)
    # a point in the middle of the upper sheet dips 8 mm (past the allowance), to 2 mm under the lower sheet's plane
    contacts = contacts_for(faces)
    contacts.update(x0, x0)
    x = x0.copy()
    strays = [n_low + 24]
    x[strays, 2] -= 0.008
    contacts.update(x, x0)
    assert not contacts.whole  # only the stray's pairs were listed again
    whole = contacts_for(faces)
    whole.update(x, x0)
    points, edge_pairs = _pair_sets(contacts)
    whole_points, whole_edges = _pair_sets(whole)
    assert whole_points <= points and whole_edges <= edge_pairs
    assert any(i in strays for i, _ in whole_points)
