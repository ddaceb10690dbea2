"""Outfits (issue 29): layer order and tuck, layers that start crossed end apart, the API's outfit answers (JSON,
GLB with a node per garment, the stream) and its refusals (422 naming the field)."""

from __future__ import annotations

import io
import json
from pathlib import Path

import numpy as np
import pytest
import trimesh
from fastapi.testclient import TestClient

from tryon.api.app import create_app
from tryon.api.frames import FRAME_HEADER
from tryon.body.build import build_body
from tryon.body.params import Measurements, Pose
from tryon.config import Settings
from tryon.garment.catalogue import Catalogue
from tryon.sim.outfit import drape_outfit
from tryon.sim.tuck import layer_order

from test_cloth_collision import tube

ROOT = Path(__file__).resolve().parents[1]
BODY = {"height": 170, "chest": 96, "waist": 82, "hips": 100}
GARMENTS = {"tshirt": ("tshirt-m.obj", "T-shirt M", "top"), "longsleeve": ("longsleeve-s.obj", "Long-sleeve S", "top"),
            "trousers": ("trousers-m.obj", "Trousers M", "bottom"), "skirt": ("skirt-m.obj", "Skirt M", "bottom")}


@pytest.fixture(scope="module")
def catalogue_ids(tmp_path_factory):
    data = tmp_path_factory.mktemp("outfits")
    catalogue = Catalogue(data)
    ids = {key: catalogue.ingest(ROOT / "garments" / f, name=n, category=c, units="m").id
           for key, (f, n, c) in GARMENTS.items()}
    return data, catalogue, ids


@pytest.fixture(scope="module")
def client(catalogue_ids):
    data, _, _ = catalogue_ids
    with TestClient(create_app(Settings(data_dir=data))) as c:
        yield c


@pytest.fixture(scope="module")
def body():
    return build_body(Measurements(**BODY), Pose())


def test_layer_order_puts_the_bottom_under_the_tops_or_over_the_first():
    assert layer_order(["top", "bottom"], "out") == [1, 0]
    assert layer_order(["top", "bottom"], "in") == [0, 1]
    assert layer_order(["top", "top", "bottom"], "in") == [0, 2, 1]  # the second top stays over both
    assert layer_order(["top", "top", "bottom"], "out") == [2, 0, 1]
    assert layer_order(["bottom"], "in") == [0]
    with pytest.raises(ValueError, match="at most one bottom"):
        layer_order(["bottom", "bottom"])
    with pytest.raises(ValueError, match="tuck"):
        layer_order(["top"], "sideways")


def test_an_outer_layer_that_starts_inside_the_inner_one_ends_outside_it(catalogue_ids, body):
    """A T-shirt over a skirt: aligned each on its own, the T-shirt's lower half starts inside the skirt's
    flare (hundreds of vertices on the wrong side); layered, it ends outside it, and neither is in the body."""
    from tryon.sim.align import align_sized
    from tryon.sim.collision.cloth import face_sides
    from tryon.sim.layers import layer_metrics, outward_from_body

    _, catalogue, ids = catalogue_ids
    inner, outer = catalogue.model(ids["skirt"]), catalogue.model(ids["tshirt"])
    start = [align_sized(body, m)[0] for m in (inner, outer)]
    faces = [np.asarray(m.coarse_faces, dtype=np.int64) for m in (inner, outer)]
    sides = [face_sides(x, f, outward_from_body(x, body)) for x, f in zip(start, faces)]
    crossed, deepest = layer_metrics(start, faces, sides)
    assert crossed > 100 and deepest > 0.01
    out = drape_outfit(body, [outer, inner])  # given top first; tuck out puts the skirt under it
    m = out.metrics
    assert m["layers"] == [ids["skirt"], ids["tshirt"]]
    assert m["layer_penetrating_vertices"] == 0 and m["max_layer_penetration_mm"] <= 2.0
    assert all(r.metrics["penetrating_vertices"] == 0 for r in out.results)
    assert m["rest_reached"]


