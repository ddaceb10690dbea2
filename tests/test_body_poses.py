"""Poses: each side on its own, the symmetric shorthand, named poses, and a body that stays a body (no arm
through the torso) in any pose of the ranges; the API's pose answers and refusals."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from test_body import SPREAD, part_faces, winding_number
from tryon.body.build import ARM_PRESS, SHOULDER_REACH, build_body, with_hands_straight
from tryon.body.types import PART_NAMES
from tryon.body.params import NAMED_POSES, POSE_RANGES, POSE_SHORTHAND, Measurements, Pose, pose_from

MEDIUM = Measurements(height=170, chest=96, waist=82, hips=100)  # the drape tests' medium body
# How far (m) an arm point may be inside the torso: the arm rests against it pressing at most ARM_PRESS (soft
# tissue gives way; measured by the body on the torso's convex sections), plus 2 mm for the section's
# convex hull against the surface at this resolution.
INSIDE_TOLERANCE = ARM_PRESS + 0.002


def arm_depth_mm(body, side: str) -> float:
    """Deepest (mm) of the arm's (upper arm and forearm with the hand) vertices inside the torso (winding
    number), as the distance to the torso's surface; the top of the upper arm, within SHOULDER_REACH of its
    length from the shoulder joint and above the chest, is where arm and torso meet and is left out."""
    faces = part_faces(body, "torso")
    pts = body.vertices[np.unique(np.concatenate([part_faces(body, f"upper_arm_{side}"),
                                                  part_faces(body, f"forearm_{side}")]))]
    joint, elbow = body.joints[f"shoulder_{side}"], body.joints[f"elbow_{side}"]
    off = (np.linalg.norm(pts - joint, axis=1) > SHOULDER_REACH * np.linalg.norm(elbow - joint)) \
        | (pts[:, 1] < body.levels["chest"])
    pts = pts[off]
    inside = pts[winding_number(body.vertices, faces, pts) > 0.5]
    if not len(inside):
        return 0.0
    torso = trimesh.Trimesh(body.vertices, faces, process=False)
    return 1000.0 * float(trimesh.proximity.closest_point_naive(torso, inside)[1].max())


def test_each_side_has_its_own_angles():
    pose = Pose(arm_angle_left=20.0, arm_angle_right=70.0, elbow_bend_right=90.0, leg_spread_left=15.0,
                leg_spread_right=2.0, arm_forward_left=40.0)
    body = build_body(MEDIUM, pose, resolution=16)
    assert body.pose == pose.as_dict()
    j = body.joints
    # the right upper arm is raised 70 degrees from hanging, the left 20 (and swung forwards)
    up_r = j["elbow_r"] - j["shoulder_r"]
    up_l = j["elbow_l"] - j["shoulder_l"]
    assert np.degrees(np.arctan2(-up_r[0], -up_r[1])) == pytest.approx(70.0, abs=0.1)
    assert np.degrees(np.arcsin(up_l[0] / np.linalg.norm(up_l))) == pytest.approx(20.0, abs=0.1)
    assert up_l[2] / np.linalg.norm(up_l) == pytest.approx(np.cos(np.radians(20)) * np.sin(np.radians(40)), abs=1e-6)
    fore_r = j["wrist_r"] - j["elbow_r"]
    assert np.degrees(np.arccos(fore_r @ up_r / np.linalg.norm(fore_r) / np.linalg.norm(up_r))) == pytest.approx(90.0, abs=0.1)
    # each leg spread its own angle, both standing on the floor
    for side, angle in (("l", 15.0), ("r", 2.0)):
        leg = j[f"knee_{side}"] - j[f"hip_{side}"]
        assert np.degrees(np.arctan2(abs(leg[0]), -leg[1])) == pytest.approx(angle, abs=0.1)
        sole = body.vertices[np.unique(part_faces(body, f"shin_{side}"))][:, 1].min()
        assert abs(sole) < 1e-3
    # the mesh measures what was asked in any pose
    for name in ("height", "chest", "waist", "hips"):
        assert body.achieved[name] == pytest.approx(getattr(MEDIUM, name), abs=0.5)


def test_the_shorthand_sets_both_sides_and_symmetric_poses_stay_mirror_images():
    assert Pose(arm_angle=50.0, elbow_bend=20.0).as_dict() == Pose(
        arm_angle_left=50.0, arm_angle_right=50.0, elbow_bend_left=20.0, elbow_bend_right=20.0).as_dict()
    body = build_body(MEDIUM, pose_from("hands_on_hips"), resolution=12)
    for left in ("upper_arm_l", "forearm_l", "thigh_l", "shin_l"):
        vl = body.vertices[np.unique(part_faces(body, left))]
        vr = body.vertices[np.unique(part_faces(body, left[:-1] + "r"))]
        assert np.allclose(vl * [-1.0, 1.0, 1.0], vr, atol=1e-12)
    with pytest.raises(ValueError, match="unknown pose 'star': the named poses are a_pose, arms_down"):
        pose_from("star")


@pytest.mark.parametrize("m", [MEDIUM, Measurements(height=158, chest=84, waist=68, hips=92),
                               Measurements(height=185, chest=112, waist=100, hips=110)])
def test_hands_on_hips_puts_the_wrists_on_the_hips(m):
    """The wrist joints are on the hips, not near them: within ~3 cm of the torso's surface (3.5 cm: the hand
    rests on the clothes, ``HAND_GAP`` 9 mm off the skin, and the wrist's own flesh is 1.7-2.7 cm thick either
    side of the joint; measured 2.5-3.5 cm on these bodies), between the hip and a little over the waist
    level; the hand does not enter the torso."""
    body = build_body(m, pose_from("hands_on_hips"), resolution=20)
    torso = trimesh.Trimesh(body.vertices, part_faces(body, "torso"), process=False)
    for side in ("l", "r"):
        wrist = body.joints[f"wrist_{side}"]
        distance = float(trimesh.proximity.closest_point_naive(torso, wrist[None])[1][0])
        assert distance < 0.035, (side, distance)
        assert body.levels["hips"] < wrist[1] < body.levels["waist"] + 0.03
    assert arm_depth_mm(body, "l") <= 1000.0 * INSIDE_TOLERANCE


def test_no_arm_passes_into_the_torso_in_any_pose_of_the_ranges():
    """Seeded poses across every range (each side its own) on bodies across the measurement ranges: no arm
    or forearm vertex is inside the torso by more than the arm may rest against it (an arm swung forwards
    at 0 degrees is raised until it clears the chest, a hand turned into the hip until it rests on it)."""
    rng = np.random.default_rng(30)
    worst = 0.0
    for i in range(24):
        pose = Pose(**{name: float(rng.uniform(lo, hi)) for name, (lo, hi) in POSE_RANGES.items()})
        body = build_body(SPREAD[i % len(SPREAD)], pose, resolution=14)
        for side in ("l", "r"):
            depth = arm_depth_mm(body, side)
            worst = max(worst, depth)
            assert depth <= 1000.0 * INSIDE_TOLERANCE, (i, side, pose, body.pose)
    # and the named poses on the medium body
    for name in NAMED_POSES:
        body = build_body(MEDIUM, pose_from(name), resolution=14)
        assert max(arm_depth_mm(body, "l"), arm_depth_mm(body, "r")) <= 1000.0 * INSIDE_TOLERANCE, name


@pytest.mark.parametrize("m", [MEDIUM, Measurements(height=170, chest=112, waist=128, hips=118)])
def test_an_arm_swung_forwards_stays_out_of_the_chest(m):
    """Hanging arms swung forwards (0 to 90 degrees), straight or bent across the body, do not enter the
    chest or the belly: where one would, the body raises it sideways to where it rests against the torso."""
    for forward in (0.0, 30.0, 60.0, 90.0):
        for bend in ({}, {"elbow_bend": 120.0, "arm_rotation": 90.0}):
            body = build_body(m, Pose(arm_angle=0.0, arm_forward=forward, **bend), resolution=14)
            assert body.pose["arm_forward_left"] == forward
            assert arm_depth_mm(body, "l") <= 1000.0 * INSIDE_TOLERANCE, (forward, bend, body.pose)


def test_a_forearm_swung_across_the_belly_does_not_go_through_it():
    """The motion stress's fourth pose (seed 30: the right arm 13.6 degrees out, 15.8 forwards, turned in 72.6
    with the elbow bent 81.1) swung the right forearm 9.3 mm through the torso, within the upper arm's
    ARM_PRESS: no cloth can lie between the two. The forearm may press only FOREARM_PRESS, so that arm is
    raised until it clears: no part of the body inside a part it does not join; the other arm as asked."""
    from tryon.bench.motion import body_crossing_mm, random_pose

    rng = np.random.default_rng(30)
    pose = [random_pose(rng) for _ in range(4)][3]
    assert pose.arm_angle_right == 13.6 and pose.elbow_bend_right == 81.1
    body = build_body(MEDIUM, pose)
    assert body_crossing_mm(body) == 0.0
    assert body.pose["arm_angle_right"] > pose.arm_angle_right + 1.0
    assert body.pose["arm_forward_right"] == pose.arm_forward_right
    assert body.pose["elbow_bend_right"] == pose.elbow_bend_right


# ---- API ---------------------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def client(tmp_path_factory):
    from fastapi.testclient import TestClient

    from tryon.api.app import create_app
    from tryon.config import Settings

    return TestClient(create_app(Settings(data_dir=tmp_path_factory.mktemp("pose-api"))))


AVERAGE = {"height": 175, "chest": 100, "waist": 88, "hips": 100}


def test_api_named_pose_and_side_fields(client):
    r = client.post("/api/bodies", json={"measurements": AVERAGE, "pose": "hands_on_hips", "resolution": 10})
    assert r.status_code == 200, r.text
    assert r.json()["pose"]["requested"] == NAMED_POSES["hands_on_hips"]
    r = client.post("/api/bodies", json={"measurements": AVERAGE, "resolution": 10,
                                         "pose": {"arm_angle_left": 60, "arm_angle_right": 40, "elbow_bend": 30}})
    assert r.status_code == 200, r.text
    achieved = r.json()["pose"]["achieved"]
    assert (achieved["arm_angle_left"], achieved["arm_angle_right"]) == (60, 40)
    assert achieved["elbow_bend_left"] == achieved["elbow_bend_right"] == 30


@pytest.mark.parametrize("pose, words", [
    ("moonwalk", "unknown pose 'moonwalk': the named poses are a_pose, arms_down, hands_on_hips, arms_raised, stride"),
    ({"arm_angle": 40, "arm_angle_left": 30}, "pose.arm_angle (both sides) and pose.arm_angle_left given together"),
    ({"leg_spread": 5, "leg_spread_right": 3}, "pose.leg_spread (both sides) and pose.leg_spread_right"),
])
def test_api_refuses_unknown_names_and_shorthand_with_a_side(client, pose, words):
    r = client.post("/api/bodies", json={"measurements": AVERAGE, "pose": pose})
    assert r.status_code == 422, r.text
    assert words in r.json()["detail"][0]["msg"]


def test_api_refuses_a_side_out_of_range_naming_it(client):
    r = client.post("/api/bodies", json={"measurements": AVERAGE, "pose": {"elbow_bend_right": 150}})
    assert r.status_code == 422
    detail = r.json()["detail"][0]
    assert detail["loc"][-1] == "elbow_bend_right" and "[0, 120] degrees" in detail["msg"]


def test_api_named_poses_everywhere_a_pose_is_taken(client):
    """The try-on and the size advice take a named pose too (refused the same way: before any work)."""
    for path, extra in (("/api/tryon", {"garment_id": "none"}), ("/api/fit", {"style": "none"})):
        r = client.post(path, json={**extra, "measurements": AVERAGE, "pose": "moonwalk"})
        assert r.status_code == 422 and "the named poses are" in r.text, (path, r.text)


def test_api_ranges_list_sides_shorthand_and_named_poses(client):
    data = client.get("/api/bodies/ranges").json()
    for name, (lo, hi) in POSE_RANGES.items():
        assert (data["pose"][name]["min"], data["pose"][name]["max"]) == (lo, hi)
        assert data["pose"][name]["unit"] == "degrees" and data["pose"][name]["default"] == getattr(Pose(), name)
    for name in POSE_SHORTHAND:
        assert data["pose"][name]["default"] is None and "both sides" in data["pose"][name]["description"]
    assert list(data["named_poses"]) == list(NAMED_POSES)
    assert data["named_poses"]["hands_on_hips"]["angles"] == NAMED_POSES["hands_on_hips"]
    assert data["named_poses"]["a_pose"]["angles"] == Pose().as_dict()


def test_the_hands_straightened_are_the_same_body_built_with_the_wrists_straight():
    """``with_hands_straight``: the body built again with both wrists at 0 (the same measurements, arms and
    resolution), so a drape can start with the hands inside the sleeves; a body whose hands are not turned is
    its own. A turned hand's forearm map is made along the forearm, elbow to wrist joint, not towards the
    fingertips (``map_axes``)."""
    turned = build_body(MEDIUM, Pose(arm_angle=50.0, elbow_bend=30.0, wrist_bend_left=70.0), resolution=20)
    straight = with_hands_straight(turned)
    again = build_body(MEDIUM, Pose(arm_angle=50.0, elbow_bend=30.0), resolution=20)
    assert turned.hands_turned and not straight.hands_turned and straight.resolution == 20
    assert np.array_equal(straight.vertices, again.vertices) and straight.pose == again.pose
    assert with_hands_straight(again) is again
    k = PART_NAMES.index("forearm_l")
    axis = turned.maps.part_axes[k]
    wrist = turned.joints["wrist_l"]
    along = (axis[1] - axis[0]) / np.linalg.norm(axis[1] - axis[0])
    assert np.linalg.norm(np.cross(along, wrist - axis[0])) < 1e-9  # through the wrist joint
    assert np.allclose(np.linalg.norm(axis[1] - axis[0]), np.linalg.norm(turned.part_axes[k, 1] - axis[0]))
    kr = PART_NAMES.index("forearm_r")  # the right hand is not turned: its own axis
    assert np.array_equal(turned.maps.part_axes[kr], turned.part_axes[kr])


def test_bodies_of_the_same_measurements_share_the_torso_hulls_and_are_the_same_bodies(monkeypatch):
    """A re-pose builds the same person in another pose: the torso's section hulls (the arm-press test's, the
    torso and its copy grown for the hands) are made once and kept, and a body built with them is the one
    built with hulls made afresh, to the bit."""
    import tryon.body.build as build
    import tryon.body.sections as sections

    m = MEDIUM
    sections._kept.clear()
    first = build_body(m, pose_from("hands_on_hips"))
    kept = list(sections._kept.values())
    assert len(kept) == 2  # the torso and the grown torso
    again = build_body(m, Pose(arm_angle=0))
    assert list(sections._kept.values()) == kept  # no new hulls: the same torso
    assert sum(len(h.hulls) for h in kept) > 0
    # another person's torso gets hulls of its own
    build_body(Measurements(height=160.0, chest=88.0, waist=70.0, hips=94.0), Pose(arm_angle=0))
    assert len(sections._kept) == 4
    monkeypatch.setattr(build, "section_hulls", lambda v, e, s: sections.SectionHulls(v, e, s))
    for pose, body in ((pose_from("hands_on_hips"), first), (Pose(arm_angle=0), again)):
        fresh = build_body(m, pose)
        assert np.array_equal(fresh.vertices, body.vertices) and fresh.pose == body.pose
