"""``tryon bench``: the service's speed and accuracy measured on this machine in one run.

Sections (one module each): the paper's tables 1-3 (``tables``), the catalogue's fit on three bodies (``fit``)
and in other poses (``poses``), live re-posing over a WebSocket (``live``) and random pose sequences through
the re-pose (``motion``), outfits of a top over a bottom (``outfits``), run time against error and the
default settings (``pareto``), the paper's simplification against quadric edge collapse
(``simplify_compare``), peer engines (``peers``: Taichi, Newton), the stability stress summary
(``stability``), and scaling (``scaling``), fit-table throughput on Ray (``scale``), size advice against the
chart on people of a CSV (``sizes``), the cost of the cloth's contact with itself (``self_contact``). Each runs isolated: a failure is reported with its reason and the others
still run.
``report`` writes bench.json, bench.md and the PNG plots.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

from tryon.bench.common import Context, machine, run_section
from tryon.bench.report import now, write_report


def sections():
    """(name, title, function) of every section, in report order."""
    from tryon.bench import (
        fit, live, motion, outfits, pareto, peers, poses, scale, scaling, self_contact, simplify_compare, sizes,
        stability, tables,
    )

    return [
        ("table1", "Paper table 1: simplification and collision time", tables.table1),
        ("table2", "Paper table 2: inside-triangle tests", tables.table2),
        ("table3", "Paper table 3: pipeline stages", tables.table3),
        ("fit", "Catalogue fit on three bodies", fit.run),
        ("poses", "Fit in other poses", poses.run),
        ("outfits", "Outfits: a top over a bottom", outfits.run),
        ("live", "Live re-posing over the WebSocket", live.run),
        ("motion", "Motion stress: random pose sequences", motion.run),
        ("sizes", "Size advice against the chart", sizes.run),
        ("pareto", "Run time against error", pareto.run),
        ("simplify", "Simplification compared", simplify_compare.run),
        ("selfcontact", "Self-contact's cost", self_contact.run),
        ("peers", "Peer engines", peers.run),
        ("stability", "Stability stress", stability.run),
        ("scaling", "Scaling", scaling.run),
        ("scale", "Past one machine: fit tables on Ray", scale.run),
    ]


def run_bench(out_dir: Path | str = "bench-results", quick: bool = False, stress: bool = False,
              only: list[str] | None = None, log=print, substeps: int | None = None, projection: int | None = None,
              bodies: Path | None = None, sequences: int | None = None) -> tuple[dict, int]:
    """Run the benchmark into ``out_dir``; returns (report dict, exit code). The exit code is 1 when a
    section failed (our code raised), 0 otherwise (skipped optional peers are not failures). ``substeps``:
    the fit section's substeps per step (one spring pass each) instead of the default settings; ``projection``:
    its Newton steps of the fast projection of the strain limits (``sim/projection.py``); ``sequences``:
    the motion section's random pose sequences per garment instead of its mode's."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    ctx = Context(out_dir=out, quick=quick, stress=stress, log=log, substeps=substeps, projection=projection,
                  bodies=bodies, sequences=sequences)
    started = now()
    info = machine()
    # every kernel compiled (or loaded) before the first section times anything, as the service does
    from tryon.api.warmup import warm_up

    warm_up()
    t0 = time.perf_counter()
    done = []
    for name, title, fn in sections():
        if only and name not in only:
            continue
        done.append(run_section(name, title, fn, ctx))
    mode = "quick" if quick else "full"
    if stress:
        mode += " + stress"
    cmd = ("tryon bench" + (" --quick" if quick else "") + (" --stress" if stress else "")
           + (f" --only {' '.join(only)}" if only else "")
           + (f" --bodies {bodies}" if bodies is not None else "")
           + (f" --substeps {substeps}" if substeps is not None else "")
           + (f" --projection {projection}" if projection is not None else "")
           + (f" --sequences {sequences}" if sequences is not None else ""))
    report = write_report(out, done, {
        "started": started, "mode": mode, "command": cmd, "seconds": time.perf_counter() - t0,
        "machine": info, "argv": sys.argv,
    })
    failed = [s.name for s in done if s.status == "failed"]
    return report, 1 if failed else 0
