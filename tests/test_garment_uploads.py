"""Uploads an admin can trust (issue 50, item 4), through the real API: a surface with no opening for the body is
refused whatever its category; a refusal names the real reason (a non-finite, absurd or stray coordinate, with the
vertex, its value and the limit, not the triangle count cleaning left); a file of several pieces lists a shirt as a
top; ``PATCH /api/garments/{id}`` changes an entry's name, size, style, chart and fabric with an upload's checks
(another fabric rescales its masses); the same file uploaded again under another name is a 409 pointing to PATCH;
an upload's fabric (issue 51: its category's, or one named), and GET /api/fabrics. Every refusal leaves the
catalogue as it was.
Meshes are made here (a tube, a sheet, the generator's garments)."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from fastapi.testclient import TestClient

from test_garment_refusals import assert_our_words, tube_obj
from tryon.api.app import create_app
from tryon.config import Settings
from tryon.garment.generate import garment_mesh
from tryon.garment.ingest import MAX_COORDINATE, MIN_OPENING_M
from tryon.sim.pieces import TOP_HEM_FRACTION, piece_kinds

AUTH = {"Authorization": "Bearer t"}
TUBE = tube_obj().encode()  # a plain skirt: 0.3 m across, 0.5 m tall, two openings


@pytest.fixture()
def client(tmp_path):
    app = create_app(Settings(data_dir=tmp_path, admin_token="t", max_upload_bytes=4_000_000, max_faces=20_000))
    with TestClient(app) as c:
        yield c


def upload(client, data: bytes, filename: str = "tube-skirt.obj", headers=AUTH, **form):
    fields = {"name": "Tube", "category": "bottom", "units": "m", **form}
    return client.post("/api/garments", files={"file": (filename, data)}, data=fields, headers=headers)


@pytest.fixture()
def tube(client):
    """The tube in the catalogue (its entry); the listing is what every refusal must leave."""
    r = upload(client, TUBE)
    assert r.status_code == 201, r.text
    return r.json()


def listing(client) -> dict:
    return client.get("/api/garments").json()


def refused(r, status: int, *words: str) -> str:
    """The detail of a refusal with ``status``, holding each of ``words``, in our words."""
    assert r.status_code == status, r.text
    detail = r.json()["detail"]
    text = detail if isinstance(detail, str) else " ".join(f"{'.'.join(map(str, e['loc']))}: {e['msg']}"
                                                            for e in detail)
    for w in words:
        assert w in text, (w, text)
    assert_our_words(text)
    return text


# --- meshes ---------------------------------------------------------------------------------------


def grid(n: int, size: float, y0: float = 1.0, hole: tuple[int, int] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """An upright square sheet ``size`` m wide of n x n quads (two triangles each), from height ``y0``; ``hole``:
    quads (i0, i1) left out in both directions (a square hole in the middle)."""
    v = np.array([[size * i / n, y0 + size * j / n, 0.0] for j in range(n + 1) for i in range(n + 1)])
    faces = []
    for j in range(n):
        for i in range(n):
            if hole and hole[0] <= i < hole[1] and hole[0] <= j < hole[1]:
                continue
            a = j * (n + 1) + i
            faces += [[a, a + 1, a + n + 2], [a, a + n + 2, a + n + 1]]
    return v, np.array(faces)


def obj(v: np.ndarray, f: np.ndarray) -> bytes:
    return trimesh.Trimesh(v, f, process=False).export(file_type="obj").encode()


def with_vertex(text: str, number: int, value: str, axis: int = 1) -> tuple[str, int]:
    """``text`` (OBJ) with coordinate ``axis`` of its vertex ``number`` (1-based) set to ``value``, and that
    vertex's line number."""
    lines = text.split("\n")
    seen = 0
    for k, line in enumerate(lines):
        if line.startswith("v "):
            seen += 1
            if seen == number:
                parts = line.split()
                parts[1 + axis] = value
                lines[k] = " ".join(parts)
                return "\n".join(lines), k + 1
    raise ValueError(number)


# --- a surface with no opening --------------------------------------------------------------------


