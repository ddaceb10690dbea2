"""Drapes in the named poses and in poses whose sides differ (``tryon.sim.run.drape`` on the real body):
the alignment, the arm plan and the sleeves read each side's own arm, the legs each leg's own spread."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from tryon.body.build import build_body, with_hands_straight
from tryon.body.params import Measurements, Pose, pose_from
from tryon.garment.catalogue import Catalogue
from tryon.sim.run import drape
from tryon.sim.settings import SimSettings

ROOT = Path(__file__).resolve().parents[1]
MEDIUM = Measurements(height=170, chest=96, waist=82, hips=100)  # the default medium body of the drape tests
# Left arm low and bent, right arm high and swung forwards, one leg spread wide and the other nearly closed.
ASYMMETRIC = Pose(arm_angle_left=20.0, arm_angle_right=60.0, elbow_bend_left=40.0, arm_forward_right=30.0,
                  leg_spread_left=12.0, leg_spread_right=2.0)


@pytest.fixture(scope="module")
def catalogue(tmp_path_factory):
    return Catalogue(tmp_path_factory.mktemp("pose-drapes"))


def _model(catalogue, filename, category):
    meta = catalogue.ingest(ROOT / "garments" / filename, name=filename, category=category, units="m")
    return catalogue.model(meta.id)


@pytest.mark.parametrize("pose", ["hands_on_hips", "asymmetric", "stride"])
def test_tshirt_drapes_with_sleeves_round_each_arm_in_its_own_pose(catalogue, pose):
    """The T-shirt M on the medium body: at rest, nothing inside the body, each sleeve round its own upper
    arm (the sides found and aimed each on its own: the right arm 40 degrees higher than the left)."""
    body = build_body(MEDIUM, ASYMMETRIC if pose == "asymmetric" else pose_from(pose))
    m = drape(body, _model(catalogue, "tshirt-m.obj", "top"), SimSettings()).metrics
    assert m["rest_reached"] and m["penetrating_vertices"] == 0, m
    assert m["openings_on_limbs"] is True, m["limb_openings"]
    assert sorted(o["around"] for o in m["limb_openings"]) == ["upper_arm_l", "upper_arm_r"]
    assert m["pose"] == body.pose
    if pose != "hands_on_hips":  # where a hand rests on the shirt the cloth is caught under it (see the docs)
        assert sum(k["over"] for k in m["strain_by_kind"].values()) == 0, m["strain_by_kind"]


def test_trousers_follow_each_leg_in_its_own_spread(catalogue):
    """The trousers M with one leg spread 12 degrees and the other 2: each leg ends round its own shin."""
    m = drape(build_body(MEDIUM, ASYMMETRIC), _model(catalogue, "trousers-m.obj", "bottom"), SimSettings()).metrics
    assert m["rest_reached"] and m["penetrating_vertices"] == 0 and m["stays_up"]
    assert sorted(o["around"] for o in m["limb_openings"]) == ["shin_l", "shin_r"]
    assert sum(k["over"] for k in m["strain_by_kind"].values()) == 0


def test_a_drape_reposed_three_times_carries_the_garment_with_the_body(catalogue):
    """The T-shirt M at rest on the medium body in the A-pose, then re-posed (``sim.repose``) three times,
    each time from where the last left it: the garment moves with the limbs and comes to rest in each new
    pose with nothing inside the body, each sleeve still round its own arm, no spring over its limit."""
    from tryon.sim.repose import repose
    from tryon.sim.run import settle as run_settle
    from tryon.sim.start import start

    def settle(d):
        return run_settle(d)[0]

    model = _model(catalogue, "tshirt-m.obj", "top")
    d = start(build_body(MEDIUM), model, SimSettings())
    settle(d)
    for pose in (pose_from("arms_raised"), ASYMMETRIC, pose_from("arms_down")):
        body = build_body(MEDIUM, pose)
        d = repose(d, body)
        assert d.control.arms.steps > 10  # the body moved over steps, not at once
        m = settle(d).metrics
        assert m["rest_reached"] and m["penetrating_vertices"] == 0, (pose, m)
        assert sorted(o["around"] for o in m["limb_openings"]) == ["upper_arm_l", "upper_arm_r"], pose
        assert sum(k["over"] for k in m["strain_by_kind"].values()) == 0, (pose, m["strain_by_kind"])
        assert m["pose"] == body.pose


def test_limbs_far_from_the_garment_take_their_new_pose_at_once(catalogue):
    """The trousers M at rest in the A-pose, the arms then raised: the arms never come within reach of the
    trousers on their way, so the body takes the new pose at once (no steps of motion, gravity kept) and the
    trousers stay at rest where they are; the T-shirt in the same change moves with its arms over steps."""
    from tryon.sim.repose import repose
    from tryon.sim.run import settle
    from tryon.sim.start import start

    raised = build_body(MEDIUM, pose_from("arms_raised"))
    trousers = start(build_body(MEDIUM), _model(catalogue, "trousers-m.obj", "bottom"), SimSettings())
    before = settle(trousers)[0]
    moved = repose(trousers, raised)
    assert moved.control.arms.steps == 0 and moved.control.arms.turned_parts() == []
    m = settle(moved)[0].metrics
    assert m["rest_reached"] and m["penetrating_vertices"] == 0 and m["stays_up"], m
    assert sorted(o["around"] for o in m["limb_openings"]) == ["shin_l", "shin_r"]
    # stepped on at rest from where they were (slid_cm: from there): no fall, no transition to settle from
    assert m["slid_cm"] < 2.0 and m["steps"] < before.metrics["steps"], (m["slid_cm"], m["steps"])
    shirt = start(build_body(MEDIUM), _model(catalogue, "tshirt-m.obj", "top"), SimSettings())
    settle(shirt)
    assert repose(shirt, raised).control.arms.steps > 10


def test_a_reposed_body_starts_where_the_garment_was_draped():
    """From the A-pose to hands_on_hips the forearm is not rigid (the hand turns 90 degrees at the wrist, and
    it is part of the forearm): moved back rigidly, the hand stood up to 13.5 cm off the old body's, through
    the long sleeve's cuff. The transition's body starts as the old body and ends as the new one, exactly."""
    from tryon.sim.collision.collider import BodyCollider
    from tryon.sim.collision.kernels import cell_max_radius
    from tryon.sim.repose import PoseTransition

    old, new = build_body(MEDIUM), build_body(MEDIUM, pose_from("hands_on_hips"))
    collider = BodyCollider(new, SimSettings().collision_margin)
    motion = PoseTransition(old, new, collider)
    motion.apply(0)
    assert np.abs(collider.vertices - old.vertices).max() < 1e-9
    motion.apply(motion.steps // 2)
    halfway = np.linalg.norm(collider.vertices - new.vertices, axis=1).max()
    assert 0.01 < halfway < np.linalg.norm(old.vertices - new.vertices, axis=1).max()
    radii = np.empty_like(collider.rest_rmax)  # only the reshaped parts' cells were measured again
    frames = collider.rest_frames
    cell_max_radius(frames["cyl_origin"], frames["cyl_axes"], collider.cyl_shape, collider.cell_base,
                    collider.cell_start, collider.cell_faces, collider.faces, collider.rest_vertices, radii)
    assert np.array_equal(radii, collider.rest_rmax)
    motion.apply(motion.steps)
    assert np.array_equal(collider.vertices, new.vertices)
    assert np.array_equal(collider.cell_faces, new.maps.cell_faces)


def test_long_sleeves_stay_round_the_forearms_into_hands_on_hips(catalogue):
    """The long-sleeve M at rest in the A-pose, re-posed to hands_on_hips (elbows bent 100 degrees, the
    forearms across onto the hips, the hands turned at the wrist): the hand turns with the motion, so each
    cuff ends round its own forearm, and nothing is inside the body. With the hand turned at once the cuffs
    ended beside the hands, 13-18 cm from the forearms' axes."""
    from tryon.sim.repose import repose
    from tryon.sim.run import settle
    from tryon.sim.start import start

    d = start(build_body(MEDIUM), _model(catalogue, "longsleeve-m.obj", "top"), SimSettings())
    settle(d)
    m = settle(repose(d, build_body(MEDIUM, pose_from("hands_on_hips"))))[0].metrics
    assert m["rest_reached"] and m["penetrating_vertices"] == 0, m
    assert {o["opening"]: o["around"] for o in m["limb_openings"]} == {"left arm": "forearm_l",
                                                                      "right arm": "forearm_r"}