@pytest.mark.parametrize("top_radius, out_ok, in_ok", [(0.16, True, False), (0.14, False, True)])
def test_tuck_is_judged_on_the_bands_surface(body, top_radius, out_ok, in_ok):
    """A tube 1 cm outside a band-like tube is over it (out), 1 cm inside is under it (in); a top that ends above
    the band has no say. The sides come from the body's axes, as in a drape."""
    from tryon.sim.collision.cloth import face_sides
    from tryon.sim.layers import outward_from_body
    from tryon.sim.tuck import tuck_as_asked

    centre = body.part_axes[body.parts.index("torso")].mean(axis=0) * [1.0, 0.0, 1.0]
    bottom, faces = tube(0.15, n_around=24, n_along=6, height=0.1, y0=0.9)
    bottom += centre
    top = tube(top_radius, n_around=24, n_along=6, height=0.2, y0=0.85)[0] + centre
    sides = face_sides(bottom, faces, outward_from_body(bottom, body))
    band = (0.95, 1.0)
    assert tuck_as_asked(top, bottom, faces, sides, band, "out") is out_ok
    assert tuck_as_asked(top, bottom, faces, sides, band, "in") is in_ok
    assert tuck_as_asked(top[top[:, 1] > 1.01], bottom, faces, sides, band, "out") is None


@pytest.mark.parametrize("bottom, tuck, through", [("trousers", "out", 0), ("skirt", "out", 0), ("skirt", "in", 2)])
def test_a_tshirt_and_a_bottom_are_layered_as_asked(catalogue_ids, body, bottom, tuck, through):
    """Out: the T-shirt's hem over the band; in: under it. Tucked in, a vertex or two of the shirt still comes
    through the skirt (``through``; more into trousers: see ``tryon bench --only outfits``)."""
    _, catalogue, ids = catalogue_ids
    models = [catalogue.model(ids["tshirt"]), catalogue.model(ids[bottom])]
    out = drape_outfit(body, models, tuck=tuck)
    m = out.metrics
    assert m["tuck_as_asked"] is True
    assert m["layer_penetrating_vertices"] <= through
    assert all(r.metrics["penetrating_vertices"] == 0 for r in out.results)
    assert all(r.metrics["openings_on_limbs"] is not False for r in out.results)
    assert m["rest_reached"]


def test_the_api_answers_one_mesh_and_metrics_per_garment(client, catalogue_ids):
    _, _, ids = catalogue_ids
    r = client.post("/api/tryon", json={"garment_ids": [ids["tshirt"], ids["skirt"]], "measurements": BODY})
    assert r.status_code == 200, r.text
    out = r.json()
    assert [g["garment_id"] for g in out["garments"]] == [ids["skirt"], ids["tshirt"]]  # tuck out: skirt under
    assert [g["layer"] for g in out["garments"]] == [0, 1]
    for g in out["garments"]:
        v, f = np.array(g["vertices"]), np.array(g["faces"])
        assert v.shape[1] == 3 and f.max() < len(v) and len(g["metrics"]["strain"]) == len(v)
        assert g["metrics"]["penetrating_vertices"] == 0
    m = out["metrics"]
    assert m["layers"] == [ids["skirt"], ids["tshirt"]] and m["tuck"] == "out"
    assert m["layer_penetrating_vertices"] == 0 and m["penetrating_vertices"] == 0
    # asked again: the result cache, saying so
    again = client.post("/api/tryon", json={"garment_ids": [ids["tshirt"], ids["skirt"]], "measurements": BODY})
    assert again.json()["metrics"]["cached"] is True
    # the GLB holds each garment as a node of its own, named by id
    glb = client.post("/api/tryon?format=glb", json={"garment_ids": [ids["tshirt"], ids["skirt"]],
                                                      "measurements": BODY})
    assert glb.status_code == 200
    scene = trimesh.load(io.BytesIO(glb.content), file_type="glb")
    assert set(scene.geometry) == {ids["skirt"], ids["tshirt"]}
    assert sum(len(g.vertices) for g in scene.geometry.values()) == sum(len(g["vertices"]) for g in out["garments"])
    assert json.loads(glb.headers["X-Tryon-Metrics"])["layers"] == m["layers"]


