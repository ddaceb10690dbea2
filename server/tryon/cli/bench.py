"""``tryon bench``: measure speed and accuracy on this machine (see ``tryon.bench``)."""

from __future__ import annotations

import argparse
from pathlib import Path

from tryon.cli.common import CliError, writable_dir
from tryon.sim.settings import SimSettings

# the most substeps ``--substeps`` takes (as the API's settings)
MAX_SUBSTEPS = 16
# the most Newton steps of the fast projection ``--projection`` takes
MAX_PROJECTION = 8
# the most random pose sequences per garment ``--sequences`` takes (the motion section's full run)
MAX_SEQUENCES = 20


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("bench", help="benchmark: paper tables, run time vs error, peers, stability, scaling")
    p.add_argument("--quick", action="store_true", help="small version (under two minutes)")
    p.add_argument("--stress", action="store_true", help="run the long stability stress test")
    p.add_argument("--out", type=Path, default=Path("bench-results"), help="output directory (default bench-results/)")
    p.add_argument("--only", nargs="+", metavar="SECTION", default=None,
                   help="run only these sections (table1 table2 table3 fit poses outfits live motion sizes pareto simplify selfcontact peers stability scaling scale)")
    p.add_argument("--page", type=Path, default=None, metavar="MD",
                   help="also write the figures page (e.g. docs/benchmarks.md, its plots beside it in bench/)")
    p.add_argument("--from", dest="from_json", type=Path, default=None, metavar="BENCH_JSON",
                   help="with --page: write the page from an earlier run's bench.json instead of running")
    p.add_argument("--bodies", type=Path, default=None, metavar="CSV",
                   help="sizes section: the people (an ANSUR II style CSV, mm; default: tests/data/bodies-sample.csv)")
    p.add_argument("--substeps", type=int, default=None, metavar="N",
                   help=f"fit section: N substeps per step, one spring pass each (default {SimSettings().substeps}), "
                        f"to see what fewer cost in accuracy; 1 to {MAX_SUBSTEPS}")
    p.add_argument("--projection", type=int, default=None, metavar="N",
                   help="fit section: N Newton steps of the fast projection of the strain limits at the end of "
                        "every step (default none), to see what it costs and changes on the catalogue; "
                        f"1 to {MAX_PROJECTION}")
    p.add_argument("--sequences", type=int, default=None, metavar="N",
                   help=f"motion section: N random pose sequences of ten poses per garment instead of all "
                        f"{MAX_SEQUENCES} (each garment's first N; ~10 minutes per sequence); 1 to {MAX_SEQUENCES}")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from tryon.bench import run_bench, sections

    if args.from_json is not None:
        return write_page_from(args.from_json, args.page)

    known = [name for name, _, _ in sections()]
    unknown = [name for name in args.only or () if name not in known]
    if unknown:
        raise CliError(f"unknown section {', '.join(map(repr, unknown))} for --only: choose from {' '.join(known)}")
    if args.substeps is not None and not 1 <= args.substeps <= MAX_SUBSTEPS:
        raise CliError(f"--substeps must be 1 to {MAX_SUBSTEPS}, got {args.substeps}")
    if args.projection is not None and not 1 <= args.projection <= MAX_PROJECTION:
        raise CliError(f"--projection must be 1 to {MAX_PROJECTION}, got {args.projection}")
    if args.sequences is not None and not 1 <= args.sequences <= MAX_SEQUENCES:
        raise CliError(f"--sequences must be 1 to {MAX_SEQUENCES}, got {args.sequences}")
    writable_dir(args.out, "--out")  # before the run, not after minutes of it
    if args.bodies is not None and not args.bodies.is_file():
        raise CliError(f"--bodies: no such file {args.bodies}")
    report, code = run_bench(args.out, quick=args.quick, stress=args.stress, only=args.only,
                             substeps=args.substeps, projection=args.projection, bodies=args.bodies,
                             sequences=args.sequences)
    for s in report["sections"]:
        for h in s["headline"]:
            print(h)
    print(f"wrote {args.out / 'bench.json'}, {args.out / 'bench.md'}"
          + ("" if code == 0 else " (some sections failed: see bench.md)"))
    if args.page is not None:
        code = max(code, write_page_from(args.out / "bench.json", args.page))
    return code


def write_page_from(bench_json: Path, page: Path | None) -> int:
    """``--page`` from an existing ``bench.json`` (its plots beside it)."""
    import json

    from tryon.bench.report import write_page

    if page is None:
        raise CliError("--from needs --page: the figures page to write")
    try:
        report = json.loads(bench_json.read_text())
    except OSError as exc:
        raise CliError(f"cannot read {bench_json}: {exc.strerror}") from None
    except ValueError:
        raise CliError(f"{bench_json} is not a bench.json (not valid JSON)") from None
    if not isinstance(report, dict) or not isinstance(report.get("sections"), list):
        raise CliError(f"{bench_json} is not a bench.json (no sections)")
    writable_dir(page.parent, "--page's folder")
    try:
        written = write_page(page, report, bench_json.parent)
    except FileNotFoundError as exc:
        raise CliError(f"a plot of {bench_json} is missing: {exc.filename}") from None
    except KeyError as exc:
        raise CliError(f"{bench_json} is not a bench.json (missing {exc})") from None
    print(f"wrote {page} and {len(written) - 1} plots in {page.parent / 'bench'}")
    return 0