@pytest.mark.parametrize("pose", ["hands_on_hips", "wrists_turned"])
def test_long_sleeves_draped_with_the_hands_turned_end_round_the_forearms(catalogue, pose):
    """A long-sleeve try-on in a pose whose hands are turned at the wrist (hands_on_hips: -90 degrees; both
    wrists at 60 towards the palms) is draped on the body with its hands straight and then re-posed to the
    turned hands (``repose.fresh_drape``): each cuff ends round its own forearm, nothing inside the body, the
    steps of both settles counted. Draped with the hands turned from the start, a hand stood out through the
    side of its sleeve and both cuffs ended crumpled beside the forearms."""
    body = build_body(MEDIUM, pose_from("hands_on_hips") if pose == "hands_on_hips" else Pose(wrist_bend=60.0))
    model = _model(catalogue, "longsleeve-m.obj", "top")
    m = drape(body, model, SimSettings()).metrics
    assert m["rest_reached"] and m["penetrating_vertices"] == 0, m
    assert {o["opening"]: o["around"] for o in m["limb_openings"]} == {"left arm": "forearm_l",
                                                                      "right arm": "forearm_r"}, m["limb_openings"]
    assert m["pose"] == body.pose
    straight = drape(with_hands_straight(body), model, SimSettings()).metrics
    assert m["steps"] > straight["steps"]  # the straight-handed drape's steps, then the hands' turn


