"""The benchmark's inputs: one body (size M measurements) and the catalogue garments, built once per run
and shared between sections through the run context's cache."""

from __future__ import annotations

import hashlib
import json
import tempfile
import time
from pathlib import Path

from tryon.bench.common import Context

# cm: the catalogue's size M body (tryon.garment.generate.SIZE_CHART) at an average height.
BODY_M = dict(height=175.0, chest=96.0, waist=82.0, hips=100.0)
# The garment used where the benchmark needs a single one (quick mode, peers, Pareto): the T-shirt M,
# the most requested kind of garment, with sleeves (the hardest start for the alignment).
MAIN_GARMENT = "tshirt-m.obj"


_GENERATED: list[Path] = []


def garments_dir() -> Path:
    """The repository's ``garments/`` (catalogue sources); outside a checkout (an installed package), the
    catalogue is generated once per process into a temporary directory."""
    here = Path(__file__).resolve()
    for parent in here.parents:
        if (parent / "pyproject.toml").exists() and (parent / "garments" / "catalogue.json").exists():
            return parent / "garments"
    if not _GENERATED:
        from tryon.garment.generate import write_catalogue

        out = Path(tempfile.mkdtemp(prefix="tryon-bench-garments-"))
        write_catalogue(out)
        _GENERATED.append(out)
    return _GENERATED[0]


def catalogue_entries() -> list[dict]:
    """Entries of ``catalogue.json`` (file, name, category, size, units)."""
    return json.loads((garments_dir() / "catalogue.json").read_text())


def default_body(ctx: Context, resolution: int | None = None):
    """The size M body in the default pose (built once per resolution)."""
    from tryon.body.build import DEFAULT_RESOLUTION, build_body
    from tryon.body.params import Measurements, Pose

    res = resolution or DEFAULT_RESOLUTION
    return ctx.cached(("body", res), lambda: build_body(Measurements(**BODY_M), Pose(), res))


def load_clean(entry: dict):
    """(CleanMesh, load seconds) of a catalogue file."""
    from tryon.garment.ingest import load_garment

    path = garments_dir() / entry["file"]
    data = path.read_bytes()
    t = time.perf_counter()
    mesh = load_garment(data, entry["file"], units=entry.get("units", "auto"))
    return mesh, time.perf_counter() - t, hashlib.sha256(data).hexdigest()


def prepared(ctx: Context, entry: dict, simplification: float | None = None):
    """(GarmentModel, {load_s, prepare_s}) for a catalogue entry at simplification B (default: the
    catalogue's), prepared in memory (the cache-free cost a first ingest pays) and cached in the run. In the
    entry's fabric at its density, as the catalogue ingests it."""
    from tryon.garment.fabric import fabric_named
    from tryon.garment.prepare import DEFAULT_SIMPLIFICATION, prepare

    b = DEFAULT_SIMPLIFICATION if simplification is None else simplification

    def make():
        mesh, load_s, sha = load_clean(entry)
        t = time.perf_counter()
        fabric = fabric_named(entry.get("fabric"), entry["category"])
        model = prepare(mesh, id=entry["file"], name=entry["name"], category=entry["category"],
                        size=entry.get("size"), source_sha256=sha, source_name=entry["file"], simplification=b,
                        density=fabric.density, fabric=fabric.name)
        return model, {"load_s": load_s, "prepare_s": time.perf_counter() - t}

    return ctx.cached(("garment", entry["file"], round(b, 4)), make)


def main_entry() -> dict:
    entries = catalogue_entries()
    return next((e for e in entries if e["file"] == MAIN_GARMENT), entries[0])


def first_garment(ctx: Context):
    """The main garment's prepared model (default simplification), or None without a catalogue."""
    try:
        return prepared(ctx, main_entry())[0]
    except FileNotFoundError:
        return None
