"""``tryon fit-table``: the size advice for every person of a bodies CSV and every style, as a CSV.

    tryon fit-table STYLE... --bodies CSV --out FILE.csv [--ray [ADDRESS]] [--data-dir DIR]

One row per person and style (``tryon.scale.fit_table``): the recommended size, each size's verdict and
ease, the reason. Run again with the same ``--out`` after an interruption, it goes on where it stopped.
``--ray`` runs the advice as Ray tasks (a local Ray without ADDRESS; ``auto`` or ``host:port`` joins one).
Exit status 0 when every row is written, 1 when some job failed (run again to retry it), 2 for a usage error.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from tryon.cli.common import CliError, load_settings
from tryon.cli.ingest import LOCAL_RAY


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("fit-table", help="size advice for every person of a bodies CSV, as a CSV",
                       description="Drape each style's sizes on every person of an ANSUR II style CSV (mm) and "
                                   "write the advice, one row per person and style.")
    p.add_argument("styles", nargs="+", metavar="STYLE", help="style ids (GET /api/styles)")
    p.add_argument("--bodies", type=Path, required=True, metavar="CSV",
                   help="people: ANSUR II style CSV in millimetres (stature, chestcircumference, "
                        "waistcircumference, buttockcircumference; subjectid names the row)")
    p.add_argument("--out", type=Path, required=True, metavar="FILE.csv", help="the table (appended to: resumes)")
    p.add_argument("--ray", nargs="?", const=LOCAL_RAY, default=None, metavar="ADDRESS",
                   help="run on a Ray cluster: no ADDRESS starts a local Ray, 'auto' or host:port joins one")
    p.add_argument("--data-dir", type=Path, help="catalogue directory (default: TRYON_DATA_DIR or ./data)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from tryon.garment.catalogue import Catalogue
    from tryon.scale.fit_table import append_rows, done_pairs, fit_rows, read_bodies
    from tryon.scale.ray_jobs import RayUnavailable

    data_dir = args.data_dir or load_settings().data_dir
    if not (Path(data_dir) / "catalogue.sqlite").exists():
        raise CliError(f"no catalogue in {data_dir}: ingest garments first (tryon ingest --catalogue garments/)")
    catalogue = Catalogue(data_dir)
    known = catalogue.styles()
    unknown = [s for s in args.styles if s not in known]
    if unknown:
        raise CliError(f"no style {', '.join(map(repr, unknown))} in {data_dir} (its styles: "
                       f"{', '.join(known) or 'none'})")
    try:
        people = read_bodies(args.bodies)
    except OSError as exc:
        raise CliError(f"cannot read {args.bodies}: {exc.strerror}") from None
    except (ValueError, UnicodeDecodeError) as exc:
        raise CliError(f"{args.bodies} is not a bodies CSV: {exc}") from None
    if not args.out.resolve().parent.is_dir():
        raise CliError(f"cannot write {args.out}: there is no directory {args.out.resolve().parent}")
    try:
        skip = done_pairs(args.out)
    except (OSError, KeyError, UnicodeDecodeError):
        raise CliError(f"{args.out} exists but is not a fit table this command wrote: give another --out") from None
    styles = {s: known[s] for s in dict.fromkeys(args.styles)}
    models = {m.id: catalogue.model(m.id) for entries in styles.values() for m in entries}
    total = len(people) * len(styles)
    todo = total - sum((p.id, s) in skip for p in people for s in styles)
    print(f"{total - todo} of {total} rows already in {args.out}; {todo} to go"
          + (f" on Ray ({args.ray})" if args.ray else ""), file=sys.stderr)
    started = time.perf_counter()
    failed = written = 0
    try:
        for row in append_rows(args.out, fit_rows(people, styles, models, skip, args.ray)):
            if isinstance(row, str):
                failed += 1
                print(f"\n{row}", file=sys.stderr)
                continue
            written += 1
            rate = written / max(time.perf_counter() - started, 1e-9)
            if sys.stderr.isatty():  # a progress bar on a terminal, a line every tenth of the way in a log
                print(f"\r[{written + failed}/{todo}] {rate:.2f} advice/s", end="", file=sys.stderr, flush=True)
            elif (written + failed) % max(1, todo // 10) == 0:
                print(f"[{written + failed}/{todo}] {rate:.2f} advice/s", file=sys.stderr, flush=True)
    except RayUnavailable as exc:
        raise CliError(str(exc), code=1) from None
    except OSError as exc:
        raise CliError(f"cannot write {args.out}: {exc.strerror or exc}", code=1) from None
    print(f"\n{written} rows written to {args.out} in {time.perf_counter() - started:.1f} s"
          + (f"; {failed} failed (run again to retry them)" if failed else ""), file=sys.stderr)
    return 1 if failed else 0
