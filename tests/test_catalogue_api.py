"""Garment REST API: catalogue reads, admin writes, and every bad upload leaves the catalogue as it was."""

import io

import numpy as np
import pytest
import trimesh
from fastapi.testclient import TestClient

from tryon.api.app import create_app
from tryon.config import Settings
from tryon.garment.generate import garment_mesh, obj_text

AUTH = {"Authorization": "Bearer t"}


@pytest.fixture(scope="module")
def skirt_obj() -> bytes:
    return obj_text(garment_mesh("skirt", "S"), "skirt").encode()


@pytest.fixture()
def client(tmp_path):
    app = create_app(Settings(data_dir=tmp_path, admin_token="t", max_upload_bytes=2_000_000, max_faces=20_000))
    with TestClient(app) as c:
        yield c


def upload(client, data, filename="skirt.obj", headers=AUTH, **form):
    fields = {"name": "Skirt", "category": "bottom", "units": "m", **form}
    return client.post("/api/garments", files={"file": (filename, data)}, data=fields, headers=headers)


def test_upload_list_get_mesh_delete(client, skirt_obj):
    assert client.get("/api/garments").json() == {"garments": []}
    r = upload(client, skirt_obj, size="S")
    assert r.status_code == 201, r.text
    entry = r.json()
    assert entry["name"] == "Skirt" and entry["category"] == "bottom" and entry["size"] == "S"
    assert entry["units"] == "m" and entry["units_guessed"] is False
    assert entry["vertices"] > 2000 and entry["faces"] > entry["coarse_faces"] > 0
    assert entry["coarse_vertices"] == pytest.approx(0.3 * entry["vertices"], abs=2)
    assert all(entry["springs"][k] > 0 for k in ("structural", "shear", "bending"))
    gid = entry["id"]
    assert client.get("/api/garments").json()["garments"] == [entry]
    assert client.get(f"/api/garments/{gid}").json() == entry
    assert client.get("/api/garments/unknown").status_code == 404

    mesh = client.get(f"/api/garments/{gid}/mesh").json()
    assert len(mesh["vertices"]) == entry["vertices"] and len(mesh["faces"]) == entry["faces"]
    coarse = client.get(f"/api/garments/{gid}/mesh?level=coarse").json()
    assert len(coarse["vertices"]) == entry["coarse_vertices"]
    glb = client.get(f"/api/garments/{gid}/mesh?format=glb")
    assert glb.status_code == 200 and glb.headers["content-type"] == "model/gltf-binary"
    loaded = trimesh.load(io.BytesIO(glb.content), file_type="glb", force="mesh", process=False)
    assert len(loaded.faces) == entry["faces"]
    obj = client.get(f"/api/garments/{gid}/mesh?format=obj")
    assert obj.status_code == 200 and obj.text.count("\nf ") + obj.text.startswith("f ") == entry["faces"]
    assert client.get(f"/api/garments/{gid}/mesh?format=fbx").status_code == 422
    assert client.get("/api/garments/unknown/mesh").status_code == 404

    assert client.delete(f"/api/garments/{gid}").status_code == 401
    assert client.delete(f"/api/garments/{gid}", headers=AUTH).status_code == 204
    assert client.get(f"/api/garments/{gid}").status_code == 404
    assert client.delete(f"/api/garments/{gid}", headers=AUTH).status_code == 404


def test_same_upload_twice_is_the_same_entry(client, skirt_obj):
    first = upload(client, skirt_obj)
    second = upload(client, skirt_obj)
    assert first.status_code == 201 and second.status_code == 200
    assert first.json()["id"] == second.json()["id"]
    assert len(client.get("/api/garments").json()["garments"]) == 1
    # the same bytes named as another format are refused as that format would be, not taken as the entry
    as_glb = upload(client, skirt_obj, filename="skirt.glb")
    assert as_glb.status_code == 422 and as_glb.json()["detail"].startswith("file: skirt.glb is not a readable GLB"), \
        as_glb.text
    assert len(client.get("/api/garments").json()["garments"]) == 1


def test_simplify_parameter(client, skirt_obj):
    r = upload(client, skirt_obj, simplify="0.5")
    assert r.status_code == 201 and r.json()["simplification"] == 0.5
    assert upload(client, skirt_obj, simplify="0").status_code == 422


def test_writes_disabled_without_a_configured_token(tmp_path, skirt_obj):
    with TestClient(create_app(Settings(data_dir=tmp_path, admin_token=None))) as c:
        r = upload(c, skirt_obj)
        assert r.status_code == 403 and "TRYON_ADMIN_TOKEN" in r.json()["detail"]
        assert c.delete("/api/garments/x", headers=AUTH).status_code == 403
        assert c.get("/api/garments").json() == {"garments": []}


def nonfinite_obj() -> bytes:
    return b"v 0 0 0\nv 1 0 nan\nv 0 1 0\nv 1 1 0\nf 1 2 3\nf 2 4 3\n"


def big_obj() -> bytes:
    n = 110  # 110 x 110 quads = 24,200 triangles > max_faces 20,000, still under 2 MB
    lines = [f"v {i / n:.3f} {j / n:.3f} 0" for j in range(n + 1) for i in range(n + 1)]
    lines += [f"f {j * (n + 1) + i + 1} {j * (n + 1) + i + 2} {(j + 1) * (n + 1) + i + 2} {(j + 1) * (n + 1) + i + 1}"
              for j in range(n) for i in range(n)]
    return ("\n".join(lines) + "\n").encode()