@pytest.mark.parametrize("category", ["top", "bottom", "dress", "auto"])
def test_a_flat_sheet_is_refused_whatever_its_category(client, tube, category):
    """A flat 1 m square sheet with no opening was taken as a top (and 'stayed up'): its one open edge is its
    rim, and nothing can go through it."""
    sheet = obj(*grid(20, 1.0))
    r = upload(client, sheet, filename="sheet-shirt.obj", category=category)
    refused(r, 422, "file: the mesh has no opening for the body", "its only open edge is its rim",
            "at least 2 openings", "whatever its category")
    assert listing(client) == {"garments": [tube]}


def test_a_sheet_with_a_small_hole_and_a_sheet_beside_a_garment_are_refused(client, tube):
    """A hole in the cloth under MIN_OPENING_M around is not an opening; a sheet beside a sewn garment in one file
    is refused as a piece, with its share of the cloth."""
    assert MIN_OPENING_M == pytest.approx(0.15)
    holed = obj(*grid(40, 1.0, hole=(20, 21)))  # one 2.5 cm quad left out: a hole 10 cm around
    r = upload(client, holed, filename="holed-shirt.obj", category="top")
    refused(r, 422, "the mesh has only one opening for the body", "1 is a hole in the cloth under 15 cm around")
    skirt = trimesh.load(trimesh.util.wrap_as_stream(TUBE), file_type="obj", process=False)
    v, f = grid(12, 0.6, y0=0.0)
    both = trimesh.util.concatenate([skirt, trimesh.Trimesh(v + [1.0, 0.0, 0.0], f, process=False)])
    r = upload(client, both.export(file_type="obj").encode(), filename="skirt-and-sheet.obj")
    refused(r, 422, "a piece of the mesh (", "of its cloth, 2 pieces in all) has no opening for the body")
    assert listing(client) == {"garments": [tube]}


# --- a refusal names the real reason ----------------------------------------------------------------


TUBE_1024 = tube_obj(around=32, rows=16, quads=False)  # 1,024 triangles


@pytest.mark.parametrize("value, words", [
    ("1e30", ["has an absurd coordinate, y = 1e+30", f"at most {MAX_COORDINATE:,.0f} either way"]),
    ("-3.4e38", ["has an absurd coordinate, y = -3.4e+38"]),
    ("nan", ["has a non-finite coordinate, y = nan", "finite number"]),
    ("inf", ["has a non-finite coordinate, y = inf"]),
    ("5000", ["is a stray vertex: its y = 5000", "times the garment's size", "the limit of 10 times"]),
])
def test_a_bad_coordinate_is_named_with_its_vertex_value_and_limit(client, tube, value, words):
    """A 1,024-triangle tube with one vertex at 1e30 was refused as 'the mesh has 3 triangles, too few' (the
    vertex's triangles made every other one look degenerate beside them)."""
    assert TUBE_1024.count("\nf ") + TUBE_1024.startswith("f ") == 1024
    text, line = with_vertex(TUBE_1024, 201, value)
    for units in ("m", "auto"):
        r = upload(client, text.encode(), category="bottom", units=units)
        detail = refused(r, 422, f"file: vertex 201 (line {line}) ", *words)
        assert "triangle" not in detail
    assert listing(client) == {"garments": [tube]}


# --- a multi-piece file's pieces ------------------------------------------------------------------


def tubes(top: tuple[float, float], bottom: tuple[float, float]) -> tuple[np.ndarray, np.ndarray]:
    """Two separate tubes (points, triangles): one from height top[0] to top[1] (m), one from bottom[0] to bottom[1]."""
    meshes = []
    for lo, hi, r in ((*top, 0.2), (*bottom, 0.18)):
        m = trimesh.creation.cylinder(radius=r, segment=[[0, lo, 0], [0, hi, 0]], sections=24)
        keep = np.abs(m.face_normals[:, 1]) < 0.5  # the side only: open at both ends
        side = trimesh.Trimesh(m.vertices, m.faces[keep], process=False)
        side.remove_unreferenced_vertices()
        meshes.append(side)
    both = trimesh.util.concatenate(meshes)
    return np.asarray(both.vertices), np.asarray(both.faces)


