"""The self-contact's broad phase by patches (``sim/collision/patches.py``): every pair a brute-force search finds
within the reach, but none inside a piece of cloth that is flat."""

from __future__ import annotations

import numpy as np

from tryon.garment.topology import face_edge_ids, faces_on_edges
from tryon.sim.collision import patches
from tryon.sim.collision.contact_pairs import SelfContact, _pairs_of_moved
from test_untangle import grid_sheet

REACH = 0.013  # m: the lists' reach at a 3 mm thickness (``test_self_contact.contacts_for``)
RADIUS = 0.005  # m: the fold's radius: its two layers 1 cm apart


def folded(x: np.ndarray, at: float) -> np.ndarray:
    """A flat sheet x (n, 3) m at z = 0 folded back over itself across x = ``at`` round a cylinder of ``RADIUS``."""
    out = x.copy()
    s = x[:, 0] - at
    bend = (s > 0) & (s < np.pi * RADIUS)
    out[bend, 0] = at + RADIUS * np.sin(s[bend] / RADIUS)
    out[bend, 2] = RADIUS * (1.0 - np.cos(s[bend] / RADIUS))
    back = s >= np.pi * RADIUS
    out[back, 0] = at - (s[back] - np.pi * RADIUS)
    out[back, 2] = 2.0 * RADIUS
    return out


def mesh(faces: np.ndarray):
    faces = np.ascontiguousarray(faces, dtype=np.int64)
    edges, face_edges = face_edge_ids(faces)
    return faces, edges, patches.make_patches(faces, int(faces.max()) + 1, faces_on_edges(face_edges, len(edges)),
                                              face_edges)


def brute_force(x, x0, faces, edges):
    points, pairs = _pairs_of_moved(x, x0, faces, edges, np.ones(len(x), dtype=np.bool_), REACH)
    return set(map(tuple, points.tolist())), set(map(tuple, pairs.tolist()))


def listed(x, x0, faces, edges, patched, cos_flat=None):
    if cos_flat is None:
        points, pairs, _ = patches.listed_pairs(x, x0, faces, edges, patched, REACH)
    else:  # nothing flat: every pair of patches within reach searched
        points, pairs = np.empty((50000, 2), dtype=np.int64), np.empty((50000, 2), dtype=np.int64)
        n, m, _ = patches.near_pairs(x, x0, faces, edges, patched.face_start, patched.face_ids,
                                     patched.point_start, patched.point_ids, patched.edge_start, patched.edge_ids,
                                     patched.near, REACH, cos_flat, points, pairs, np.empty((50000, 2), np.int64))
        points, pairs = points[:n], pairs[:m]
    return set(map(tuple, points.tolist())), set(map(tuple, pairs.tolist()))


def test_every_triangle_is_in_one_patch_and_every_point_and_edge_owned_once():
    x, faces = grid_sheet(21, 0.6, lambda gx, gy: 0.0 * gx)
    faces, edges, patched = mesh(faces)
    assert sorted(patched.face_ids.tolist()) == list(range(len(faces)))
    assert sorted(patched.point_ids[:patched.point_start[-1]].tolist()) == list(range(len(x)))
    assert sorted(patched.edge_ids.tolist()) == list(range(len(edges)))
    sizes = np.diff(patched.face_start)
    assert sizes.max() == patches.PATCH_FACES and np.median(sizes) == patches.PATCH_FACES
    assert np.all(np.diag(patched.near)) and np.array_equal(patched.near, patched.near.T)


def test_with_nothing_flat_the_patches_find_what_a_search_of_every_pair_finds():
    # a folded sheet whose points moved a few millimetres at random within the step
    rng = np.random.default_rng(7)
    x, faces = grid_sheet(21, 0.6, lambda gx, gy: 0.0 * gx)
    faces, edges, patched = mesh(faces)
    x0 = folded(x, 0.31)
    x1 = x0 + rng.normal(0.0, 0.003, x0.shape)
    points, pairs = brute_force(x1, x0, faces, edges)
    assert len(points) > 100 and len(pairs) > 100
    assert listed(x1, x0, faces, edges, patched, cos_flat=2.0) == (points, pairs)


def test_a_flat_sheet_lists_nothing_and_a_folded_one_every_pair_across_its_fold():
    # 1 cm triangles: the sheet's own neighbours are within the reach of each other
    x, faces = grid_sheet(61, 0.6, lambda gx, gy: 0.0 * gx)
    faces, edges, patched = mesh(faces)
    x[:, 2] = 0.02 * np.sin(x[:, 0] * 6.0)  # gently waved: flat within the patches' angle
    assert listed(x, x, faces, edges, patched) == (set(), set())
    x = folded(grid_sheet(61, 0.6, lambda gx, gy: 0.0 * gx)[0], 0.305)
    points, pairs = listed(x, x, faces, edges, patched)
    all_points, all_pairs = brute_force(x, x, faces, edges)
    assert points <= all_points and pairs <= all_pairs
    # the layers' pairs away from the fold, within which a pair 1 cm apart is only a bend the patches see as a
    # height field (they cannot cross there without it turning further, which the next list sees)
    lower, away = x[:, 2] < RADIUS, np.abs(x[:, 0] - 0.305) > 0.02
    across = {(i, f) for i, f in all_points if (lower[faces[f]] != lower[i]).all() and away[faces[f]].all()}
    across_edges = {(e, k) for e, k in all_pairs if (lower[edges[e]] != lower[edges[k][0]]).all()
                    and lower[edges[k][0]] == lower[edges[k][1]] and away[edges[[e, k]]].all()}
    assert len(across) > 1000 and across <= points
    assert len(across_edges) > 1000 and across_edges <= pairs
    within = {(i, f) for i, f in all_points if (lower[faces[f]] == lower[i]).all() and away[faces[f]].all()}
    assert len(within) > 1000 and not within & points  # the layers' own near neighbours: left out


def test_a_list_is_made_again_when_a_piece_it_left_out_as_flat_bends():
    # a sheet of 3 mm triangles, pairs listed within 5 mm (thickness 1 mm, each point allowed 2 mm): all of it
    # left out while flat; pleated by 1.8 mm up and down row by row (under the allowance), its triangles tilt 50
    # degrees, past the flat angle, and the list is made again
    x, faces = grid_sheet(21, 0.06, lambda gx, gy: 0.0 * gx)
    faces = np.ascontiguousarray(faces, dtype=np.int64)
    edges, face_edges = face_edge_ids(faces)
    contacts = SelfContact(faces, edges, face_edges, 0.001, 0.005)
    contacts.update(x, x)
    assert len(contacts.points) == 0 and len(contacts.edge_pairs) == 0 and len(contacts.flats) > 0
    assert not contacts.update(x + 0.001, x + 0.001)  # moved as a whole: kept
    pleated = x.copy()
    pleated[:, 2] = np.where(np.round(x[:, 0] / 0.003) % 2 == 0, 0.0018, -0.0018)
    assert contacts.update(pleated, pleated)
    assert len(contacts.points) > 0
