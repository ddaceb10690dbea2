"""The catalogue: idempotent, atomic, safe with concurrent ingestions, read back without re-preparing."""

import json
import os
import subprocess
import sys
import threading
from pathlib import Path

import numpy as np
import pytest

import tryon.garment.catalogue as catalogue_module
from tryon.garment.catalogue import Catalogue
from tryon.garment.generate import garment_mesh, obj_text
from tryon.garment.ingest import GarmentError
from tryon.garment.model import GarmentModel


@pytest.fixture(scope="module")
def skirt_obj() -> bytes:
    return obj_text(garment_mesh("skirt", "S"), "skirt").encode()


@pytest.fixture(scope="module")
def shorts_obj() -> bytes:
    return obj_text(garment_mesh("shorts", "S"), "shorts").encode()


def count_prepares(monkeypatch) -> list:
    calls = []
    real = catalogue_module.prepare

    def counting(*args, **kwargs):
        calls.append(kwargs.get("simplification"))
        return real(*args, **kwargs)

    monkeypatch.setattr(catalogue_module, "prepare", counting)
    return calls


def test_ingest_list_get_model(tmp_path, skirt_obj):
    cat = Catalogue(tmp_path)
    meta = cat.ingest(skirt_obj, name="Skirt S", category="bottom", units="m", size="S", filename="skirt.obj")
    assert len(meta.id) == 12
    assert [m.id for m in cat.list()] == [meta.id]
    assert cat.get(meta.id) == meta and cat.get("nope") is None
    assert meta.vertices > 2000 and meta.coarse_vertices == pytest.approx(0.3 * meta.vertices, abs=2)
    model = cat.model(meta.id)
    assert isinstance(model, GarmentModel)
    assert model.meta.name == "Skirt S" and model.meta.size == "S"
    assert len(model.coarse_index) == meta.coarse_vertices
    assert (tmp_path / "catalogue.sqlite").exists()
    with pytest.raises(KeyError):
        cat.model("nope")


def test_idempotent_same_file_same_params(tmp_path, skirt_obj, monkeypatch):
    cat = Catalogue(tmp_path)
    calls = count_prepares(monkeypatch)
    a, created_a = cat.ingest_with_status(skirt_obj, "Skirt", "bottom", "m", filename="skirt.obj")
    b, created_b = cat.ingest_with_status(skirt_obj, "Skirt again", "bottom", "m", filename="other-name.obj")
    assert a.id == b.id and created_a and not created_b
    assert len(calls) == 1 and len(cat.list()) == 1
    c = cat.ingest(skirt_obj, "Skirt", "bottom", "m", simplify=0.5, filename="skirt.obj")
    assert c.id != a.id and len(calls) == 2  # other parameters: another entry


def test_reload_reads_back_without_preparing(tmp_path, skirt_obj, shorts_obj, monkeypatch):
    first = Catalogue(tmp_path)
    a = first.ingest(skirt_obj, "Skirt", "bottom", "m", filename="skirt.obj")
    b = first.ingest(shorts_obj, "Shorts", "bottom", "auto", filename="shorts.obj")
    model_a = first.model(a.id)
    calls = count_prepares(monkeypatch)
    second = Catalogue(tmp_path)
    assert [m.id for m in second.list()] == [a.id, b.id]
    again = second.model(a.id)
    assert np.array_equal(again.springs, model_a.springs) and np.array_equal(again.attach_bary, model_a.attach_bary)
    assert second.ingest(skirt_obj, "Skirt", "bottom", "m", filename="skirt.obj").id == a.id
    assert calls == []


def test_a_model_of_another_preparation_version_is_prepared_again(tmp_path, skirt_obj, monkeypatch):
    """A model saved by an older preparation (another PREPARATION_VERSION, or none: before versions) is
    made again from the kept source on first use, once; the entry, its name and its listing stay."""
    first = Catalogue(tmp_path)
    meta = first.ingest(skirt_obj, "Skirt", "bottom", "m", size="S", filename="skirt.obj")
    model = first.model(meta.id)
    directory = tmp_path / "models" / meta.id
    for stale in ('{"version": 1}', None):
        if stale is None:
            (directory / "prepared.json").unlink()
        else:
            (directory / "prepared.json").write_text(stale)
        assert not GarmentModel.is_current(directory)
        calls = count_prepares(monkeypatch)
        again = Catalogue(tmp_path).model(meta.id)
        assert calls == [meta.simplification]
        assert GarmentModel.is_current(directory)
        assert np.array_equal(again.springs, model.springs) and again.meta.name == "Skirt" and again.meta.size == "S"
        assert Catalogue(tmp_path).list() == [meta]
        monkeypatch.undo()
    calls = count_prepares(monkeypatch)
    Catalogue(tmp_path).model(meta.id)
    assert calls == []


