"""Stability stress test: many randomized scenes, checked at every step (issue 5).

Each scene: a body with measurements drawn across the whole allowed range (and a random arm angle), a
random catalogue garment, a time step in [0.005, 0.1] s, 1 to 50 constraint passes, strain limits from
very stiff (1 %) to very loose (100 %), and a smooth random initial displacement of the aligned garment
(up to 3 cm, wavelengths >= 0.3 m, so it bends the cloth instead of shredding single springs). At every
step: every position finite, no spring longer than 3x its natural length, kinetic energy bounded.

``stress(n_scenes, seed)`` returns a summary dict; ``tryon bench --stress`` prints it.
"""

from __future__ import annotations

import json
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from tryon.body.build import build_body
from tryon.body.params import MEASUREMENT_RANGES, POSE_RANGES, REQUIRED, Measurements, Pose, check_measurements
from tryon.garment.model import GarmentModel
from tryon.sim.align import align_garment
from tryon.sim.constraints import spring_lengths
from tryon.sim.run import settle
from tryon.sim.start import start
from tryon.sim.settings import SimSettings

GARMENTS_DIR = Path(__file__).resolve().parents[3] / "garments"
# Largest spring length / natural length allowed at any step (issue 5).
MAX_STRETCH = 3.0
# J/kg: mean kinetic energy per kg allowed at any step. The speed clamp (SimSettings.max_speed, 10 m/s)
# bounds it by 50 J/kg; a free fall from the shoulders reaches ~15 J/kg.
MAX_ENERGY = 50.0
# Steps per scene: enough for a garment to fall onto the body and settle or misbehave.
SCENE_STEPS = 120


def catalogue_models(garments_dir: Path = GARMENTS_DIR, data_dir: Path | None = None,
                     names: list[str] | None = None, simplification: float = 0.3) -> list[GarmentModel]:
    """The repository's catalogue garments (``garments/catalogue.json``) prepared into ``data_dir``
    (a temporary directory by default); ``names``: only those files."""
    from tryon.garment.catalogue import Catalogue

    entries = json.loads((garments_dir / "catalogue.json").read_text())
    if names:
        entries = [e for e in entries if e["file"] in names]
    catalogue = Catalogue(data_dir or Path(tempfile.mkdtemp(prefix="tryon-stress-")))
    models = []
    for e in entries:
        meta = catalogue.ingest(garments_dir / e["file"], name=e["name"], category=e["category"],
                                units=e.get("units", "m"), size=e.get("size"), simplify=simplification)
        models.append(catalogue.model(meta.id))
    return models


def random_measurements(rng: np.random.Generator) -> Measurements:
    """Required measurements uniform over their ranges, redrawn until plausible together."""
    for _ in range(1000):
        m = Measurements(**{k: float(rng.uniform(*MEASUREMENT_RANGES[k])) for k in REQUIRED})
        if not check_measurements(m):
            return m
    raise RuntimeError("no plausible measurements drawn")


def smooth_displacement(points: np.ndarray, rng: np.random.Generator, amplitude: float) -> np.ndarray:
    """(k, 3) displacement: a sum of three random plane waves (wavelength 0.3-1 m) of total amplitude
    up to ``amplitude`` metres, plus nothing per vertex (a smooth field)."""
    out = np.zeros_like(points)
    for _ in range(3):
        k = rng.normal(size=3)
        k *= 2 * np.pi / rng.uniform(0.3, 1.0) / np.linalg.norm(k)
        out += rng.normal(size=3) / np.sqrt(3) * amplitude / 3 * np.sin(points @ k + rng.uniform(0, 2 * np.pi))[:, None]
    return out


def random_settings(rng: np.random.Generator) -> SimSettings:
    passes = int(rng.integers(1, 51))
    stiffness = float(np.exp(rng.uniform(np.log(0.01), np.log(1.0))))  # structural limit 1 % .. 100 %
    return SimSettings(
        time_step=float(rng.uniform(0.005, 0.1)),
        passes=passes,
        substeps=int(rng.integers(1, min(passes, 16) + 1)),
        max_steps=SCENE_STEPS,
        strain_limit=(stiffness, 1.5 * stiffness, 3.0 * stiffness),
        min_steps=SCENE_STEPS,  # run every step: the test is about what happens along the way
    )