@pytest.mark.parametrize("change, field", [
    ({"garment_ids": ["tshirt", "nope"]}, "garment_ids[1]"),
    ({"garment_ids": ["tshirt", "trousers", "skirt"]}, "garment_ids"),
    ({"garment_ids": ["tshirt", "trousers", "skirt", "longsleeve"]}, "garment_ids"),
    ({"garment_ids": []}, "garment_ids"),
    ({"garment_ids": ["tshirt", "tshirt"]}, "garment_ids"),
    ({"garment_ids": ["tshirt"], "garment_id": "tshirt"}, "garment_id"),
    ({"garment_ids": ["tshirt"], "tuck": "half"}, "tuck"),
    ({"garment_id": "tshirt", "tuck": "in"}, "tuck"),
])
def test_outfits_a_user_cannot_wear_are_refused_naming_the_field(client, catalogue_ids, change, field):
    _, _, ids = catalogue_ids
    payload = {"measurements": BODY}
    for key, value in change.items():
        payload[key] = [ids.get(v, v) for v in value] if isinstance(value, list) else ids.get(value, value)
    r = client.post("/api/tryon", json=payload)
    assert r.status_code == 422, r.text
    assert field in r.text


def test_the_stream_sends_every_garment_with_its_ranges(client, catalogue_ids):
    _, _, ids = catalogue_ids
    with client.websocket_connect("/ws/tryon") as ws:
        ws.send_text(json.dumps({"garment_ids": [ids["tshirt"], ids["trousers"]], "tuck": "in",
                                 "measurements": BODY, "settings": {"max_steps": 40}}))
        init = json.loads(ws.receive_text())
        assert init["type"] == "init", init
        garments = init["garments"]
        assert [g["id"] for g in garments] == [ids["tshirt"], ids["trousers"]]  # tuck in: trousers over
        assert garments[1]["vertex_start"] == garments[0]["vertex_count"]
        assert sum(g["vertex_count"] for g in garments) == init["vertex_count"]
        assert sum(g["face_count"] for g in garments) == init["face_count"] == len(init["faces"])
        frames = 0
        while True:
            message = ws.receive()
            if message.get("bytes") is not None:
                assert len(message["bytes"]) == FRAME_HEADER.size + 12 * init["vertex_count"]
                frames += 1
                continue
            done = json.loads(message["text"])
            break
        assert done["type"] == "done" and frames >= 1
        assert [g["garment_id"] for g in done["metrics"]["garments"]] == [ids["tshirt"], ids["trousers"]]
        assert len(done["strain"]) == init["vertex_count"]


def test_a_file_of_a_shirt_and_trousers_drapes_its_pieces_as_layers(body):
    """One file holding a T-shirt and trousers (as MakeHuman's outfits do): its pieces drape as an outfit, the
    shirt over the trousers, and the answer is still one garment in the file's own vertex order."""
    from tryon.garment.generate import garment_mesh
    from tryon.garment.ingest import CleanMesh
    from tryon.garment.prepare import prepare
    from tryon.sim.outfit import piece_categories
    from tryon.sim.run import drape

    shirt, trousers = garment_mesh("tshirt", "M"), garment_mesh("trousers", "M")
    sv, tv = np.asarray(shirt.vertices, dtype=np.float64), np.asarray(trousers.vertices, dtype=np.float64)
    faces = np.vstack([np.asarray(shirt.faces), np.asarray(trousers.faces) + len(sv)]).astype(np.int32)
    mesh = CleanMesh(vertices=np.vstack([sv, tv]), faces=faces, units="m", units_guessed=False)
    model = prepare(mesh, id="outfit", name="outfit", category="top", size="M", source_sha256="0",
                    source_name="outfit.obj")
    assert sorted(piece_categories(model)) == ["bottom", "top"]
    result = drape(body, model)
    m = result.metrics
    assert m["layered_pieces"] == 2
    assert m["layer_penetrating_vertices"] == 0 and m["penetrating_vertices"] == 0
    assert m["rest_reached"] and m["openings_on_limbs"]
    assert result.vertices.shape == model.vertices.shape and np.array_equal(result.faces, model.faces)
    # the file's first vertices are the shirt's: they stay above the trousers' (which begin at the waist)
    legs = result.vertices[len(sv):]
    assert result.vertices[:len(sv), 1].max() > legs[:, 1].max() + 0.2
    assert legs[:, 1].min() < 0.2  # trouser hems near the floor


