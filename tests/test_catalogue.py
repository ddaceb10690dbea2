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
