"""``POST /api/tryon`` with ``poses``: the garment draped through a motion, answered as an animated GLB (morph
targets, one per pose after the first) or as each pose's metrics."""

from __future__ import annotations

import io
import json
import struct
from pathlib import Path

import numpy as np
import pytest
import trimesh
from fastapi.testclient import TestClient

from tryon.api.app import create_app
from tryon.body.params import NAMED_POSES
from tryon.config import Settings
from tryon.garment.catalogue import Catalogue

ROOT = Path(__file__).resolve().parents[1]
MEDIUM = {"height": 170, "chest": 96, "waist": 82, "hips": 100}
MOTION = ["a_pose", "arms_raised", {"arm_angle_left": 20, "arm_angle_right": 60, "elbow_bend_left": 40}]


@pytest.fixture(scope="module")
def client_and_id(tmp_path_factory):
    data = tmp_path_factory.mktemp("motion")
    meta = Catalogue(data).ingest(ROOT / "garments" / "tshirt-m.obj", name="T-shirt M", category="top", units="m")
    with TestClient(create_app(Settings(data_dir=data))) as client:
        yield client, meta.id


def glb_parts(data: bytes) -> tuple[dict, bytes]:
    """(the glTF JSON, the binary chunk) of a GLB."""
    magic, version, length = struct.unpack_from("<III", data)
    assert magic == 0x46546C67 and version == 2 and length == len(data)
    json_len, _ = struct.unpack_from("<II", data, 12)
    document = json.loads(data[20:20 + json_len])
    bin_len, _ = struct.unpack_from("<II", data, 20 + json_len)
    return document, data[28 + json_len:28 + json_len + bin_len]


def accessor(document: dict, blob: bytes, index: int) -> np.ndarray:
    a = document["accessors"][index]
    view = document["bufferViews"][a["bufferView"]]
    dtype = {5126: "<f4", 5125: "<u4", 5121: "u1"}[a["componentType"]]
    width = {"SCALAR": 1, "VEC3": 3, "VEC4": 4}[a["type"]]
    return np.frombuffer(blob, dtype=dtype, count=a["count"] * width, offset=view["byteOffset"]).reshape(a["count"], -1)


def test_a_motion_as_an_animated_glb(client_and_id):
    client, gid = client_and_id
    r = client.post("/api/tryon?format=glb", json={"garment_id": gid, "measurements": MEDIUM, "poses": MOTION})
    assert r.status_code == 200, r.text
    assert r.headers["content-type"] == "model/gltf-binary"
    # trimesh loads it: the garment and the body, each in the first pose
    scene = trimesh.load(io.BytesIO(r.content), file_type="glb", process=False)
    assert sorted(scene.geometry) == ["body", "garment"]
    document, blob = glb_parts(r.content)
    meshes = {m["name"]: m for m in document["meshes"]}
    for name in ("garment", "body"):
        primitive = meshes[name]["primitives"][0]
        assert len(primitive["targets"]) == len(MOTION) - 1
        base = accessor(document, blob, primitive["attributes"]["POSITION"])
        assert np.allclose(base, scene.geometry[name].vertices, atol=1e-6)
    # the body's second target raises the hands (arms_raised: forearms up beside the head)
    body = meshes["body"]["primitives"][0]
    base = accessor(document, blob, body["attributes"]["POSITION"])
    raised = base + accessor(document, blob, body["targets"][0]["POSITION"])
    assert raised[:, 1].max() > base[:, 1].max() - 0.05 and raised[np.abs(raised[:, 0]) > 0.4, 1].max() > 1.5
    # one animation, one second per pose, stepping the weights from pose to pose
    animation = document["animations"][0]
    assert len(animation["channels"]) == 2 and {c["target"]["path"] for c in animation["channels"]} == {"weights"}
    sampler = animation["samplers"][0]
    assert accessor(document, blob, sampler["input"]).ravel().tolist() == [0.0, 1.0, 2.0]
    weights = accessor(document, blob, sampler["output"]).reshape(len(MOTION), len(MOTION) - 1)
    assert weights.tolist() == [[0, 0], [1, 0], [0, 1]]
    metrics = json.loads(r.headers["X-Tryon-Metrics"])
    assert metrics["pose"] == {**NAMED_POSES["a_pose"]}


def test_a_motion_as_json_gives_each_poses_fit(client_and_id):
    client, gid = client_and_id
    r = client.post("/api/tryon", json={"garment_id": gid, "measurements": MEDIUM, "poses": MOTION})
    assert r.status_code == 200, r.text
    poses = r.json()["poses"]
    assert [p["pose"]["elbow_bend_left"] for p in poses] == [0.0, 90.0, 40.0]
    for p in poses:
        assert p["metrics"]["penetrating_vertices"] == 0 and p["metrics"]["openings_on_limbs"] is True
    # how deep the cloth went into the moving body on the way to each pose after the first (the first did not
    # move); at rest each time nothing is inside
    motion = [p["metrics"]["motion_max_penetration_mm"] for p in poses]
    assert motion[0] is None and all(isinstance(m, float) and m >= 0.0 for m in motion[1:]), motion


@pytest.mark.parametrize("extra, words", [
    ({"poses": MOTION, "pose": "a_pose"}, "give either pose (one pose) or poses (a motion), not both"),
    ({"poses": ["a_pose"] * 11}, "at most 10"),
    ({"poses": ["a_pose", "moonwalk"]}, "the named poses are"),
])
def test_a_motion_is_refused_in_words(client_and_id, extra, words):
    client, gid = client_and_id
    r = client.post("/api/tryon", json={"garment_id": gid, "measurements": MEDIUM, **extra})
    assert r.status_code == 422 and words in r.text, r.text
