"""Short stability stress test (the long one: ``tryon bench --stress``)."""

from __future__ import annotations

import pytest

from tryon.sim.stress import MAX_ENERGY, MAX_STRETCH, catalogue_models, stress


@pytest.mark.slow
def test_random_scenes_never_blow_up(tmp_path):
    # two garments (a top and a bottom, 0.3 coarse) keep the preparation short; 8 scenes ~ 30-60 s
    models = catalogue_models(data_dir=tmp_path, names=["tshirt-s.obj", "trousers-l.obj"])
    summary = stress(8, seed=7, models=models)
    assert summary["never_nan"], summary["failures"]
    assert summary["max_stretch"] <= MAX_STRETCH, summary["failures"]
    assert summary["max_energy_J_per_kg"] <= MAX_ENERGY, summary["failures"]
    assert summary["failed"] == 0, summary["failures"]