def test_other_simplification_is_prepared_once_from_the_kept_source(tmp_path, skirt_obj, monkeypatch):
    cat = Catalogue(tmp_path)
    meta = cat.ingest(skirt_obj, "Skirt", "bottom", "m", filename="skirt.obj")
    calls = count_prepares(monkeypatch)
    fine = cat.model(meta.id, simplification=0.5)
    assert fine.meta.simplification == 0.5
    assert len(fine.coarse_index) == pytest.approx(0.5 * meta.vertices, abs=2)
    assert cat.model(meta.id, simplification=0.5) is fine  # in-memory LRU
    assert Catalogue(tmp_path).model(meta.id, 0.5).meta.coarse_vertices == fine.meta.coarse_vertices  # on disk
    assert calls == [0.5]
    assert len(cat.list()) == 1  # a variant is not a new entry


def test_crash_while_saving_leaves_nothing(tmp_path, skirt_obj, monkeypatch):
    cat = Catalogue(tmp_path)

    def broken_save(self, directory):
        (directory / "model.npz").write_bytes(b"half a file")
        raise OSError("disk full")

    monkeypatch.setattr(GarmentModel, "save", broken_save)
    with pytest.raises(OSError):
        cat.ingest(skirt_obj, "Skirt", "bottom", "m", filename="skirt.obj")
    assert cat.list() == []
    assert list((tmp_path / "models").iterdir()) == []
    assert list((tmp_path / "tmp").iterdir()) == []
    monkeypatch.undo()
    meta = cat.ingest(skirt_obj, "Skirt", "bottom", "m", filename="skirt.obj")  # works afterwards
    assert cat.model(meta.id).meta.id == meta.id


def test_crash_before_the_index_row_leaves_no_entry_and_is_adopted(tmp_path, skirt_obj, monkeypatch):
    cat = Catalogue(tmp_path)

    def crash(*args, **kwargs):
        raise KeyboardInterrupt("killed")

    monkeypatch.setattr(Catalogue, "_insert_row", crash)
    with pytest.raises(KeyboardInterrupt):
        cat.ingest(skirt_obj, "Skirt", "bottom", "m", filename="skirt.obj")
    assert cat.list() == []
    monkeypatch.undo()
    calls = count_prepares(monkeypatch)
    meta = Catalogue(tmp_path).ingest(skirt_obj, "Skirt", "bottom", "m", filename="skirt.obj")
    assert calls == []  # the complete model directory was adopted, not prepared again
    assert Catalogue(tmp_path).model(meta.id).meta.vertices == meta.vertices


def test_refused_file_leaves_the_catalogue_unchanged(tmp_path, skirt_obj):
    cat = Catalogue(tmp_path)
    cat.ingest(skirt_obj, "Skirt", "bottom", "m", filename="skirt.obj")
    def state():
        return (cat.list(), *(sorted(p.name for p in (tmp_path / d).iterdir()) for d in ("models", "sources", "tmp")))

    before = state()
    for data, name in [(b"", "x.obj"), (b"v 0 0 0\n", "x.obj"), (skirt_obj, "x.3ds"), (skirt_obj, "../x.obj")]:
        with pytest.raises(GarmentError):
            cat.ingest(data, "X", "top", filename=name)
    with pytest.raises(GarmentError, match="category"):
        cat.ingest(skirt_obj, "X", "hat", filename="x.obj")
    assert state() == before


def test_delete(tmp_path, skirt_obj, shorts_obj):
    cat = Catalogue(tmp_path)
    a = cat.ingest(skirt_obj, "Skirt", "bottom", "m", filename="skirt.obj")
    b = cat.ingest(shorts_obj, "Shorts", "bottom", "m", filename="shorts.obj")
    cat.model(a.id, 0.5)
    assert cat.delete(a.id) and not cat.delete(a.id)
    assert [m.id for m in cat.list()] == [b.id]
    assert sorted(p.name for p in (tmp_path / "models").iterdir()) == [b.id]
    assert len(list((tmp_path / "sources").iterdir())) == 1
    with pytest.raises(KeyError):
        cat.model(a.id)


