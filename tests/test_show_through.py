"""Issue 32: body through cloth, the opposite of penetration, measured on the shown mesh."""

from __future__ import annotations

import numpy as np
import pytest

from tryon.sim.collision.collider import BodyCollider
from tryon.sim.collision.collider import relevant_parts
from tryon.sim.metrics import penetration_metrics
from tryon.bench.synthetic import stick_body
from tryon.sim.show_through import PROBE_IN, show_through_depth, show_through_metrics

TORSO_RADIUS = 0.15  # m, stick_body's
Y0, Y1 = 1.05, 1.30  # m: a band around the torso, clear of the hips and the arms


def prism(sides: int, corner_radius: float, rows: int = 6) -> tuple[np.ndarray, np.ndarray]:
    """An open prism around the y axis (the torso's), ``sides`` flat faces, its corners at ``corner_radius``
    m: (vertices (rows * sides, 3), faces)."""
    ang = np.linspace(0.0, 2 * np.pi, sides, endpoint=False)
    ys = np.linspace(Y0, Y1, rows)
    v = np.stack([np.tile(corner_radius * np.sin(ang), rows), np.repeat(ys, sides),
                  np.tile(corner_radius * np.cos(ang), rows)], axis=1)
    faces = []
    for r in range(rows - 1):
        for j in range(sides):
            a, b = r * sides + j, r * sides + (j + 1) % sides
            faces += [(a, b, b + sides), (a, b + sides, a + sides)]
    return v, np.asarray(faces, dtype=np.int64)


@pytest.fixture(scope="module")
def collider() -> BodyCollider:
    return BodyCollider(stick_body(n_around=48), margin=0.004)


def measure(collider: BodyCollider, vertices: np.ndarray, faces: np.ndarray) -> tuple[dict, dict]:
    parts = relevant_parts(collider.body.maps, vertices.min(axis=0), vertices.max(axis=0), 0.01)
    through = show_through_metrics(show_through_depth(collider, parts, vertices, faces))
    return through, penetration_metrics(collider.depth(vertices, parts))


def test_a_round_garment_just_outside_shows_no_body(collider):
    through, inside = measure(collider, *prism(96, TORSO_RADIUS + 0.005))
    assert through["body_through_vertices"] == 0 and inside["penetrating_vertices"] == 0


def test_flat_faces_cutting_under_the_skin_are_seen(collider):
    # a hexagon round the torso, corners 3 mm outside the skin: every garment vertex is outside (the
    # penetration metric sees nothing), but the middle of each face lies 0.866 x 15.3 = 13.2 cm from the
    # axis, 1.8 cm under the skin: the torso shows through all six faces
    vertices, faces = prism(6, TORSO_RADIUS + 0.003)
    through, inside = measure(collider, vertices, faces)
    assert inside["penetrating_vertices"] == 0
    expected_mm = 1000 * (TORSO_RADIUS - np.cos(np.pi / 6) * (TORSO_RADIUS + 0.003))
    assert through["body_through_vertices"] > 50
    assert through["max_body_through_mm"] == pytest.approx(min(expected_mm, 1000 * PROBE_IN), abs=1.0)


def test_skin_the_garment_does_not_cover_is_not_counted(collider):
    # a band of cloth 2 cm under the skin on the front only: the back of the torso is bare, not "through"
    vertices, faces = prism(96, TORSO_RADIUS - 0.010)
    front = vertices[:, 2] > 0.05
    keep = front[faces].all(axis=1)
    through, _ = measure(collider, vertices, faces[keep])
    depth = show_through_depth(collider, np.arange(len(collider.body.parts)), vertices, faces[keep])
    assert through["body_through_vertices"] > 0
    assert (collider.vertices[depth > 0][:, 2] > 0.04).all()  # only front skin, where the cloth is
    assert through["max_body_through_mm"] == pytest.approx(10.0, abs=1.0)


def test_lift_over_skin_mends_faces_cutting_under_the_skin_and_leaves_deeper_ones(collider):
    """A 12-sided prism whose corners are 3 mm out and whose faces' middles are 2.2 mm under the skin: the lift
    puts every covered body vertex under the cloth again (the faces bow out over their middles). Cloth 1.5 cm
    under the skin everywhere is deeper than ``deepest`` (1 cm) and is left as it is: that is a body part through
    the garment, not a chord across a curve."""
    from tryon.sim.show_through import lift_over_skin

    parts = np.arange(len(collider.body.parts))
    # the faces' middles 1000 * (0.15 - cos(15 deg) 0.153) = 2.2 mm under the skin
    vertices, faces = prism(12, TORSO_RADIUS + 0.003, rows=12)
    before = show_through_depth(collider, parts, vertices, faces)
    assert (before > 0.002).sum() > 20
    lifted = vertices.copy()
    for _ in range(3):
        lift_over_skin(collider, parts, lifted, faces, 0.001, 0.01)
    after = show_through_depth(collider, parts, lifted, faces)
    assert after.max() == 0.0
    assert np.abs(lifted - vertices).max() < 0.01  # a few mm, not a jump
    sunk, sunk_faces = prism(96, TORSO_RADIUS - 0.015, rows=12)
    assert show_through_depth(collider, parts, sunk, sunk_faces).max() > 0.014
    moved = sunk.copy()
    assert lift_over_skin(collider, parts, moved, sunk_faces, 0.001, 0.01) == 0
    assert np.array_equal(moved, sunk)