def test_an_outfit_asked_for_over_rest_is_replayed_from_the_cache_over_the_stream(client, catalogue_ids):
    _, _, ids = catalogue_ids
    request = {"garment_ids": [ids["longsleeve"], ids["trousers"]], "measurements": BODY,
               "settings": {"max_steps": 40}}
    first = client.post("/api/tryon", json=request)
    assert first.status_code == 200, first.text
    with client.websocket_connect("/ws/tryon") as ws:
        ws.send_text(json.dumps(request))
        init = json.loads(ws.receive_text())
        assert [g["id"] for g in init["garments"]] == [ids["trousers"], ids["longsleeve"]]
        frame = ws.receive_bytes()
        assert len(frame) == FRAME_HEADER.size + 12 * init["vertex_count"]
        done = json.loads(ws.receive_text())
    assert done["cached"] is True
    assert [g["garment_id"] for g in done["metrics"]["garments"]] == [ids["trousers"], ids["longsleeve"]]
    shown = np.frombuffer(frame[FRAME_HEADER.size:], dtype="<f4").reshape(-1, 3)
    rest = np.concatenate([np.array(g["vertices"]) for g in first.json()["garments"]])
    assert np.abs(shown - rest).max() < 1e-4  # the same final state, in the same order


def test_an_outfits_shown_meshes_are_untangled_without_going_through_each_other(tmp_path, body):
    """The T-shirt M tucked into the shorts M: their shown meshes cross their own folds in 18 and 103 edges when
    not untangled; untangled as they are built, each round followed by the push off the layer under it, in
    0 and 1 here (at most half asserted: the folds move with the platform's rounding; the T-shirt tucked into the
    trousers, used before, crossed in 39 edges with OpenBLAS told its core type, OPENBLAS_CORETYPE=Haswell, and 18
    without), with no more of either layer through the other and nothing in the body. The simulated meshes are the
    same either way."""
    from dataclasses import replace

    from tryon.bench.stress import catalogue_models
    from tryon.sim.tuning import TUNING

    models = catalogue_models(data_dir=tmp_path, names=["tshirt-m.obj", "shorts-m.obj"])
    untangled = drape_outfit(body, models, tuck="in")
    tangled = drape_outfit(body, models, tuck="in", tuning=replace(TUNING, untangle_step=0.0))
    before = [r.metrics["self_crossings"] for r in tangled.results]
    after = [r.metrics["self_crossings"] for r in untangled.results]
    assert sum(before) > 40 and sum(after) <= sum(before) // 2, (before, after)
    assert (untangled.metrics["layer_penetrating_vertices"]
            <= max(2, tangled.metrics["layer_penetrating_vertices"]))
    assert all(r.metrics["penetrating_vertices"] == 0 for r in untangled.results)
    assert all(np.array_equal(a.coarse, b.coarse) for a, b in zip(untangled.results, tangled.results))


def test_a_tshirt_under_a_long_sleeve_comes_to_rest(catalogue_ids, body):
    """Two tops: the long-sleeve's points pushed off the T-shirt keep the T-shirt's plane through the next step
    (without it the two fought every step and the outfit ran to its step limit)."""
    _, catalogue, ids = catalogue_ids
    out = drape_outfit(body, [catalogue.model(ids["tshirt"]), catalogue.model(ids["longsleeve"])])
    m = out.metrics
    assert m["layers"] == [ids["tshirt"], ids["longsleeve"]] and m["tuck_as_asked"] is None
    assert m["rest_reached"] and m["steps"] < 200
    assert all(r.metrics["penetrating_vertices"] == 0 for r in out.results)
    assert all(r.metrics["openings_on_limbs"] is not False for r in out.results)
    assert m["max_layer_penetration_mm"] < 30.0