def test_two_threads_ingesting_at_once(tmp_path, skirt_obj, shorts_obj):
    cat_a, cat_b = Catalogue(tmp_path), Catalogue(tmp_path)  # two handles, like two workers
    barrier = threading.Barrier(4)
    results, errors = [], []

    def work(cat, data, name):
        try:
            barrier.wait()
            results.append(cat.ingest(data, name, "bottom", "m", filename=f"{name}.obj").id)
        except Exception as exc:  # pragma: no cover - reported below
            errors.append(exc)

    jobs = [(cat_a, skirt_obj, "skirt"), (cat_b, skirt_obj, "skirt"), (cat_a, shorts_obj, "shorts"),
            (cat_b, shorts_obj, "shorts")]
    threads = [threading.Thread(target=work, args=j) for j in jobs]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert errors == []
    assert len(set(results)) == 2 and len(Catalogue(tmp_path).list()) == 2
    assert sorted(p.name for p in (tmp_path / "models").iterdir()) == sorted(set(results))
    for gid in set(results):
        GarmentModel.load(tmp_path / "models" / gid)  # complete, loadable


@pytest.mark.slow
def test_two_processes_ingesting_at_once(tmp_path, skirt_obj):
    src = tmp_path / "skirt.obj"
    src.write_bytes(skirt_obj)
    data_dir = tmp_path / "data"
    code = (
        "import sys; from tryon.garment.catalogue import Catalogue; "
        "m = Catalogue(sys.argv[1]).ingest(sys.argv[2], 'Skirt', 'bottom', 'm'); print(m.id)"
    )
    env = dict(os.environ)
    procs = [subprocess.Popen([sys.executable, "-c", code, str(data_dir), str(src)], stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, env=env) for _ in range(2)]
    outs = [p.communicate(timeout=120) for p in procs]
    assert all(p.returncode == 0 for p in procs), [o[1].decode()[-500:] for o in outs]
    ids = {o[0].decode().strip() for o in outs}
    assert len(ids) == 1
    cat = Catalogue(data_dir)
    assert [m.id for m in cat.list()] == list(ids)
    assert json.loads((data_dir / "models" / ids.pop() / "meta.json").read_text())["vertices"] > 2000
    assert list(Path(data_dir / "tmp").iterdir()) == []


# --- fabrics (issue 51, item 1) ---------------------------------------------------------------------


def test_catalogue_json_says_each_garments_fabric(tmp_path):
    """garments/catalogue.json (the generator's: test_garment_generate): jersey T-shirts, long-sleeves and dresses,
    cotton-twill trousers, shorts and skirts, and ingested so, their masses of that fabric's density."""
    from tryon.garment.catalogue import mass_density
    from tryon.garment.fabric import FABRICS

    root = Path(__file__).resolve().parents[1] / "garments"
    entries = json.loads((root / "catalogue.json").read_text())
    kinds = {e["style"]: e["fabric"] for e in entries}
    assert kinds == {"tshirt": "jersey", "longsleeve": "jersey", "dress": "jersey", "skirt": "cotton-twill",
                     "trousers": "cotton-twill", "shorts": "cotton-twill"}
    assert len(entries) == 30 and all(e["fabric"] == kinds[e["style"]] for e in entries)
    cat = Catalogue(tmp_path)
    for e in (e for e in entries if e["size"] == "S" and e["style"] in ("shorts", "tshirt")):
        meta = cat.ingest(root / e["file"], e["name"], e["category"], e["units"], size=e["size"], style=e["style"],
                          chart=e["chart"], fabric=e["fabric"])
        assert (meta.fabric, meta.density) == (e["fabric"], FABRICS[e["fabric"]].density)
        assert mass_density(cat.model(meta.id)) == pytest.approx(meta.density, rel=1e-9)