@pytest.mark.parametrize("top, kind", [((0.75, 1.4), "top"), ((0.45, 1.4), "top"), ((0.2, 1.4), None)])
def test_a_piece_over_a_bottom_is_a_top_by_where_its_hem_ends(top, kind):
    """Beside trousers whose waist is at 0.85 m, a piece reaching 0.55 m over that waist and ending 10 or 40 cm
    under it (the generator's long T-shirt ends 0.73 of its reach under the waist) is a top, whatever the file's
    category (dress, guessed from 'outfit'); one reaching down the legs is a dress over trousers that are not
    taken for a bottom of their own (their waist is above its middle): one garment, no pieces."""
    v, f = tubes(top, (0.0, 0.85))
    for category in ("dress", "top"):
        assert piece_kinds(v, f, category) == (None if kind is None else [kind, "bottom"])
    assert piece_kinds(v, f, "bottom") is None  # catalogued as a bottom: one bottom
    assert TOP_HEM_FRACTION == 1.0  # a hem at mid-thigh: about as far under the waist as the neck is over it


def test_an_outfit_file_lists_its_shirt_as_a_top(client):
    """A shirt and trousers in one file named as an outfit: the entry is a dress (the file name says so), its
    pieces a top and a bottom (the MakeHuman outfits listed their shirts and blouses as 'dress')."""
    both = trimesh.util.concatenate([garment_mesh("tshirt", "M"), garment_mesh("trousers", "M")])
    r = upload(client, both.export(file_type="obj").encode(), filename="outfit-tshirt-trousers.obj", category="auto",
               name="Shirt and trousers")
    assert r.status_code == 201, r.text
    entry = r.json()
    assert entry["category"] == "dress" and entry["pieces"] == ["top", "bottom"], entry
    assert client.get(f"/api/garments/{entry['id']}").json()["pieces"] == ["top", "bottom"]


# --- PATCH /api/garments/{id} ------------------------------------------------------------------------


def test_patch_changes_name_size_style_and_chart(client, tube):
    gid = tube["id"]
    model_before = client.app.state.catalogue.model(gid)  # cached in this process before the change
    assert model_before.meta.name == "Tube"
    r = client.patch(f"/api/garments/{gid}", headers=AUTH, json={
        "name": "  Pencil skirt S ", "size": "S", "style": "pencil", "chart": {"waist": [66, 72], "hips": 92}})
    assert r.status_code == 200, r.text
    entry = r.json()
    assert (entry["name"], entry["size"], entry["style"], entry["chart"]) == (
        "Pencil skirt S", "S", "pencil", {"waist": [66.0, 72.0], "hips": [92.0, 92.0]})
    assert {k: entry[k] for k in entry if k not in ("name", "size", "style", "chart")} == \
        {k: tube[k] for k in tube if k not in ("name", "size", "style", "chart")}  # the file and its preparation stay
    assert client.get(f"/api/garments/{gid}").json() == entry
    assert client.get("/api/styles").json() == [{"style": "pencil", "name": "Pencil skirt", "category": "bottom",
                                                 "sizes": [{"size": "S", "garment_id": gid, "chart": entry["chart"]}]}]
    assert client.app.state.catalogue.model(gid).meta.name == "Pencil skirt S"  # the cached model follows
    # one field at a time; null removes a style and a chart
    r = client.patch(f"/api/garments/{gid}", headers=AUTH, json={"style": None, "chart": None})
    assert r.status_code == 200 and (r.json()["style"], r.json()["chart"], r.json()["size"]) == (None, None, "S")
    r = client.patch(f"/api/garments/{gid}", headers=AUTH, json={"size": None})
    assert r.status_code == 200 and r.json()["size"] is None and r.json()["name"] == "Pencil skirt S"