def test_an_outfit_is_the_same_whether_its_garments_step_at_once_or_in_turn(catalogue_ids, body):
    """Where the caller may use two threads the garments step (and relax, and build their shown meshes) at once,
    one thread each (``blocks.at_once``); one thread steps them in turn. Each touches only its own drape,
    so the outfits are the same to the bit."""
    import threading

    from tryon.sim import outfit
    from tryon.sim.blocks import machine_threads, use_threads

    _, catalogue, ids = catalogue_ids
    models = [catalogue.model(ids["tshirt"]), catalogue.model(ids["skirt"])]
    seen = set()
    each = outfit.at_once

    def spy(fn, drapes):  # notes which threads ran the garments' work
        def noted(d):
            seen.add(threading.current_thread().name)
            return fn(d)
        return each(noted, drapes)

    runs = []
    try:
        outfit.at_once = spy
        for threads in (1, machine_threads()):
            use_threads(threads)
            runs.append(drape_outfit(body, models, tuck="out"))
    finally:
        outfit.at_once = each
        use_threads(machine_threads())
    for a, b in zip(runs[0].results, runs[1].results):
        assert np.array_equal(a.vertices, b.vertices)
    assert runs[0].metrics["steps"] == runs[1].metrics["steps"]
    if machine_threads() > 1:
        assert any(name.startswith("tryon-at-once") for name in seen)  # the two-thread run did step at once


def test_a_file_that_is_already_an_outfit_is_not_layered_with_more(tmp_path):
    """A top and trousers in one file (a MakeHuman outfit) drapes as its own layers when tried on alone; listed
    with another bottom it would be an outfit of two bottoms (a user's MakeHuman outfit with the catalogue trousers
    was draped as one 'dress' under them: never at rest, 240 vertices through the trousers). 422 naming the list
    entry; alone it drapes."""
    from tryon.garment.generate import garment_mesh

    shirt, trousers = garment_mesh("tshirt", "M"), garment_mesh("trousers", "M")
    both = trimesh.util.concatenate([shirt, trousers])
    catalogue = Catalogue(tmp_path)
    outfit = catalogue.ingest(both.export(file_type="obj").encode(), name="Shirt and trousers",
                              category="auto", units="m", filename="tshirt-and-trousers.obj")
    assert outfit.category == "dress"
    skirt = catalogue.ingest(ROOT / "garments" / "skirt-m.obj", name="Skirt M", category="bottom", units="m")
    with TestClient(create_app(Settings(data_dir=tmp_path))) as client:
        for ids, k in (([outfit.id, skirt.id], 0), ([skirt.id, outfit.id], 1)):
            r = client.post("/api/tryon", json={"garment_ids": ids, "measurements": BODY})
            assert r.status_code == 422, r.text
            detail = r.json()["detail"]
            assert detail.startswith(f"garment_ids[{k}]: 'Shirt and trousers' is already an outfit"), detail
        alone = client.post("/api/tryon", json={"garment_ids": [outfit.id], "measurements": BODY,
                                                "settings": {"max_steps": 40}})
        assert alone.status_code == 200, alone.text
        # the catalogue says which entry is a file of pieces (the page then offers nothing to wear with it)
        listed = {g["id"]: g["pieces"] for g in client.get("/api/garments").json()["garments"]}
        assert listed == {outfit.id: ["top", "bottom"], skirt.id: None}  # the shirt is a top (issue 50)
        assert client.get(f"/api/garments/{outfit.id}").json()["pieces"] == ["top", "bottom"]


def test_no_spring_of_an_outfit_ends_past_three_times_its_length(tmp_path, body):
    """The T-shirt M tucked into the skirt S (a band 8 cm under the medium body's waist): the layer and body
    collisions after the relaxation left a band spring at 6.1 x its length (max_strain 5.1), past issue 5's
    bound of 3 x; the last word is now the bound's (``outfit.FINAL_CAP``)."""
    from tryon.bench.stress import catalogue_models
    from tryon.sim.outfit import FINAL_CAP

    models = catalogue_models(data_dir=tmp_path, names=["tshirt-m.obj", "skirt-s.obj"])
    out = drape_outfit(body, models, tuck="in")
    worst = [r.metrics["max_strain"] for r in out.results]
    assert max(worst) <= FINAL_CAP - 1.0 + 1e-6, worst
    # the band is still far too small: the figures say so (past its 10 % limit, too tight at the waist)
    assert max(worst) > 0.5
    assert "torso waist" in out.results[1].metrics["too_tight"]
    assert out.metrics["tuck_as_asked"]


