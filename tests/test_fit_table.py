"""Issue 31: ``tryon fit-table``, the size advice over a customer base: one row per person and style, the
same row for row in this process and on a local Ray cluster (two worker processes), resumed after an
interruption without simulating or duplicating the rows already written, and its input errors in words."""

from __future__ import annotations

import csv
from pathlib import Path

import pytest

from tryon.cli import main
from tryon.garment.catalogue import Catalogue
from tryon.garment.generate import GARMENTS, chart_row, garment_mesh, obj_text
from tryon.scale import fit_table

SIZES = ("S", "M", "L")
# People (ANSUR II style, millimetres), at the centres of the generated T-shirt's S, M and L chart rows and
# between them; the last is out of the measurement ranges (a child).
PEOPLE = [
    ("p1", 1650, 880, 740, 940), ("p2", 1700, 960, 820, 1000), ("p3", 1780, 1040, 900, 1060),
    ("p4", 1720, 920, 780, 970), ("p5", 1750, 1000, 860, 1030), ("p6", 1000, 600, 500, 600),
]


@pytest.fixture(scope="module")
def data_dir(tmp_path_factory) -> Path:
    data = tmp_path_factory.mktemp("fit-table-data")
    catalogue = Catalogue(data)
    name, category = GARMENTS["tshirt"]
    for size in SIZES:
        path = data.parent / f"tshirt-{size.lower()}.obj"
        path.write_text(obj_text(garment_mesh("tshirt", size), f"tshirt {size}"))
        catalogue.ingest(path, name=f"{name} {size}", category=category, units="m", size=size, style="tshirt",
                         chart=chart_row(size, category))
    return data


@pytest.fixture(scope="module")
def bodies(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("bodies") / "people.csv"
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["subjectid", "Gender", "stature", "chestcircumference", "waistcircumference",
                    "buttockcircumference"])
        for pid, *mm in PEOPLE:
            w.writerow([pid, "Female", *mm])
    return path


def read(path: Path) -> list[dict]:
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


@pytest.fixture(scope="module")
def serial(tmp_path_factory, data_dir, bodies) -> list[dict]:
    out = tmp_path_factory.mktemp("serial") / "table.csv"
    assert main(["fit-table", "tshirt", "--bodies", str(bodies), "--out", str(out), "--data-dir", str(data_dir)]) == 0
    return read(out)


def test_one_row_per_person_and_style(serial):
    assert [r["person"] for r in serial] == [p[0] for p in PEOPLE] and {r["style"] for r in serial} == {"tshirt"}
    by = {r["person"]: r for r in serial}
    assert by["p2"]["recommended"] == "M" and "M=fits" in by["p2"]["verdicts"]  # a chart row's centre
    assert by["p6"]["recommended"] == "" and by["p6"]["reason"].startswith("not advised: height")
    assert "chest" in by["p2"]["ease_cm"]


@pytest.mark.slow
def test_ray_gives_the_same_table(tmp_path, data_dir, bodies, serial):
    ray = pytest.importorskip("ray")
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False, logging_level="ERROR")
    try:
        out = tmp_path / "table.csv"
        assert main(["fit-table", "tshirt", "--bodies", str(bodies), "--out", str(out), "--data-dir",
                     str(data_dir), "--ray", "auto"]) == 0
    finally:
        ray.shutdown()
    key = lambda r: (r["person"], r["style"])  # noqa: E731 - rows come in the order they finish
    assert sorted(read(out), key=key) == sorted(serial, key=key)


def test_an_interrupted_table_goes_on_where_it_stopped(tmp_path, data_dir, bodies, serial, monkeypatch):
    out = tmp_path / "table.csv"
    real = fit_table.advise_person
    calls = []

    def interrupted(person, *args):
        if len(calls) == 3:
            raise KeyboardInterrupt  # Ctrl-C after three rows
        calls.append(person.id)
        return real(person, *args)

    monkeypatch.setattr(fit_table, "advise_person", interrupted)
    with pytest.raises(KeyboardInterrupt):
        main(["fit-table", "tshirt", "--bodies", str(bodies), "--out", str(out), "--data-dir", str(data_dir)])
    assert [r["person"] for r in read(out)] == ["p1", "p2", "p3"]
    calls.clear()
    monkeypatch.setattr(fit_table, "advise_person", lambda person, *args: calls.append(person.id) or real(person, *args))
    assert main(["fit-table", "tshirt", "--bodies", str(bodies), "--out", str(out), "--data-dir", str(data_dir)]) == 0
    assert calls == ["p4", "p5", "p6"]  # only the rows not written before
    assert read(out) == serial  # none lost, none twice


def test_input_errors_are_said_in_words(tmp_path, data_dir, bodies, capsys):
    out = str(tmp_path / "t.csv")
    assert main(["fit-table", "hats", "--bodies", str(bodies), "--out", out, "--data-dir", str(data_dir)]) == 2
    assert "no style 'hats'" in capsys.readouterr().err
    bad = tmp_path / "bad.csv"
    bad.write_text("subjectid,stature\n1,1700\n")
    assert main(["fit-table", "tshirt", "--bodies", str(bad), "--out", out, "--data-dir", str(data_dir)]) == 2
    assert "no column chestcircumference" in capsys.readouterr().err
    assert main(["fit-table", "tshirt", "--bodies", str(tmp_path / "none.csv"), "--out", out, "--data-dir",
                 str(data_dir)]) == 2
    assert "cannot read" in capsys.readouterr().err
    typo = tmp_path / "typo.csv"
    typo.write_text("subjectid,stature,chestcircumference,waistcircumference,buttockcircumference\n"
                    "1,1700,960,820,1000\n2,1700,96O,820,1000\n")
    assert main(["fit-table", "tshirt", "--bodies", str(typo), "--out", out, "--data-dir", str(data_dir)]) == 2
    assert "line 3: chestcircumference is '96O', not a number (mm)" in capsys.readouterr().err
    nowhere = str(tmp_path / "no-such-dir" / "t.csv")
    assert main(["fit-table", "tshirt", "--bodies", str(bodies), "--out", nowhere, "--data-dir", str(data_dir)]) == 2
    assert f"cannot write {nowhere}: there is no directory {tmp_path / 'no-such-dir'}" in capsys.readouterr().err
    assert not Path(out).exists()
