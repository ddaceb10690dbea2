"""Issue 31: garment preparation on a real local Ray cluster (two worker processes), the catalogue written
on the driver exactly as a local ingestion writes it; a worker killed mid-task is retried by Ray."""

from __future__ import annotations

import os
import sys
from pathlib import Path

import numpy as np
import pytest

from tryon.cli import main
from tryon.garment.catalogue import Catalogue
from tryon.garment.generate import garment_mesh, obj_text

ray = pytest.importorskip("ray", reason="the scale extra (pip install '.[scale]') is installed by the test command")
pytestmark = pytest.mark.e2e


@pytest.fixture(scope="module")
def files(tmp_path_factory) -> list[Path]:
    root = tmp_path_factory.mktemp("ray-files")
    out = []
    for kind, size in (("tshirt", "S"), ("skirt", "M"), ("shorts", "L")):
        path = root / f"{kind}-{size.lower()}.obj"
        path.write_text(obj_text(garment_mesh(kind, size), kind))
        out.append(path)
    bad = root / "broken-shirt.obj"
    bad.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3/\n")
    return out + [bad]


@pytest.fixture(scope="module")
def local_ray():
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False, logging_level="ERROR")
    yield
    ray.shutdown()


def arrays(directory: Path) -> dict:
    with np.load(directory / "model.npz") as z:
        return {k: z[k] for k in z.files}


@pytest.mark.slow
def test_ray_ingestion_is_the_local_one(tmp_path, files, local_ray, capsys):
    args = [str(p) for p in files] + ["--units", "m"]
    assert main(["ingest", *args, "--data-dir", str(tmp_path / "local")]) == 1  # the broken file is refused
    local_out = capsys.readouterr().out
    assert main(["ingest", *args, "--data-dir", str(tmp_path / "ray"), "--ray", "auto"]) == 1
    ray_out = capsys.readouterr().out
    assert "broken-shirt.obj: REFUSED: line 4" in local_out and "broken-shirt.obj: REFUSED: line 4" in ray_out
    assert "3 of 4 garments" in ray_out
    local, remote = Catalogue(tmp_path / "local"), Catalogue(tmp_path / "ray")
    assert sorted(m.id for m in local.list()) == sorted(m.id for m in remote.list())
    for meta in local.list():
        other = remote.get(meta.id)
        assert other is not None and (other.name, other.category, other.vertices) == (meta.name, meta.category,
                                                                                       meta.vertices)
        a, b = arrays(local.models / meta.id), arrays(remote.models / meta.id)
        assert a.keys() == b.keys() and all(np.array_equal(a[k], b[k]) for k in a), meta.name  # bit for bit
    # run again: nothing to prepare, every file already in
    assert main(["ingest", *args[:3], "--units", "m", "--data-dir", str(tmp_path / "ray"), "--ray", "auto"]) == 0
    assert capsys.readouterr().out.count("(cached)") == 3


def _dies_once(marker: str) -> int:
    """Kills its own worker process the first time (as a crash or an out-of-memory kill would)."""
    if not os.path.exists(marker):
        Path(marker).write_text("died")
        os._exit(1)
    return os.getpid()


@pytest.mark.slow
def test_a_killed_worker_is_retried(tmp_path, local_ray):
    from tryon.scale.ray_jobs import run_tasks

    ray.cloudpickle.register_pickle_by_value(sys.modules[__name__])  # the workers cannot import this test file
    results = dict(run_tasks(_dies_once, [(str(tmp_path / "marker"),)]))
    assert isinstance(results[0], int) and Path(tmp_path / "marker").exists()


def test_without_ray_the_flag_says_how_to_install_it(tmp_path, files, monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "ray", None)  # import ray fails, as when the extra is not installed
    assert main(["ingest", str(files[0]), "--units", "m", "--data-dir", str(tmp_path / "d"), "--ray"]) == 1
    assert "pip install '.[scale]'" in capsys.readouterr().err
    assert Catalogue(tmp_path / "d").list() == []
