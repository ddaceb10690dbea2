"""``tryon ingest``: one line per garment, cached the second time, refused files named with a reason."""

import json

import pytest

from tryon.cli import main
from tryon.garment.catalogue import Catalogue
from tryon.garment.generate import garment_mesh, obj_text


def test_ingest_files_and_a_refused_one(tmp_path, capsys):
    good = tmp_path / "skirt-s.obj"
    good.write_text(obj_text(garment_mesh("skirt", "S"), "skirt"))
    bad = tmp_path / "broken-top.obj"
    bad.write_bytes(b"v 0 0 0\nv 1 0 0\n")
    data = tmp_path / "data"
    code = main(["ingest", str(good), str(bad), "--units", "m", "--size", "S", "--data-dir", str(data)])
    out = capsys.readouterr().out
    assert code == 1
    assert "[1/2] skirt-s.obj:" in out and "bottom S" in out and "-> " in out and " ms" in out
    assert "[2/2] broken-top.obj: REFUSED: the file is a point cloud" in out
    assert "1 of 2 garments" in out and "1 refused" in out
    entries = Catalogue(data).list()
    assert [(e.name, e.category, e.size, e.units) for e in entries] == [("skirt-s", "bottom", "S", "m")]

    code = main(["ingest", str(good), "--units", "m", "--size", "S", "--data-dir", str(data)])
    assert code == 0 and "(cached)" in capsys.readouterr().out


def test_ingest_a_catalogue_directory(tmp_path, capsys):
    src = tmp_path / "garments"
    src.mkdir()
    entries = []
    for kind, category in (("shorts", "bottom"), ("tshirt", "top")):
        (src / f"{kind}.obj").write_text(obj_text(garment_mesh(kind, "S"), kind))
        entries.append(dict(file=f"{kind}.obj", name=f"{kind} S", category=category, size="S", units="m"))
    (src / "catalogue.json").write_text(json.dumps(entries))
    data = tmp_path / "data"
    assert main(["ingest", "--catalogue", str(src), "--data-dir", str(data)]) == 0
    out = capsys.readouterr().out
    assert "[1/2] shorts.obj" in out and "[2/2] tshirt.obj" in out and "2 of 2 garments" in out
    listed = Catalogue(data).list()
    assert [(e.name, e.category, e.size) for e in listed] == [("shorts S", "bottom", "S"), ("tshirt S", "top", "S")]


def test_usage_errors(tmp_path, capsys):
    assert main(["ingest", "--data-dir", str(tmp_path)]) == 2
    assert main(["ingest", "a.obj", "b.obj", "--name", "x", "--data-dir", str(tmp_path)]) == 2
    assert main(["ingest", "a.obj", "--simplify", "1.5", "--data-dir", str(tmp_path)]) == 2
    assert main(["ingest", str(tmp_path / "missing.obj"), "--data-dir", str(tmp_path)]) == 1
    assert "no such file" in capsys.readouterr().out