@pytest.mark.parametrize("wrist", [80.0, -90.0])
def test_a_forearm_moves_rigidly_with_the_forearm_not_with_its_turning_hand(wrist):
    """Between two poses that differ only in the hand's turn at the wrist, the forearm hardly moves rigidly
    (``part_motions`` fits it on the forearm's own vertices, ``FOREARM_OWN``; under a degree, its wrist joint
    under 5 mm: the spline of the forearm's sections bends a little towards the turned wrist): the hand's turn
    is in the shape change. Fitted on the hand too, the forearm turned 23-25 degrees and its wrist 7 cm, and
    half-way through a re-pose it stood off its cylinder map's axis (cloth 2 cm outside judged 2 cm inside)."""
    from tryon.sim.repose import part_motions

    old, new = build_body(MEDIUM, Pose(elbow_bend=60.0)), build_body(MEDIUM, Pose(elbow_bend=60.0, wrist_bend=wrist))
    moves = part_motions(new, old)
    for side in ("l", "r"):
        k = new.parts.index(f"forearm_{side}")
        turn = np.degrees(np.arccos(np.clip((np.trace(moves[k, :3, :3]) - 1.0) / 2.0, -1.0, 1.0)))
        w = new.joints[f"wrist_{side}"]
        assert turn < 1.0 and np.linalg.norm(moves[k, :3, :3] @ w + moves[k, :3, 3] - w) < 0.005, (side, turn)


def test_cloth_beyond_a_turning_hands_fingertips_is_not_judged_inside():
    """A re-pose from hands turned 90 degrees one way (elbows bent) to 90 the other (arms raised): at every
    third step, points scattered 2 cm about the forearms' surfaces are inside the collider's forearm exactly
    where the winding number says so, but for a few deep ones (none judged inside outside). Where the radial
    ray from the axis misses the part (the axis runs past a turned hand's fingertips), the nearest face's side
    called 19 of 34,800 such points inside, 5-14 mm outside the fingertips (a 13.8 mm frame of the motion
    stress); a ray along the axis decides it now (``kernels._axial_inside``)."""
    from test_body import winding_number
    from tryon.sim.collision.collider import BodyCollider
    from tryon.sim.repose import PoseTransition

    old = build_body(MEDIUM, Pose(wrist_bend=-90.0, elbow_bend=100.0))
    new = build_body(MEDIUM, Pose(wrist_bend=90.0, arm_angle=70.0))
    collider = BodyCollider(new, SimSettings().collision_margin)
    motion = PoseTransition(old, new, collider)
    rng = np.random.default_rng(0)
    false_inside = missed = total = 0
    for step in range(0, motion.steps + 1, 3):
        motion.apply(step)
        for k in (new.parts.index("forearm_l"), new.parts.index("forearm_r")):
            faces = new.faces[new.face_part == k]
            pts = collider.vertices[rng.choice(np.unique(faces), 200)] + rng.normal(scale=0.02, size=(200, 3))
            inside = winding_number(collider.vertices, faces, pts) > 0.5
            judged = collider.depth(pts, np.array([k])) > 0.0
            false_inside += int((judged & ~inside).sum())
            missed += int((inside & ~judged).sum())
            total += len(pts)
    assert false_inside == 0 and missed <= 0.001 * total, (false_inside, missed, total)