def test_masses_are_the_fabrics_unless_a_density_is_given(tmp_path, skirt_obj, shorts_obj):
    """No density given: the fabric's (the category's by default, or the one named); a density given wins and is
    part of the id (the fabric is not: it is one of the entry's words)."""
    from tryon.garment.catalogue import mass_density
    from tryon.garment.fabric import FABRICS

    cat = Catalogue(tmp_path)
    twill = cat.ingest(skirt_obj, "Skirt", "bottom", "m", filename="skirt.obj")
    assert (twill.fabric, twill.density) == ("cotton-twill", FABRICS["cotton-twill"].density)
    assert mass_density(cat.model(twill.id)) == pytest.approx(0.220, rel=1e-9)
    assert cat.model(twill.id).fabric is FABRICS["cotton-twill"]
    given = cat.ingest(skirt_obj, "Skirt", "bottom", "m", filename="skirt.obj", density=0.3, fabric="denim")
    assert given.id != twill.id and (given.fabric, given.density) == ("denim", 0.3)
    assert mass_density(cat.model(given.id)) == pytest.approx(0.3, rel=1e-9)
    knit = cat.ingest(shorts_obj, "Shorts", "bottom", "m", filename="shorts.obj", fabric="jersey")
    assert (knit.fabric, knit.density) == ("jersey", 0.187)
    assert mass_density(cat.model(knit.id)) == pytest.approx(0.187, rel=1e-9)
    assert cat.ingest(shorts_obj, "Shorts", "bottom", "m", filename="shorts.obj").id == knit.id  # same entry
    with pytest.raises(GarmentError, match="unknown fabric 'silk': choose one of jersey, cotton-twill, denim") as e:
        cat.ingest(skirt_obj, "Skirt", "bottom", "m", filename="other-skirt.obj", fabric="silk")
    assert e.value.field == "fabric" and len(cat.list()) == 3


def test_a_catalogue_from_before_fabrics_keeps_its_ids_and_takes_the_fabrics_density(tmp_path, skirt_obj):
    """An index without the fabric column (written before fabrics, every density 0.15): opened, each entry takes
    its category's fabric and that fabric's density, its id stays, its model is prepared again with it."""
    import sqlite3

    from tryon.garment.catalogue import mass_density

    meta = Catalogue(tmp_path).ingest(skirt_obj, "Skirt", "bottom", "m", filename="skirt.obj")
    db = sqlite3.connect(tmp_path / "catalogue.sqlite")
    db.execute("ALTER TABLE garments DROP COLUMN fabric")
    db.execute("UPDATE garments SET density = 0.15")
    db.commit()
    db.close()
    (tmp_path / "models" / meta.id / "prepared.json").write_text(json.dumps({"version": 4}))
    cat = Catalogue(tmp_path)
    again = cat.get(meta.id)
    assert (again.id, again.fabric, again.density) == (meta.id, "cotton-twill", 0.22)
    assert mass_density(cat.model(meta.id)) == pytest.approx(0.22, rel=1e-9)


def test_another_fabric_rescales_the_stored_masses_and_keeps_the_id(tmp_path, skirt_obj):
    """``update(fabric=)``: the masses were the old fabric's, so they become the new one's (the model on disk and
    its variant of another simplification too, and a cached model in another Catalogue of the same directory); a
    density given at ingestion stays."""
    from tryon.garment.catalogue import mass_density

    cat, other = Catalogue(tmp_path), Catalogue(tmp_path)
    meta = cat.ingest(skirt_obj, "Skirt", "bottom", "m", filename="skirt.obj")
    before = cat.model(meta.id).mass.copy()
    fine = cat.model(meta.id, 0.5).mass.copy()
    assert other.model(meta.id).mass.sum() == pytest.approx(before.sum())  # cached there
    changed = cat.update(meta.id, fabric="denim")
    assert (changed.id, changed.fabric, changed.density) == (meta.id, "denim", 0.324)
    ratio = 0.324 / 0.22
    for c in (cat, other, Catalogue(tmp_path)):
        np.testing.assert_allclose(c.model(meta.id).mass, before * ratio, rtol=1e-12)
        assert c.model(meta.id).fabric.name == "denim"
    np.testing.assert_allclose(cat.model(meta.id, 0.5).mass, fine * ratio, rtol=1e-12)
    on_disk = GarmentModel.load(tmp_path / "models" / meta.id)
    assert (on_disk.meta.fabric, on_disk.meta.density) == ("denim", 0.324)
    assert mass_density(on_disk) == pytest.approx(0.324, rel=1e-9)

    given = cat.ingest(skirt_obj, "Skirt 2", "bottom", "m", filename="skirt.obj", density=0.25)
    assert cat.update(given.id, fabric="jersey").density == 0.25
    assert mass_density(cat.model(given.id)) == pytest.approx(0.25, rel=1e-9)