@pytest.mark.parametrize("listing, words", [
    (None, "no such file"),  # a directory without catalogue.json
    ("{not json", "expecting property name"),
    ('{"file": "x.obj"}', "expected a json list"),
    ('[{"name": "no file"}]', 'entry 0 is not an object with a "file"'),
    ('["x.obj"]', "entry 0"),
])
def test_bad_catalogue_directory_is_a_usage_error(tmp_path, capsys, listing, words):
    src = tmp_path / "src"
    src.mkdir()
    if listing is not None:
        (src / "catalogue.json").write_text(listing)
    assert main(["ingest", "--catalogue", str(src), "--data-dir", str(tmp_path / "data")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("tryon ingest: cannot read") and words in err.lower(), err


def test_unusable_data_dir_or_settings_are_usage_errors(tmp_path, capsys, monkeypatch):
    blocker = tmp_path / "a-file"
    blocker.write_text("not a directory")
    assert main(["ingest", str(blocker), "--data-dir", str(blocker / "data")]) == 2
    assert "cannot open the catalogue in" in capsys.readouterr().err
    broken = tmp_path / "broken"
    broken.mkdir()
    (broken / "catalogue.sqlite").write_text("not a database")
    assert main(["ingest", str(blocker), "--data-dir", str(broken)]) == 2
    assert "not a database" in capsys.readouterr().err
    monkeypatch.setenv("TRYON_MAX_FACES", "lots")
    assert main(["ingest", str(blocker), "--data-dir", str(tmp_path / "d")]) == 2
    assert "TRYON_MAX_FACES='lots'" in capsys.readouterr().err


def test_a_directory_given_as_a_file_is_refused_by_name(tmp_path, capsys):
    assert main(["ingest", str(tmp_path), "--data-dir", str(tmp_path / "data")]) == 1
    assert "is a directory" in capsys.readouterr().out


@pytest.mark.parametrize("flag, value", [("--units", "furlong"), ("--category", "hat"), ("--simplify", "abc")])
def test_bad_flag_values_are_refused_by_argparse(tmp_path, capsys, flag, value):
    with pytest.raises(SystemExit) as exit_:
        main(["ingest", "a.obj", flag, value, "--data-dir", str(tmp_path)])
    assert exit_.value.code == 2 and flag in capsys.readouterr().err


def test_category_guessed_from_the_file_name():
    from tryon.garment.catalogue import guess_category

    assert guess_category("polo-shirt.obj") == "top"
    assert guess_category("A-line_Skirt.glb") == "bottom"
    assert guess_category("cargo-pants.obj") == "bottom"
    assert guess_category("dress-straps.obj") == "dress"
    assert guess_category("outfit-tshirt-pants.obj") == "dress"  # a top and a bottom in one file
    assert guess_category("blouse-skirt.obj") == "dress"
    assert guess_category("longsleeve-m.obj") == "top"
    assert guess_category("short-sleeve-shirt.obj") == "top"  # not shorts and a shirt
    assert guess_category("shorts-m.obj") == "bottom"
    assert guess_category("garment.obj") is None  # no hint: refused, not taken for a top


def _listing(tmp_path, kinds=(("shorts", "bottom"), ("tshirt", "top")), styled=True):
    """A garments/ directory like the repository's: its OBJ files and a catalogue.json with fabrics."""
    from tryon.garment.fabric import DEFAULT_FABRIC

    src = tmp_path / "garments"
    src.mkdir(parents=True, exist_ok=True)
    entries = []
    for kind, category in kinds:
        (src / f"{kind}-s.obj").write_text(obj_text(garment_mesh(kind, "S"), kind))
        entry = dict(file=f"{kind}-s.obj", name=f"{kind} S", category=category, size="S", units="m",
                     fabric=DEFAULT_FABRIC[category])
        if styled:
            entry.update(style=kind, chart={"waist": [70.0, 78.0]})
        entries.append(entry)
    (src / "catalogue.json").write_text(json.dumps(entries))
    return src


def test_ingest_says_each_garments_fabric_and_takes_a_density_given(tmp_path, capsys):
    """The catalogue's fabric reaches the entry (and the line printed); --fabric names one for files; --density
    wins over the fabric's."""
    src, data = _listing(tmp_path), tmp_path / "data"
    assert main(["ingest", "--catalogue", str(src), "--data-dir", str(data)]) == 0
    out = capsys.readouterr().out
    assert "cotton-twill 220 g/m2" in out and "jersey 187 g/m2" in out
    assert [(e.fabric, e.density) for e in Catalogue(data).list()] == [("cotton-twill", 0.22), ("jersey", 0.187)]
    assert main(["ingest", str(src / "shorts-s.obj"), "--units", "m", "--fabric", "denim", "--density", "0.4",
                 "--data-dir", str(data)]) == 0
    assert "denim 400 g/m2" in capsys.readouterr().out
    with pytest.raises(SystemExit) as exit_:
        main(["ingest", str(src / "shorts-s.obj"), "--fabric", "silk", "--data-dir", str(data)])
    assert exit_.value.code == 2 and "jersey" in capsys.readouterr().err


def test_patched_words_survive_the_catalogue_ingest_at_the_next_start(tmp_path, capsys):
    """scripts/serve.sh runs ``tryon ingest --catalogue garments/`` at every start: a shipped garment whose size,
    style, chart and fabric were PATCHed through the API keeps them (it took catalogue.json's back); an entry with
    no style (a catalogue from before styles) still gains catalogue.json's style, size and chart."""
    from fastapi.testclient import TestClient

    from tryon.api.app import create_app
    from tryon.config import Settings

    src, data = _listing(tmp_path), tmp_path / "data"
    assert main(["ingest", "--catalogue", str(src), "--data-dir", str(data)]) == 0
    auth = {"Authorization": "Bearer t"}
    with TestClient(create_app(Settings(data_dir=data, admin_token="t"))) as client:
        shorts = next(g for g in client.get("/api/garments").json()["garments"] if g["style"] == "shorts")
        r = client.patch(f"/api/garments/{shorts['id']}", headers=auth,
                         json={"size": "M", "style": "cutoffs", "chart": {"waist": [78, 86]}, "fabric": "denim"})
        assert r.status_code == 200, r.text
        patched = r.json()
    assert (patched["size"], patched["style"], patched["fabric"]) == ("M", "cutoffs", "denim")
    assert main(["ingest", "--catalogue", str(src), "--data-dir", str(data)]) == 0  # the next start
    capsys.readouterr()
    with TestClient(create_app(Settings(data_dir=data, admin_token="t"))) as client:
        assert client.get(f"/api/garments/{shorts['id']}").json() == patched
        assert len(client.get("/api/garments").json()["garments"]) == 2

    bare = tmp_path / "before-styles"
    _listing(bare, kinds=(("skirt", "bottom"),), styled=False)
    old = tmp_path / "old-data"
    assert main(["ingest", "--catalogue", str(bare / "garments"), "--data-dir", str(old)]) == 0
    assert Catalogue(old).list()[0].style is None
    _listing(bare, kinds=(("skirt", "bottom"),))
    assert main(["ingest", "--catalogue", str(bare / "garments"), "--data-dir", str(old)]) == 0
    gained = Catalogue(old).list()[0]
    assert (gained.style, gained.size, gained.chart) == ("skirt", "S", {"waist": [70.0, 78.0]})