def run_scene(model: GarmentModel, settings: SimSettings, measurements: Measurements, pose: Pose,
              rng: np.random.Generator, amplitude: float = 0.03) -> dict:
    """One scene, checked at every step; returns its record."""
    body = build_body(measurements, pose)
    x0 = align_garment(body, model) + smooth_displacement(model.coarse_vertices, rng, amplitude)
    springs = model.springs.astype(np.int64)
    worst = {"stretch": 0.0, "energy": 0.0, "finite": True, "step": 0}
    prev = [x0.copy()]
    mass = model.mass

    def check(step: int, x: np.ndarray) -> bool:
        worst["step"] = step
        if not np.all(np.isfinite(x)):
            worst["finite"] = False
            return False
        ratio = float((spring_lengths(x, springs) / model.rest).max())
        v = (x - prev[0]) / settings.time_step
        energy = float(0.5 * (mass * (v * v).sum(axis=1)).sum() / mass.sum())
        prev[0] = x.copy()
        worst["stretch"] = max(worst["stretch"], ratio)
        if step > 1:  # the first step starts from the displaced positions
            worst["energy"] = max(worst["energy"], energy)
        return True

    error = None
    try:
        # every step checked, the start-up's too (``drape`` with ``initial``, its start-up handed over)
        result = settle(start(body, model, settings, initial=x0), check, start_up=True)[0]
        final_ok = bool(np.all(np.isfinite(result.vertices)))
    except FloatingPointError as exc:  # the loop's own NaN guard
        error, final_ok = str(exc), False
    ok = (worst["finite"] and final_ok and worst["stretch"] <= MAX_STRETCH and worst["energy"] <= MAX_ENERGY
          and error is None)
    return {
        "garment": model.meta.name, "ok": ok, "max_stretch": round(worst["stretch"], 4),
        "max_energy_J_per_kg": round(worst["energy"], 4), "finite": worst["finite"] and final_ok,
        "steps": worst["step"], "error": error,
        "time_step": round(settings.time_step, 4), "passes": settings.passes, "substeps": settings.substeps,
        "structural_limit": round(settings.strain_limit[0], 4),
        "measurements": {k: round(v, 1) for k, v in measurements.as_dict().items() if v is not None},
        "arm_angle": round(pose.arm_angle_left, 1),
    }


def stress(n_scenes: int = 100, seed: int = 0, models: list[GarmentModel] | None = None) -> dict:
    """Run ``n_scenes`` random scenes (see the module doc); summary with the worst values and failures."""
    rng = np.random.default_rng(seed)
    models = models if models is not None else catalogue_models()
    t0 = time.perf_counter()
    records = []
    for i in range(n_scenes):
        model = models[i % len(models)] if i < len(models) else models[int(rng.integers(len(models)))]
        pose = replace(Pose(), arm_angle=float(rng.uniform(*POSE_RANGES["arm_angle_left"])))  # both sides
        records.append(run_scene(model, random_settings(rng), random_measurements(rng), pose, rng))
    failures = [r for r in records if not r["ok"]]
    return {
        "scenes": n_scenes,
        "seed": seed,
        "garments": sorted({r["garment"] for r in records}),
        "passed": n_scenes - len(failures),
        "failed": len(failures),
        "never_nan": all(r["finite"] for r in records),
        "max_stretch": max((r["max_stretch"] for r in records), default=0.0),
        "max_energy_J_per_kg": max((r["max_energy_J_per_kg"] for r in records), default=0.0),
        "limits": {"stretch": MAX_STRETCH, "energy_J_per_kg": MAX_ENERGY},
        "wall_seconds": round(time.perf_counter() - t0, 2),
        "failures": failures[:20],
    }
