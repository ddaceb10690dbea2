"""``tryon fit``: which size of a style fits a body, as a table (the advice ``POST /api/fit`` gives).

    tryon fit STYLE --height CM --chest CM --waist CM --hips CM [--fit slim|regular|relaxed] [--data-dir DIR]

The sizes near the person's on the style's chart are draped (``TRYON_SIM_WORKERS`` at once), the others
reported not draped unless the answer needs them (``tryon.fit.advice``). Exit status 0 with a
recommendation, 1 when no size fits, 2 for a usage error (an unknown style, a measurement out of range).
"""

from __future__ import annotations

import argparse
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

from tryon.cli.common import CliError, load_settings


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("fit", help="which size of a style fits a body",
                       description="Drape a style's sizes on a body built from measurements and say which size "
                                   "fits, with each size's verdict, ease and reason.")
    p.add_argument("style", help="style id (tryon ingest --style; GET /api/styles)")
    for name in ("height", "chest", "waist", "hips"):
        p.add_argument(f"--{name}", type=float, required=True, metavar="CM", help=f"{name}, cm")
    p.add_argument("--fit", choices=("slim", "regular", "relaxed"), default="regular",
                   help="the fit you like: a size under the chart's, the chart's, or a size over (default regular)")
    p.add_argument("--data-dir", type=Path, help="catalogue directory (default: TRYON_DATA_DIR or ./data)")
    p.set_defaults(func=run)


def _cell(value) -> str:
    return "-" if value is None else f"{value:+.1f}"


def run(args: argparse.Namespace) -> int:
    from tryon.body.build import build_body
    from tryon.body.params import Measurements, Pose, check_measurements
    from tryon.fit.advice import Drape, advise_style
    from tryon.garment.catalogue import Catalogue
    from tryon.sim.blocks import machine_threads, use_threads
    from tryon.sim.run import drape
    from tryon.sim.settings import SimSettings

    measurements = Measurements(height=args.height, chest=args.chest, waist=args.waist, hips=args.hips)
    problems = check_measurements(measurements)
    if problems:
        raise CliError("measurements: " + "; ".join(problems))
    settings = load_settings()
    data_dir = args.data_dir or settings.data_dir
    if not (Path(data_dir) / "catalogue.sqlite").exists():
        raise CliError(f"no catalogue in {data_dir}: ingest garments first (tryon ingest --catalogue garments/)")
    catalogue = Catalogue(data_dir)
    entries = catalogue.style(args.style)
    if not entries:
        styles = ", ".join(catalogue.styles()) or "none"
        raise CliError(f"no style {args.style!r} in {data_dir} (its styles: {styles})")
    started = time.perf_counter()
    body = build_body(measurements, Pose())
    sim = SimSettings()

    def drape_one(i: int) -> Drape:
        use_threads(machine_threads() // settings.sim_workers)  # the cores shared among the workers
        result = drape(body, catalogue.model(entries[i].id, sim.simplification), sim)
        return Drape(result.vertices, result.faces, result.metrics)

    with ThreadPoolExecutor(max_workers=settings.sim_workers) as workers:
        def drape_sizes(indices: list[int]) -> dict[int, Drape | str]:
            return dict(zip(indices, workers.map(drape_one, indices)))

        advice, recommended, reason, notes = advise_style(entries, measurements.as_dict(), body, drape_sizes,
                                                          lambda gid: catalogue.model(gid).vertices, args.fit)
    girths = list(dict.fromkeys(k for a in advice for k in a.ease_cm)) or ["ease"]
    header = ["size", "verdict", *[f"{g} ease cm" for g in girths], "reason"]
    rows = [[a.size, a.verdict, *[_cell(a.ease_cm.get(g)) for g in girths], a.reason] for a in advice]
    widths = [max(len(str(r[c])) for r in [header, *rows]) for c in range(len(header) - 1)]
    for r in [header, *rows]:
        print("  ".join(str(v).ljust(w) for v, w in zip(r[:-1], widths)) + "  " + r[-1])
    print(f"recommended: {recommended or 'none'} ({reason}); {time.perf_counter() - started:.2f} s")
    for note in notes:
        print(f"note: {note}")
    return 0 if recommended else 1