@pytest.mark.parametrize("body, status, words", [
    ({}, 422, "nothing to change: give any of name, size, style, chart"),
    ({"name": "   "}, 422, "must not be blank"),
    ({"name": None}, 422, "an entry needs a name"),
    ({"name": "x" * 201}, 422, "name"),
    ({"size": "x" * 21}, 422, "size must be a label of at most 20 characters"),
    ({"style": "Pencil Skirt"}, 422, "style must be a short id"),
    ({"style": "pencil"}, 422, "size: style 'pencil' needs a size label"),
    ({"chart": {"waist": 70}}, 422, "size: a size chart row needs a size label"),
    ({"size": "S", "chart": {"hips": [20, 30]}}, 422, "hips [20, 30] cm is outside the plausible range [75, 150] cm"),
    ({"size": "S", "chart": {"waist": [80, 70]}}, 422, "waist min 80 cm is greater than its max 70 cm"),
    ({"size": "S", "chart": {"bust": 90}}, 422, "unknown key 'bust'"),
    ({"size": "S", "chart": '{"waist": 70}'}, 422, "a size chart row is a JSON object"),
    ({"size": "S", "chart": {"waist": "70"}}, 422, "waist must be a number or [min, max] in cm"),
    ({"category": "top"}, 422, "category cannot be changed"),
    ({"units": "cm"}, 422, "units cannot be changed: it is part of how the file was prepared"),
    ({"colour": "red"}, 422, "unknown field 'colour'"),
    ({"fabric": "silk"}, 422, "fabric: unknown fabric 'silk': choose one of jersey, cotton-twill, denim"),
    ({"fabric": " "}, 422, "fabric: must not be blank: give one of jersey, cotton-twill, denim"),
    ({"fabric": "x" * 41}, 422, "fabric"),
    ({"fabric": "denim", "size": "x" * 21}, 422, "size must be a label"),  # one refusal: the fabric stays too
    ({"density": 0.3}, 422, "density cannot be changed on its own: an entry's masses are made of its fabric's"),
])
def test_patch_refusals_change_nothing(client, tube, body, status, words):
    before = listing(client)
    r = client.patch(f"/api/garments/{tube['id']}", headers=AUTH, json=body)
    refused(r, status, words)
    assert listing(client) == before


def test_patch_needs_the_admin_token_and_a_known_id(client, tube, tmp_path):
    url = f"/api/garments/{tube['id']}"
    refused(client.patch(url, json={"name": "X"}), 401, "missing admin token")
    refused(client.patch(url, json={"name": "X"}, headers={"Authorization": "Bearer nope"}), 401, "wrong admin token")
    refused(client.patch(url, json={}), 401, "missing admin token")  # the token before the body
    refused(client.patch("/api/garments/unknown", json={"name": "X"}, headers=AUTH), 404,
            "no garment with id 'unknown'")
    refused(client.patch(url, content=b"name=X", headers={**AUTH, "content-type": "text/plain"}), 422,
            "the body must be a JSON object")
    assert listing(client) == {"garments": [tube]}
    with TestClient(create_app(Settings(data_dir=tmp_path, admin_token=None))) as reader:
        refused(reader.patch(url, json={"name": "X"}, headers=AUTH), 403, "catalogue writes are disabled")
    assert listing(client) == {"garments": [tube]}


def test_patch_keeps_a_styles_sizes_each_once(client, tube):
    other = upload(client, tube_obj(around=26).encode(), name="Tube M", size="M", style="tube")
    assert other.status_code == 201, other.text
    first = client.patch(f"/api/garments/{tube['id']}", headers=AUTH, json={"size": "S", "style": "tube"})
    assert first.status_code == 200, first.text
    before = listing(client)
    r = client.patch(f"/api/garments/{tube['id']}", headers=AUTH, json={"size": "m"})
    refused(r, 409, "style: style 'tube' already has a size M")
    assert listing(client) == before


# --- the same file again -------------------------------------------------------------------------


