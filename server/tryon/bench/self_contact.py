"""Self-contact's cost (issue 53 item 3: it may add at most 30 % to a single drape's time to rest): the six M
garments and the shorts XXL (loose legs swinging) on the medium body, each draped with the cloth's contact with
itself off (the default) and on at ``THICKNESS``, one thread, the two alternated; medians of ``REPEATS``. Also
the steps to rest and the shown mesh's self-crossing edges either way.
"""

from __future__ import annotations

import statistics
import time
from dataclasses import replace

from tryon.bench.common import Context, Section, Table, fmt
from tryon.bench.fit import BODIES
from tryon.bench.scenes import catalogue_entries, prepared
from tryon.sim.blocks import machine_threads, use_threads

# m: the cloth's thickness for the measured runs (``Tuning.self_thickness``)
THICKNESS = 0.001
GARMENTS = ("T-shirt M", "Long-sleeve shirt M", "Sleeveless dress M", "A-line skirt M", "Trousers M", "Shorts M",
            "Shorts XXL")
REPEATS = 3


def run(ctx: Context, sec: Section) -> None:
    from tryon.body.build import build_body
    from tryon.body.params import Measurements, Pose
    from tryon.sim.run import drape
    from tryon.sim.settings import SimSettings
    from tryon.sim.tuning import TUNING

    entries = {e["name"]: e for e in catalogue_entries()}
    names = GARMENTS[:1] if ctx.quick else GARMENTS
    body = build_body(Measurements(**BODIES["medium"]), Pose())
    settings = SimSettings()
    tunings = {"off": TUNING, "on": replace(TUNING, self_thickness=THICKNESS)}
    rows, data = [], []
    use_threads(1)
    try:
        for name in names:
            model = prepared(ctx, entries[name])[0]
            results = {k: drape(body, model, settings, tuning=tu) for k, tu in tunings.items()}  # warm
            times = {k: [] for k in tunings}
            for _ in range(REPEATS):
                for k, tu in tunings.items():
                    t = time.perf_counter()
                    results[k] = drape(body, model, settings, tuning=tu)
                    times[k].append(time.perf_counter() - t)
            d = {"garment": name}
            for k in tunings:
                d[f"{k}_s"] = statistics.median(times[k])
                d[f"{k}_steps"] = results[k].metrics["steps"]
                d[f"{k}_crossings"] = results[k].metrics["self_crossings"]
            d["ratio"] = d["on_s"] / max(d["off_s"], 1e-9)
            data.append(d)
            rows.append([name, fmt(d["off_s"]), fmt(d["on_s"]), fmt(d["ratio"]), d["off_steps"], d["on_steps"],
                         d["off_crossings"], d["on_crossings"]])
            ctx.log(f"  self-contact {name}: {d['ratio']:.2f}x, crossings {d['off_crossings']} -> {d['on_crossings']}")
    finally:
        use_threads(machine_threads())
    sec.data = {"thickness_m": THICKNESS, "repeats": REPEATS, "rows": data}
    sec.tables.append(Table(
        f"Self-contact at {THICKNESS * 1e3:g} mm against none, on the medium body, one thread",
        ["garment", "off s", "on s", "on / off", "off steps", "on steps", "off crossings", "on crossings"], rows,
        note=f"Time to rest of `sim.run.drape`, the two alternated, median of {REPEATS}. Crossings: the shown "
             "mesh's self-crossing edges. Self-contact is off by default (`Tuning.self_thickness`).",
    ))
    ratios = [d["ratio"] for d in data]
    sec.headline.append(
        f"self-contact at {THICKNESS * 1e3:g} mm (off by default): {fmt(min(ratios))}-{fmt(max(ratios))}x a "
        f"drape's time to rest, median {fmt(statistics.median(ratios))} over {len(data)} garments on the medium "
        f"body (one thread; the issue's bound 1.3); shown self-crossing edges "
        f"{sum(d['off_crossings'] for d in data)} -> {sum(d['on_crossings'] for d in data)}"
    )
