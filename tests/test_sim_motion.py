"""Accurate in motion (issue 30): how deep the cloth goes inside the body while the body moves
(``motion_max_penetration_mm``, measured against the body as it is at each step), and the motion stress
(``tryon bench --only motion``) in small: seeded random pose sequences through the sim-level re-pose."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from tryon.bench.motion import MOTION_PENETRATION_TARGET_MM, deepest_point, motion_stress, too_tight_there
from tryon.bench.stress import MAX_STRETCH, catalogue_models
from tryon.body.build import build_body
from tryon.body.params import Measurements, pose_from
from tryon.sim.collision.collider import BodyCollider
from tryon.sim.metrics import deepest_inside
from tryon.sim.repose import repose
from tryon.sim.run import settle
from tryon.sim.settings import SimSettings
from tryon.sim.start import start

MEDIUM = Measurements(height=170, chest=96, waist=82, hips=100)


def test_a_point_inside_a_turned_forearm_is_as_deep_as_it_was_put():
    """A point 5 mm under the skin of the middle of the left forearm (along the vertex normal, inwards) is 5 mm
    deep; with the forearm turned 60 degrees about the elbow, the point turned with it is still 5 mm deep and
    the point left where it was is outside: the depth is taken against the body as it is now."""
    body = build_body(MEDIUM)
    collider = BodyCollider(body, SimSettings().collision_margin)
    k = body.parts.index("forearm_l")
    ids = np.flatnonzero(body.vertex_part == k)
    elbow, wrist = np.asarray(body.joints["elbow_l"]), np.asarray(body.joints["wrist_l"])
    axis = (wrist - elbow) / np.linalg.norm(wrist - elbow)
    along = (body.vertices[ids] - elbow) @ axis / np.linalg.norm(wrist - elbow)
    v = ids[np.argmin(np.abs(along - 0.5))]  # halfway down the forearm, away from its ends
    point = body.vertices[v] - 0.005 * body.vertex_normals[v]
    assert deepest_inside(collider, point[None]) == pytest.approx(0.005, abs=0.001)
    assert deepest_inside(collider, (body.vertices[v] + 0.005 * body.vertex_normals[v])[None]) == 0.0

    rot = Rotation.from_rotvec(np.radians(60.0) * np.array([0.0, 0.0, 1.0])).as_matrix()
    collider.pose_arms({k: (elbow, rot)})
    turned = elbow + rot @ (point - elbow)
    assert np.linalg.norm(turned - point) > 0.05
    assert deepest_inside(collider, turned[None]) == pytest.approx(0.005, abs=0.001)
    assert deepest_inside(collider, point[None]) == 0.0
    assert deepest_inside(collider, np.stack([point, turned])) == pytest.approx(0.005, abs=0.001)
    # the motion stress says where: the forearm, for the deeper of a point 5 mm into it and one 2 mm into the
    # torso's side
    t = np.flatnonzero(body.vertex_part == body.parts.index("torso"))[0]
    shallow = body.vertices[t] - 0.002 * body.vertex_normals[t]
    assert deepest_point(collider, np.stack([shallow, turned])) == (1, "forearm_l")


def test_a_motion_too_deep_is_put_down_to_a_garment_too_tight_only_where_the_done_says_so():
    """The motion stress's 'too tight there': the done's too_tight places (limbs by name, the torso by band)
    name the part the deepest point was in."""
    assert too_tight_there("upper_arm_r", {"upper_arm_r": 3, "torso chest": 1})
    assert too_tight_there("torso", {"torso waist": 2})
    assert not too_tight_there("upper_arm_l", {"upper_arm_r": 3, "torso chest": 1})
    assert not too_tight_there("forearm_l", {})
    assert not too_tight_there(None, {"torso chest": 1})


def test_a_repose_reports_the_deepest_point_of_any_of_its_steps(tmp_path):
    """The T-shirt M at rest in the A-pose (a fresh drape: no motion, no figure), then re-posed to each named
    pose: the result's ``motion_max_penetration_mm`` is the deepest any coarse point was inside the body as the
    collider had it after each step (the limbs where the transition had them), and under the issue's 10 mm for
    arms raised and hands on hips."""
    model = catalogue_models(data_dir=tmp_path, names=["tshirt-m.obj"])[0]
    d = start(build_body(MEDIUM), model, SimSettings())
    first, _ = settle(d)
    assert "motion_max_penetration_mm" not in first.metrics
    parts = np.arange(len(d.control.body.parts), dtype=np.int64)
    for name in ("arms_raised", "hands_on_hips"):
        d = repose(d, build_body(MEDIUM, pose_from(name)))
        frames = []

        def watch(step, x, d=d):
            frames.append(float(d.control.collider.depth(x, parts, offset=False).max()))  # the body as it is this step
            return True

        result, _ = settle(d, watch)
        reported = result.metrics["motion_max_penetration_mm"]
        assert reported == pytest.approx(1000.0 * max(frames), abs=1e-9), name
        assert 0.0 <= reported < MOTION_PENETRATION_TARGET_MM, (name, reported)


@pytest.fixture(scope="module")
def small_stress(tmp_path_factory):
    """The motion stress in small: a seeded sequence of ten random poses (every angle over its whole range) on
    the T-shirt, the trousers and the skirt M, through repose and settle as a live session (the section's first
    sequence; ~40 s: a re-pose of a top is ~1 s)."""
    models = catalogue_models(data_dir=tmp_path_factory.mktemp("motion"),
                              names=["tshirt-m.obj", "trousers-m.obj", "skirt-m.obj"])
    return motion_stress(models, sequences=1, poses=10, seed=30, crossing=False)


@pytest.mark.slow
def test_random_pose_sequences_never_blow_up_nor_hang(small_stress):
    """Never a NaN, no spring over 3x its length in any frame, every settle at rest within its max steps, none
    raises."""
    a = small_stress["all"]
    bad = [r for r in small_stress["records"] if not r["finite"] or r["hang"] or r["max_stretch"] >= MAX_STRETCH]
    assert a["settles"] == 30 and a["errors"] == 0, bad
    assert a["never_nan"] and a["max_stretch"] < MAX_STRETCH and a["hangs"] == 0, bad


@pytest.mark.slow
def test_random_pose_sequences_keep_the_cloth_out_of_the_body_and_on_the_limbs(small_stress):
    """No frame with cloth 10 mm inside the body, and at every settle's end nothing inside the body and every
    sleeve and leg round its limb. (Before the re-posed drapes capped how fast crushed cloth unfolds,
    ``tuning.unfold_per_pass``, the trousers' hem was pulled 13 mm into a sole as the legs spread.)"""
    a = small_stress["all"]
    bad = [r for r in small_stress["records"] if not r["ok"]]
    assert a["motion_max_penetration_mm"] < MOTION_PENETRATION_TARGET_MM, bad
    assert a["ending_inside"] == 0 and a["off_limbs"] == 0, bad
    # a settle whose cloth went in says where (the body part of its deepest point)
    went_in = [r for r in small_stress["records"] if r["motion_mm"] > 0.0]
    assert went_in and all(r["motion_part"] in build_body(MEDIUM).parts for r in went_in)


@pytest.mark.slow
def test_a_sleeve_caught_in_a_big_move_is_carried_again_through_the_midway_pose(tmp_path):
    """The long-sleeve XXL carried from the A-pose to the first pose of the motion stress's sequence 15 (right arm
    swung 81 degrees forward, its elbow bent 112): the right sleeve ends caught beside the arm, and a fresh drape
    in that pose leaves it off too. Carried again from the A-pose through the midway pose it ends on the arm
    (``repose.through_midway``, tried by ``redrape_if_off`` after the fresh drape)."""
    from tryon.bench.motion import SEED, random_pose
    from tryon.sim.repose import redrape_if_off, through_midway

    rng = np.random.default_rng(SEED)
    pose = [[random_pose(rng) for _ in range(10)] for _ in range(15)][14][0]
    model = catalogue_models(data_dir=tmp_path, names=["longsleeve-xxl.obj"])[0]
    rest = start(build_body(MEDIUM), model, SimSettings())
    settle(rest)
    assert through_midway(rest) is None  # a drape from scratch: no re-pose to do again
    d = repose(rest, build_body(MEDIUM, pose))
    result, _ = settle(d)
    # the case this test needs (if the solver comes to carry this sleeve on, pick another caught one)
    assert [o["opening"] for o in result.metrics["limb_openings"] if not o["ok"]] == ["right arm"]
    again, fixed, redraped = redrape_if_off(d, result)
    assert redraped and again is not d
    assert fixed.metrics["openings_on_limbs"] is True and fixed.metrics["penetrating_vertices"] == 0
    assert fixed.metrics["rest_reached"]
    assert again.control.body is d.control.body and again.control.body.pose == d.control.body.pose


def test_a_garment_sized_to_the_body_stays_sized_in_every_pose():
    """A dress of guessed units is sized to the person where it is first draped (``start``); carried to another
    pose it is the same resized garment, and the answer for that pose says so too (it said false from the second
    pose of a motion on: a user's upload in ``poses`` read [true, false, false, false])."""
    from tryon.garment.generate import garment_mesh
    from tryon.garment.ingest import CleanMesh
    from tryon.garment.prepare import prepare

    g = garment_mesh("dress", "S")
    v = np.array(g.vertices, dtype=np.float64)
    centre = v.mean(axis=0)
    v[:, [0, 2]] = centre[[0, 2]] + 0.7 * (v[:, [0, 2]] - centre[[0, 2]])  # too small as made: sized up
    mesh = CleanMesh(vertices=v, faces=np.asarray(g.faces, dtype=np.int32), units="m", units_guessed=True)
    model = prepare(mesh, id="guessed", name="guessed", category="dress", size="S", source_sha256="0",
                    source_name="guessed.obj")
    d = start(build_body(MEDIUM), model, SimSettings(max_steps=3))
    assert d.model.sized
    moved = repose(d, build_body(MEDIUM, pose_from("hands_on_hips")))
    assert moved.model.sized and moved.model.garment is d.model.garment
    result, _ = settle(moved)
    assert result.metrics["sized_to_body"]


@pytest.mark.slow
def test_a_sleeve_too_tight_for_a_move_is_not_left_a_centimetre_in_the_forearm(tmp_path):
    """The motion stress's second sequence on the long-sleeve S, to its fifth pose (elbow bent 104 degrees, the
    wrist turned 83): its cuff, too tight for the forearm there, was 13.2 mm inside it in a frame of the move.
    A re-pose's every step takes a contact point that slid into the body out of it (``step._out_of_the_body``,
    the start-up's steps too: they show the body moving), so no frame goes past the issue's 10 mm."""
    from tryon.bench.motion import SEED, random_pose, run_sequence

    rng = np.random.default_rng(SEED)
    plans = [[random_pose(rng) for _ in range(10)] for _ in range(2)]
    model = catalogue_models(data_dir=tmp_path, names=["longsleeve-s.obj"])[0]
    records = run_sequence(model, MEDIUM, plans[1][:5])
    assert [r["error"] for r in records] == [None] * 5
    assert records[4]["motion_mm"] < MOTION_PENETRATION_TARGET_MM, records[4]["motion_part"]
    assert all(r["ok"] for r in records), [(r["pose_index"], r["motion_mm"]) for r in records if not r["ok"]]