def test_the_same_file_under_another_name_is_a_409_pointing_to_patch(client, tube):
    """It silently kept the old name; now the upload says the file is in, as what, and how to change that."""
    gid = tube["id"]
    r = upload(client, TUBE, name="Tube skirt")
    refused(r, 409, f"name: this file is already in the catalogue as garment {gid} (its name is 'Tube', not "
                    f"'Tube skirt'): to change its words, PATCH /api/garments/{gid}")
    r = upload(client, TUBE, size="S")  # a size without a style would be dropped just as silently
    refused(r, 409, "size: this file is already in the catalogue", "its size is none, not S")
    assert listing(client) == {"garments": [tube]}
    # the same words: the entry as it is (200, as documented); after a rename, the new name is the entry's
    assert upload(client, TUBE, name=" Tube ").status_code == 200
    assert client.patch(f"/api/garments/{gid}", headers=AUTH, json={"name": "Tube skirt"}).status_code == 200
    again = upload(client, TUBE, name="Tube skirt")
    assert again.status_code == 200 and again.json()["name"] == "Tube skirt", again.text
    # with a style, an entry takes the style, size and chart given (a catalogue made before styles gains them)
    styled = upload(client, TUBE, name="Tube skirt", style="tube", size="S")
    assert styled.status_code == 200 and (styled.json()["style"], styled.json()["size"]) == ("tube", "S")
    assert len(listing(client)["garments"]) == 1
    # once it has one, its own words stay: another style or size is a 409 pointing to PATCH, as another fabric is
    before = listing(client)
    refused(upload(client, TUBE, name="Tube skirt", style="tube", size="M"), 409, "size: this file is already in",
            "its size is S, not M", f"PATCH /api/garments/{gid}")
    refused(upload(client, TUBE, name="Tube skirt", style="pencil", size="S"), 409, "its style is tube, not pencil")
    refused(upload(client, TUBE, name="Tube skirt", fabric="denim"), 409, "fabric: this file is already in",
            "its fabric is cotton-twill, not denim")
    assert listing(client) == before
    assert upload(client, TUBE, name="Tube skirt", style="tube", size="S", fabric="cotton-twill").status_code == 200


# --- fabrics (issue 51, item 1) ---------------------------------------------------------------------

FIGURES = {  # garment/fabric.py: Wang, O'Brien, Ramamoorthi 2011
    "jersey": {"density": 0.187, "stretch": 51.07, "shear": 73.72},
    "cotton-twill": {"density": 0.22, "stretch": 4051.5, "shear": 209.5},
    "denim": {"density": 0.324, "stretch": 1219.25, "shear": 106.8},
}


def stored(client, tmp_path) -> tuple:
    """What the catalogue holds: its listing, and the files in its sources and models."""
    files = sorted(str(p.relative_to(tmp_path)) for d in ("sources", "models") for p in (tmp_path / d).rglob("*"))
    return listing(client), files


def assert_made_of(client, entry: dict, fabric: str, density: float | None = None) -> None:
    """The answer names ``fabric`` with its figures, and the stored model's masses are of ``density`` kg/m^2
    (the fabric's unless given)."""
    from tryon.garment.catalogue import mass_density

    density = FIGURES[fabric]["density"] if density is None else density
    assert entry["fabric"] == fabric and entry["density"] == pytest.approx(density)
    figures = entry["fabric_figures"]
    assert figures["name"] == fabric and "Wang, O'Brien, Ramamoorthi 2011" in figures["source"]
    assert {k: pytest.approx(figures[k], rel=1e-3) for k in FIGURES[fabric]} == FIGURES[fabric]
    model = client.app.state.catalogue.model(entry["id"])
    assert model.fabric.name == fabric and mass_density(model) == pytest.approx(density, rel=1e-9)


def test_an_upload_is_made_of_its_categorys_fabric_unless_it_names_one(client, tube):
    assert_made_of(client, tube, "cotton-twill")  # a bottom: a woven
    top = upload(client, tube_obj(around=26).encode(), filename="tube-top.obj", name="Tube top", category="top")
    assert top.status_code == 201, top.text
    assert_made_of(client, top.json(), "jersey")  # a top: a knit
    dress = upload(client, tube_obj(around=28).encode(), filename="tube-dress.obj", name="Tube dress",
                   category="dress", fabric=" denim ")
    assert dress.status_code == 201, dress.text
    assert_made_of(client, dress.json(), "denim")
    assert client.get(f"/api/garments/{dress.json()['id']}").json() == dress.json()
    assert [g["fabric"] for g in listing(client)["garments"]] == ["cotton-twill", "jersey", "denim"]


