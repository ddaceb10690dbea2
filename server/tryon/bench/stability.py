"""Numerical stability: the stress summary of ``tryon.bench.stress`` (random bodies, garments, time steps,
passes and strain limits, checked at every step: scenes, NaNs, worst stretch, worst energy).
``tryon bench --stress`` runs the long version."""

from __future__ import annotations

from tryon.bench.common import Context, Section, SkipSection, Table, fmt
from tryon.bench.scenes import main_entry, prepared

SCENES = {"quick": 2, "full": 24, "stress": 200}


def run(ctx: Context, sec: Section) -> None:
    try:
        from tryon.bench.stress import stress
    except ImportError as exc:
        raise SkipSection(f"tryon.bench.stress is not available ({exc})") from exc
    mode = "stress" if ctx.stress else "quick" if ctx.quick else "full"
    n = SCENES[mode]
    # quick: the main garment only (already prepared); otherwise the whole catalogue
    models = [prepared(ctx, main_entry())[0]] if ctx.quick else None
    summary = stress(n, 0, models=models)
    sec.data = {"mode": mode, "summary": summary}
    limits = summary.get("limits", {})
    rows = [
        ["scenes", summary["scenes"], ""], ["passed", summary["passed"], ""], ["failed", summary["failed"], ""],
        ["never NaN", fmt(summary["never_nan"]), ""],
        ["worst stretch (length / natural)", fmt(summary["max_stretch"]), f"limit {fmt(limits.get('stretch'))}"],
        ["worst kinetic energy (J/kg)", fmt(summary["max_energy_J_per_kg"]),
         f"limit {fmt(limits.get('energy_J_per_kg'))}"],
        ["garments", len(summary.get("garments", [])), ", ".join(summary.get("garments", []))[:120]],
        ["wall seconds", fmt(summary.get("wall_seconds")), ""],
    ]
    sec.tables.append(Table(f"Stress: {n} random scenes (seed 0)", ["figure", "value", "note"], rows))
    failures = summary.get("failures", [])
    if failures:
        sec.tables.append(Table(
            "Failed scenes (first 20)",
            ["garment", "time step", "passes", "structural limit", "max stretch", "max energy", "finite", "error"],
            [[f["garment"], f["time_step"], f["passes"], f["structural_limit"], fmt(f["max_stretch"]),
              fmt(f["max_energy_J_per_kg"]), fmt(f["finite"]), f.get("error") or ""] for f in failures],
        ))
    sec.headline.append(
        f"stability: {summary['scenes']} random scenes, {summary['failed']} failed, "
        f"{'no NaN' if summary['never_nan'] else 'NaN seen'}, worst stretch {fmt(summary['max_stretch'])}x, "
        f"worst energy {fmt(summary['max_energy_J_per_kg'])} J/kg"
    )
