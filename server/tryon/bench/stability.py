"""Numerical stability: the stress summary of ``tryon.sim.stress`` (random scenes, NaNs, worst stretch,
worst energy). ``tryon bench --stress`` runs the long version."""

from __future__ import annotations

from tryon.bench.common import Context, Section, SkipSection, Table, fmt

SCENES = {"quick": 4, "full": 24, "stress": 300}


def run(ctx: Context, sec: Section) -> None:
    try:
        from tryon.sim.stress import stress
    except ImportError as exc:
        raise SkipSection(f"tryon.sim.stress is not available ({exc})") from exc
    n = SCENES["stress" if ctx.stress else "quick" if ctx.quick else "full"]
    summary = stress(n, 0)
    summary = dict(summary) if not isinstance(summary, dict) else summary
    sec.data = {"scenes": n, "seed": 0, "summary": summary}
    rows = [[k, fmt(v) if not isinstance(v, (dict, list)) else str(v)[:80]] for k, v in summary.items()]
    sec.tables.append(Table(f"Stress: {n} random scenes (seed 0)", ["figure", "value"], rows))
    keys = {k.lower(): k for k in summary}
    parts = [f"{n} scenes"]
    for word in ("nan", "stretch", "strain", "energy"):
        k = next((keys[x] for x in keys if word in x), None)
        if k is not None and not isinstance(summary[k], (dict, list)):
            parts.append(f"{k} {fmt(summary[k])}")
    sec.headline.append("stability: " + ", ".join(parts))