def test_the_fabrics_are_listed_with_their_figures(client):
    r = client.get("/api/fabrics")
    assert r.status_code == 200
    body = r.json()
    assert [f["name"] for f in body["fabrics"]] == list(FIGURES)
    for f in body["fabrics"]:
        assert {k: pytest.approx(f[k], rel=1e-3) for k in FIGURES[f["name"]]} == FIGURES[f["name"]]
        assert f["bending"] > 0 and "ARCSim materials" in f["source"]
    assert body["defaults"] == {"top": "jersey", "dress": "jersey", "bottom": "cotton-twill"}


@pytest.mark.parametrize("fabric, words", [
    ("silk", "fabric: unknown fabric 'silk': choose one of jersey, cotton-twill, denim (GET /api/fabrics"),
    ("Jersey", "unknown fabric 'Jersey'"),
    ("x" * 41, "fabric"),
])
def test_an_unknown_fabric_is_refused_with_nothing_stored(client, tube, tmp_path, fabric, words):
    before = stored(client, tmp_path)
    r = upload(client, tube_obj(around=30).encode(), filename="other-skirt.obj", name="Other", fabric=fabric)
    refused(r, 422, words)
    assert stored(client, tmp_path) == before


def test_patch_changes_the_fabric_and_rescales_the_masses(client, tube):
    """The masses were the old fabric's density: they become the new one's (times 0.187 / 0.220 from cotton twill
    to jersey), in the answer and the stored model; the id stays; null is the category's again; a try-on asked
    again after the change is draped again, not answered from the result cache."""
    gid = tube["id"]
    before = client.app.state.catalogue.model(gid).mass.copy()
    request = {"garment_id": gid, "measurements": {"height": 170, "chest": 92, "waist": 76, "hips": 98},
               "settings": {"max_steps": 3}}
    first = client.post("/api/tryon", json=request)
    assert first.status_code == 200 and not first.json()["metrics"]["cached"], first.text[:300]
    assert client.post("/api/tryon", json=request).json()["metrics"]["cached"]

    r = client.patch(f"/api/garments/{gid}", headers=AUTH, json={"fabric": "jersey"})
    assert r.status_code == 200, r.text
    entry = r.json()
    assert entry["id"] == gid and entry["name"] == "Tube"
    assert_made_of(client, entry, "jersey")
    np.testing.assert_allclose(client.app.state.catalogue.model(gid).mass, before * (0.187 / 0.220), rtol=1e-12)
    assert client.get(f"/api/garments/{gid}").json() == entry and listing(client) == {"garments": [entry]}
    assert {k: v for k, v in entry.items() if k not in ("fabric", "fabric_figures", "density")} == \
        {k: v for k, v in tube.items() if k not in ("fabric", "fabric_figures", "density")}
    again = client.post("/api/tryon", json=request)
    assert again.status_code == 200 and not again.json()["metrics"]["cached"], again.text[:300]

    back = client.patch(f"/api/garments/{gid}", headers=AUTH, json={"fabric": None})
    assert back.status_code == 200 and back.json() == tube
    np.testing.assert_allclose(client.app.state.catalogue.model(gid).mass, before, rtol=1e-12)


def test_patching_a_fabric_needs_the_admin_token(client, tube, tmp_path):
    before = stored(client, tmp_path)
    url = f"/api/garments/{tube['id']}"
    refused(client.patch(url, json={"fabric": "denim"}), 401, "missing admin token")
    refused(client.patch(url, json={"fabric": "denim"}, headers={"Authorization": "Bearer nope"}), 401,
            "wrong admin token")
    assert stored(client, tmp_path) == before
    assert client.app.state.catalogue.model(tube["id"]).fabric.name == "cotton-twill"