BAD_UPLOADS = [
    # label, kwargs for upload(), expected status, words in the message
    ("no token", dict(headers={}), 401, "missing admin token"),
    ("wrong token", dict(headers={"Authorization": "Bearer nope"}), 401, "wrong admin token"),
    ("not bearer", dict(headers={"Authorization": "Basic dDp0"}), 401, "token"),
    ("empty file", dict(data=b""), 422, "empty"),
    ("garbage", dict(data=b"\x00\xffnot a mesh" * 50), 422, "skirt.obj is not a readable OBJ file"),
    ("garbage glb", dict(data=b"glTF" + b"\x00" * 40, filename="x.glb"), 422, "x.glb is not a readable GLB file"),
    ("unknown extension", dict(filename="skirt.fbx"), 415, "FBX"),
    ("other extension", dict(filename="skirt.txt"), 415, "unknown file type"),
    ("3ds", dict(filename="skirt.3ds"), 415, "3DS"),
    ("non-finite", dict(data=nonfinite_obj()), 422, "non-finite"),
    ("point cloud", dict(data=b"v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 1\n"), 422, "point cloud"),
    ("too many bytes", dict(data=b"v 0 0 0\n" * 300_000), 413, "larger than the limit"),
    ("too many faces", dict(data=big_obj(), units="m"), 413, "faces"),
    ("parent path", dict(filename="../x.obj"), 400, "directory"),
    ("sub path", dict(filename="a/b.obj"), 400, "directory"),
    ("bad category", dict(category="hat"), 422, "category"),
    ("bad units", dict(units="furlong"), 422, "units"),
    ("blank name", dict(name="   "), 422, "name: must not be blank"),
    ("simplify not a number", dict(simplify="abc"), 422, "simplify"),
    ("simplify NaN", dict(simplify="nan"), 422, "simplify.*finite"),
    ("simplify infinite", dict(simplify="inf"), 422, "simplify.*finite"),
    ("simplify out of range", dict(simplify="0"), 422, "simplify.*greater than"),
]


@pytest.mark.parametrize("label,kwargs,status,words", BAD_UPLOADS, ids=[b[0] for b in BAD_UPLOADS])
def test_bad_uploads_are_refused_and_change_nothing(client, skirt_obj, label, kwargs, status, words):
    existing = upload(client, skirt_obj, name="Existing")
    assert existing.status_code == 201
    before = client.get("/api/garments").json()
    kwargs = dict(kwargs)
    data = kwargs.pop("data", skirt_obj)
    r = upload(client, data, **kwargs)
    assert r.status_code == status, r.text
    assert __import__("re").search(words, str(r.json()["detail"]), __import__("re").IGNORECASE), r.json()
    assert client.get("/api/garments").json() == before


def test_truncated_upload_is_refused(client, skirt_obj):
    r = upload(client, skirt_obj[: len(skirt_obj) // 2 + 1])
    assert r.status_code == 422 and "truncated" in r.json()["detail"]
    assert client.get("/api/garments").json() == {"garments": []}


def test_one_catalogue_per_app(client, skirt_obj):
    upload(client, skirt_obj)
    app = client.app
    assert app.state.catalogue is not None
    cat = app.state.catalogue
    client.get("/api/garments")
    assert app.state.catalogue is cat
    model = cat.model(cat.list()[0].id)
    assert np.isfinite(model.vertices).all()


def test_preparing_an_upload_does_not_stall_the_server(client, skirt_obj, monkeypatch):
    """An upload is prepared in a worker thread, not on the event loop: while its preparation is held (until
    another request has been answered) the server answers that request. Were the preparation on the event
    loop, nothing else could be answered until it ended, and the hold would run out (a guard against a hang,
    not a measured limit)."""
    import threading

    from tryon.garment import catalogue as catalogue_module

    preparing, answered, held = threading.Event(), threading.Event(), []
    prepare_model = catalogue_module.prepare_model

    def prepare_held(job):
        preparing.set()
        held.append(answered.wait(timeout=120))  # True: released by an answer given meanwhile
        return prepare_model(job)

    monkeypatch.setattr(catalogue_module, "prepare_model", prepare_held)
    result = {}
    worker = threading.Thread(target=lambda: result.update(r=upload(client, skirt_obj)), daemon=True)
    worker.start()
    assert preparing.wait(timeout=120), "the upload never reached its preparation"
    assert client.get("/api/health").status_code == 200 and client.get("/api/garments").json() == {"garments": []}
    answered.set()
    worker.join(timeout=120)
    assert held == [True], "the server answered nothing while the upload was being prepared"
    assert result["r"].status_code == 201, result["r"].text
    assert [g["name"] for g in client.get("/api/garments").json()["garments"]] == ["Skirt"]


def test_flat_pattern_with_stitch_lines_is_a_422_saying_so(client):
    from test_garment_ingest import flat_pattern_obj

    r = upload(client, flat_pattern_obj(stitches=12), filename="pattern.obj", category="dress")
    assert r.status_code == 422
    assert "flat patterns with stitch lines are not supported" in r.json()["detail"]
    assert client.get("/api/garments").json() == {"garments": []}