def test_a_top_over_a_bottom_it_fits_is_not_left_tight_by_the_layers(tmp_path):
    """The T-shirt S and trousers M the advice gives 170 / 92 / 76 / 98, worn together (the T-shirt over): the
    last layer pushes left the T-shirt's back over the trousers' seat with a spring at 43 % (max_strain 0.43,
    "too tight at the hips"); with a relaxation round after each push no spring of either ends over its limit
    (the jersey's shear 15 %) and neither is too tight anywhere."""
    from tryon.bench.stress import catalogue_models

    shopper = build_body(Measurements(height=170, chest=92, waist=76, hips=98), Pose())
    models = catalogue_models(data_dir=tmp_path, names=["trousers-m.obj", "tshirt-s.obj"])
    out = drape_outfit(shopper, models)
    assert out.metrics["rest_reached"] and out.metrics["layer_penetrating_vertices"] == 0
    for r in out.results:
        assert r.metrics["too_tight"] == {}, r.metrics["too_tight"]
        assert r.metrics["max_strain"] <= 0.15 + 1e-3, r.metrics["max_strain"]


def test_an_inner_layer_on_the_body_does_not_give_way_to_the_outer_one():
    """Two crossed layers 1 mm apart: pushed apart by inverse mass, the inner one gives way (it moves in); where
    its points lie on the body (``on_body``), the body is under them and the outer layer takes the whole move.
    Pushed into the body instead, a waistband under a top's hem was pushed back out along the body's normal,
    up the hips' slope, a little every step: the A-line skirt M under the long-sleeve M on the small body climbed
    23 cm once the jersey was as stiff as its fabric."""
    from tryon.sim.layers import collide_layers

    tri = np.array([[0.0, 0.0, 0.0], [0.1, 0.0, 0.0], [0.0, 0.1, 0.0]])
    faces = [np.array([[0, 1, 2]], dtype=np.int64)] * 2
    sides = [np.ones(1)] * 2  # counter-clockwise seen from +z: +z is outward

    def collided(on_body):
        inner, outer = tri.copy(), tri + [0.01, 0.01, -0.001]
        points = [inner, outer]
        collide_layers(points, [p.copy() for p in points], [np.ones(3), np.ones(3)], faces, sides, 0.002,
                       both_ways=True, on_body=on_body)
        return inner, outer

    inner, outer = collided(None)
    assert inner[:, 2].min() < -1e-4  # the inner layer gave way
    inner, outer = collided([np.ones(3, dtype=np.bool_), np.zeros(3, dtype=np.bool_)])
    assert np.array_equal(inner, tri)
    assert outer[0, 2] == pytest.approx(0.002)  # its point over the inner triangle went the whole gap out


def test_a_shirt_tucked_into_trousers_is_gathered_above_the_crotch(tmp_path):
    """The T-shirt M hangs below the crotch of 170 / 92 / 76 / 98 (tucked out); tucked into the trousers M its tail
    lay across the gap between the thighs and held the trousers' crotch seam under it: the trousers were "too
    tight at the left thigh, the right thigh, the waist, the right shin and the hips", shown at 2.35x. Gathered
    inside the band (``tuck.tail_gathered``) it ends above the crotch and the trousers are not too tight; the
    catalogue's T-shirt keeps its own lengths."""
    from tryon.bench.stress import catalogue_models
    from tryon.sim.landmarks import body_landmarks
    from tryon.sim.tuck import TAIL_ABOVE_CROTCH

    shopper = build_body(Measurements(height=170, chest=92, waist=76, hips=98), Pose())
    crotch = body_landmarks(shopper).crotch_y
    shirt, trousers = catalogue_models(data_dir=tmp_path, names=["tshirt-m.obj", "trousers-m.obj"])
    rest = shirt.rest.copy()
    out = drape_outfit(shopper, [shirt, trousers], tuck="out")
    assert out.results[1].coarse[:, 1].min() < crotch - 0.05  # the shirt, over the trousers, hangs past the crotch
    tucked = drape_outfit(shopper, [shirt, trousers], tuck="in")
    top, bottom = tucked.results
    assert tucked.metrics["tuck_as_asked"] and tucked.metrics["layer_penetrating_vertices"] == 0
    assert top.coarse[:, 1].min() > crotch + TAIL_ABOVE_CROTCH - 0.015  # 1.5 cm above it at least
    assert bottom.metrics["too_tight"] == {}, bottom.metrics["too_tight"]
    assert bottom.metrics["max_strain"] < 0.25  # 0.48 with the tail between the thighs
    assert np.array_equal(shirt.rest, rest)
